"""The figures a run leaves in its own folder when it ends (`coadapt run`, docs/results.md):
convergence for one objective, the Pareto front for several, the surrogate's error where it
was measured. They are drawn by the report's own functions (`report_figures`), fed from the
run folder's records instead of a results store, so a run without a store (`--store none`)
has them too and `coadapt report` draws the same pictures of the same numbers."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from coadapt_core.methods import DEFAULT_METHOD
from coadapt_core.results.recorders import read_evaluations, read_jsonl
from coadapt_core.results.rows import Evaluation, objective_list


class FolderRecords:
    """The two store reads the report's figures make of a run (its evaluations, its training
    phases), answered from the run folder's JSON lines (`evaluations.jsonl`,
    `trainings.jsonl`, as `coadapt_core.results.recorders.JsonRecorder` writes them)."""

    def __init__(self, run_dir: str | Path):
        self.run_dir = Path(run_dir)

    def evaluations(
        self, run_id: str | None = None, *, kind: str | None = None
    ) -> list[Evaluation]:
        out = []
        for r in read_evaluations(self.run_dir):
            if kind is not None and r.get("kind") != kind:
                continue
            costs = {
                str(k): (math.nan if v is None else float(v))
                for k, v in (r.get("costs") or {}).items()
            }
            errors = r.get("surrogate_error")
            out.append(
                Evaluation(
                    run_id=str(r.get("run_id") or self.run_dir.name),
                    outer=int(r["outer"]),
                    inner=int(r["inner"]),
                    idx=int(r["idx"]),
                    kind=str(r["kind"]),
                    design=[float(x) for x in r.get("design") or []],
                    costs=costs,
                    surrogate_error=None
                    if errors is None
                    else {str(k): (math.nan if v is None else float(v)) for k, v in errors.items()},
                    interactions=int(r.get("interactions") or 0),
                    seconds=float(r.get("seconds") or 0.0),
                    simulator=None,
                    created_at=float(r.get("time") or 0.0),
                )
            )
        return out

    def training(self, run_id: str | None = None) -> list[dict[str, Any]]:
        return [
            {
                "outer": int(t["outer"]),
                "steps": int(t.get("steps") or 0),
                "seconds": float(t.get("seconds") or 0.0),
                "created_at": float(t.get("time") or 0.0),
            }
            for t in read_jsonl(self.run_dir / "trainings.jsonl")
        ]


def run_row(run_dir: str | Path, config: dict[str, Any], summary: dict[str, Any]) -> dict[str, Any]:
    """The run as a store row would hold it (`ResultsStore.get_run`), from its config and
    summary."""
    run_dir = Path(run_dir)
    return {
        "id": run_dir.name,
        "method": str(config.get("method") or summary.get("method") or DEFAULT_METHOD),
        "objectives": objective_list(config) or objective_list(summary),
        "terrain": config.get("terrain"),
        "optimizer": summary.get("optimizer") or config.get("optimizer"),
        "robot": config.get("robot"),
        "simulator": config.get("sim"),
        "preset": config.get("preset"),
        "seed": config.get("seed"),
        "config": dict(config),
        "summary": dict(summary),
        "status": "finished",
        "run_dir": str(run_dir),
    }


def write_run_figures(
    run_dir: str | Path, summary: dict[str, Any], config: dict[str, Any] | None = None
) -> list[tuple[Path, str]]:
    """Draw the run's figures into its folder; returns [(PNG path, caption)]. The run's config
    is its config.yaml (`config` where the folder has none)."""
    from coadapt_core.analysis.facts import run_facts
    from coadapt_core.analysis.pareto_figure import figure_pareto
    from coadapt_core.analysis.report_figures import figure_convergence, figure_surrogate_error

    run_dir = Path(run_dir)
    import yaml

    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text()) or config or {}
    except (OSError, yaml.YAMLError):
        config = config or {}
    records = FolderRecords(run_dir)
    facts = [run_facts(records, run_row(run_dir, config, summary))]  # type: ignore[arg-type]
    written = figure_convergence(records, facts, run_dir)  # type: ignore[arg-type]
    written += figure_pareto(facts, run_dir)
    written += figure_surrogate_error(facts, run_dir)
    return written


__all__ = ["FolderRecords", "run_row", "write_run_figures"]
