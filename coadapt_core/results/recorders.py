"""Where a co-adaptation run writes its evidence: JSON files in the run folder, and the one
factory (`make_recorder`) that also hands out the results store's recorder.

Run folder: `config.yaml`, `evaluations.jsonl` (one line per evaluated design),
`trainings.jsonl`, `checkpoints.jsonl`, `summary.json`. Lines are keyed by
(outer, inner, kind, idx); a resumed run that redoes an interrupted batch appends the same
keys again, and `read_evaluations` keeps the last line of each key.
"""

from __future__ import annotations

import json
import os
import time
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.fitness import RunRecorder, TrainingResult


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, float) and value != value:  # NaN is not JSON
        return None
    return value


def write_json_atomic(path: Path, data: Any) -> None:
    """Through a temporary file and a rename; on a full disk, one line and no partial file."""
    from coadapt_core.statefile import write_atomic

    write_atomic(path, json.dumps(_jsonable(data), indent=2).encode("utf-8"))


class JsonRecorder:
    """`RunRecorder` writing JSON lines into one run folder (the folder name is the run id)."""

    def __init__(self, run_dir: str | os.PathLike):
        self.run_dir = Path(run_dir)
        self._next_eval: dict[tuple[int, int, str], int] = defaultdict(int)

    def _append(self, name: str, record: dict[str, Any]) -> None:
        with open(self.run_dir / name, "a") as f:
            f.write(json.dumps(_jsonable(record)) + "\n")
            f.flush()

    def start_run(self, config: dict[str, Any]) -> str:
        import yaml

        self.run_dir.mkdir(parents=True, exist_ok=True)
        config_path = self.run_dir / "config.yaml"
        if not config_path.exists():  # a resumed run keeps the config it started with
            from coadapt_core.statefile import write_atomic

            write_atomic(config_path, yaml.safe_dump(_jsonable(dict(config)), sort_keys=False).encode("utf-8"))
        return self.run_dir.name

    def record_evaluation(
        self,
        run_id: str,
        *,
        outer: int,
        inner: int,
        design: Sequence[float],
        costs: dict[str, float],
        kind: str,
        interactions: int,
        seconds: float,
        surrogate_error: dict[str, float] | None = None,
        index: int | None = None,
    ) -> None:
        key = (int(outer), int(inner), str(kind))
        idx = self._next_eval[key] if index is None else int(index)
        self._next_eval[key] = max(self._next_eval[key], idx + 1)
        self._append(
            "evaluations.jsonl",
            {
                "run_id": run_id, "outer": outer, "inner": inner, "idx": idx, "kind": kind,
                "design": [float(x) for x in design], "costs": costs, "interactions": int(interactions),
                "seconds": float(seconds), "surrogate_error": surrogate_error, "time": time.time(),
            },
        )

    def record_training(self, run_id: str, *, outer: int, result: TrainingResult) -> None:
        self._append(
            "trainings.jsonl",
            {"run_id": run_id, "outer": outer, "steps": int(result.steps), "seconds": float(result.seconds),
             "mean_reward": float(result.mean_reward), "extra": dict(result.extra), "time": time.time()},
        )

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None:
        self._append("checkpoints.jsonl", {"run_id": run_id, "outer": outer, "path": os.fspath(path)})

    def finish(self, run_id: str, summary: dict[str, Any], status: str = "finished") -> None:
        write_json_atomic(self.run_dir / "summary.json", {**summary, "status": status})


def read_jsonl(path: str | os.PathLike) -> list[dict[str, Any]]:
    path = Path(path)
    if not path.exists():
        return []
    records = []
    for line in path.read_text().splitlines():
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:  # a line torn by a kill or a full disk: that record is redone
            continue
    return records


def read_evaluations(run_dir: str | os.PathLike) -> list[dict[str, Any]]:
    """The run's evaluation records, one per (outer, inner, kind, idx), last write wins."""
    latest: dict[tuple, dict[str, Any]] = {}
    for record in read_jsonl(Path(run_dir) / "evaluations.jsonl"):
        latest[(record["outer"], record["inner"], record["kind"], record["idx"])] = record
    return sorted(latest.values(), key=lambda r: (r["outer"], r["inner"], r["kind"] != "real", r["idx"]))


def make_recorder(run_dir: str | os.PathLike, store: str | None = None) -> RunRecorder:
    """The recorder for a run folder: JSON files always, teed into the results store.

    `store` is a results store URL or path; without one, `$COADAPT_STORE`, else coadapt.db
    beside the runs folder (./coadapt.db for ./runs/<id>); "none" records JSON files only.
    See `coadapt_core.results.store.store_url_for_run`."""
    from coadapt_core.results.store import store_url_for_run

    json_recorder = JsonRecorder(run_dir)
    url = store_url_for_run(run_dir, store)
    if url is None:
        return json_recorder
    from coadapt_core.results import SqliteRecorder

    return SqliteRecorder(url, run_dir=run_dir, tee=json_recorder)
