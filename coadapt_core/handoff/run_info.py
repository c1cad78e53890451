"""What a handoff reads of a finished run: its folder (a path or a run id), its config and
summary, the starting policy and its SHA-256, and the code version and commit its results
store recorded, gathered into the design sheet's provenance."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from coadapt_core import __version__
from coadapt_core.errors import UserError


# -- the run --------------------------------------------------------------------------------
def find_run(text: str, runs_dir: Path = Path("runs")) -> Path:
    """A run folder given as a path or as a run id under `runs_dir`."""
    path = Path(text)
    for candidate in (path, runs_dir / text):
        if candidate.is_dir() and (candidate / "config.yaml").is_file():
            return candidate.resolve()
    raise UserError(
        f"run '{text}' is neither a run folder nor a run id under {runs_dir}/ (no config.yaml "
        "found)",
        field="run",
    )


def read_run(run_dir: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(config, summary) of a finished run; one-line errors otherwise."""
    import yaml

    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise UserError(
            f"run {run_dir.name}: config.yaml cannot be read ({type(exc).__name__})", field="run"
        ) from None
    summary_path = run_dir / "summary.json"
    if not summary_path.is_file():
        raise UserError(
            f"run {run_dir.name} has no summary.json: it has not finished (resume it with "
            f"`coadapt run --resume {run_dir.name}`)",
            field="run",
        )
    try:
        summary = json.loads(summary_path.read_text())
    except (OSError, ValueError) as exc:
        raise UserError(
            f"run {run_dir.name}: summary.json cannot be read ({type(exc).__name__})", field="run"
        ) from None
    if (
        not isinstance(config, dict)
        or not isinstance(summary, dict)
        or not summary.get("best_design")
    ):
        raise UserError(
            f"run {run_dir.name} recorded no best design; nothing to hand off", field="run"
        )
    return config, summary


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _starting_policy(robot: Any, config: dict[str, Any]) -> dict[str, Any]:
    """The policy the run started from (the config's `checkpoint`: empty = the robot's shipped
    one for the terrain and space, `none` = from scratch) and its SHA-256."""
    given = str(config.get("checkpoint") or "")
    if given.lower() == "none":
        return {"policy": "none (trained from scratch in the run)", "sha256": None}
    path = (
        Path(given)
        if given
        else robot.shipped_policy(config.get("terrain") or "flat", bool(config.get("mixed")))
    )
    if path is None:
        return {"policy": "the robot's shipped policy (none found now)", "sha256": None}
    label = f"{path.name} (shipped with robot '{robot.name}')" if not given else str(path)
    return {"policy": label, "sha256": sha256(path) if Path(path).is_file() else None}


def _recorded_commit(run_dir: Path, run_id: str) -> dict[str, Any]:
    """The run's code version and git commit as its results store recorded them (the
    default store beside the runs folder, no tables created; an older store is upgraded on
    open); empty when there is none."""
    store_file = run_dir.parent.parent / "coadapt.db"
    if not store_file.is_file():
        return {}
    try:
        from coadapt_core.results.store import ResultsStore

        store = ResultsStore(str(store_file), create=False)
        try:
            row = store.get_run(run_id)
        finally:
            store.close()
        return {"code_version": row.get("code_version"), "git_commit": row.get("git_commit")}
    except Exception:  # a store of another layout or a locked file: provenance goes without it
        return {}


def provenance(
    run_dir: Path,
    config: dict[str, Any],
    summary: dict[str, Any],
    *,
    robot: Any,
    objectives: list[str],
    seed: int,
    simulator: str,
    checkpoint: Path,
    state: dict[str, Any],
    nominal_checkpoint: Path | None = None,
) -> dict[str, Any]:
    """Where the design and its controller come from: the run, its starting and final
    policies with their SHA-256 (and the nominal design's own policy, for a run without a
    shared one), and the code versions of the run and of the handoff."""
    from coadapt_core.results.storage import code_commit

    run_id = str(summary.get("run_id") or run_dir.name)
    recorded_at_run = _recorded_commit(run_dir, run_id)
    start = _starting_policy(robot, config)

    def name(path: Path) -> str:
        return str(path.relative_to(run_dir)) if run_dir in path.parents else path.name

    nominal = (
        {}
        if nominal_checkpoint is None
        else {
            "nominal_policy": name(nominal_checkpoint),
            "nominal_policy_sha256": sha256(nominal_checkpoint),
        }
    )
    return {
        "run_id": run_id,
        "method": summary.get("method") or config.get("method"),
        "optimizer": summary.get("optimizer") or config.get("optimizer"),
        "objectives": objectives,
        "seed": seed,
        "simulator": simulator,
        "preset": config.get("preset"),
        "starting_policy": start["policy"],
        "starting_policy_sha256": start["sha256"],
        "final_policy": name(checkpoint),
        "final_policy_sha256": sha256(checkpoint),
        "final_policy_steps": int(state.get("total_steps") or 0),
        **nominal,
        "run_code_version": recorded_at_run.get("code_version"),
        "run_git_commit": recorded_at_run.get("git_commit"),
        "handoff_coadapt_version": __version__,
        "handoff_git_commit": code_commit(),
        "reliable": summary.get("reliable"),
        "reliability": summary.get("reliability"),
    }
