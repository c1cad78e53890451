"""Where a run writes its evidence, behind the one `RunRecorder` protocol
(coadapt_core/fitness.py): JSON files in the run folder (`JsonRecorder`), the results store
(`SqliteRecorder`, optionally teeing every call to a JSON recorder), and the factory
(`make_recorder`) that picks them for a run folder.

Run folder: `config.yaml`, `evaluations.jsonl` (one line per evaluated design),
`trainings.jsonl`, `checkpoints.jsonl`, `summary.json`.

Idempotence is what makes resume safe: an evaluation batch is recorded at once, its designs
keyed by (run, outer, inner, kind, idx) with idx 0..K-1. A resumed run that redoes the batch
it was interrupted in records the same keys again: the store replaces those rows (all of a
batch or none, in one transaction) and `read_evaluations` keeps the last line of each key.
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
from coadapt_core.io import jsonable, write_atomic, write_json_atomic
from coadapt_core.results.store import ResultsStore


def batch_rows(
    *,
    outer: int,
    inner: int,
    kind: str,
    designs: Sequence[Sequence[float]],
    costs: Sequence[dict[str, float]],
    interactions: Sequence[int] | int,
    seconds: Sequence[float] | float,
    surrogate_errors: Sequence[dict[str, float] | None] | None = None,
    simulator: str | None = None,
) -> list[dict[str, Any]]:
    """One row per design of an evaluation batch (idx 0..K-1); a single `interactions` or
    `seconds` number is each design's."""
    k = len(designs)
    inter = (
        [int(interactions)] * k if isinstance(interactions, int) else [int(x) for x in interactions]
    )
    secs = [float(seconds)] * k if isinstance(seconds, int | float) else [float(x) for x in seconds]
    errs = list(surrogate_errors) if surrogate_errors is not None else [None] * k
    if not len(costs) == len(inter) == len(secs) == len(errs) == k:
        raise ValueError(
            f"an evaluation batch of {k} designs needs {k} costs, interactions, seconds and errors"
        )
    return [
        {
            "outer": int(outer),
            "inner": int(inner),
            "idx": i,
            "kind": str(kind),
            "design": [float(x) for x in designs[i]],
            "costs": dict(costs[i]),
            "surrogate_error": errs[i],
            "interactions": inter[i],
            "seconds": secs[i],
            "simulator": simulator,
        }
        for i in range(k)
    ]


class JsonRecorder:
    """`RunRecorder` writing JSON lines into one run folder (the folder name is the run id)."""

    def __init__(self, run_dir: str | os.PathLike):
        self.run_dir = Path(run_dir)

    def _append(self, name: str, record: dict[str, Any]) -> None:
        with open(self.run_dir / name, "a") as f:
            f.write(json.dumps(jsonable(record)) + "\n")
            f.flush()

    def start_run(self, config: dict[str, Any]) -> str:
        import yaml

        self.run_dir.mkdir(parents=True, exist_ok=True)
        config_path = self.run_dir / "config.yaml"
        if not config_path.exists():  # a resumed run keeps the config it started with
            write_atomic(
                config_path, yaml.safe_dump(jsonable(dict(config)), sort_keys=False).encode("utf-8")
            )
        return self.run_dir.name

    def record_evaluations(self, run_id: str, **batch: Any) -> None:
        """One line per design of the batch (see `batch_rows` for the fields)."""
        now = time.time()
        with open(self.run_dir / "evaluations.jsonl", "a") as f:
            for row in batch_rows(**batch):
                row.pop("simulator")
                f.write(json.dumps(jsonable({"run_id": run_id, **row, "time": now})) + "\n")
            f.flush()

    def record_training(self, run_id: str, *, outer: int, result: TrainingResult) -> None:
        self._append(
            "trainings.jsonl",
            {
                "run_id": run_id,
                "outer": outer,
                "steps": int(result.steps),
                "seconds": float(result.seconds),
                "mean_reward": float(result.mean_reward),
                "extra": dict(result.extra),
                "time": time.time(),
            },
        )

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None:
        self._append(
            "checkpoints.jsonl", {"run_id": run_id, "outer": outer, "path": os.fspath(path)}
        )

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
    return sorted(
        latest.values(), key=lambda r: (r["outer"], r["inner"], r["kind"] != "real", r["idx"])
    )


def make_recorder(run_dir: str | os.PathLike, store: str | None = None) -> RunRecorder:
    """The recorder for a run folder: JSON files always, teed into the results store.

    `store` is a results store URL or path; without one, `$COADAPT_STORE`, else coadapt.db
    beside the runs folder (./coadapt.db for ./runs/<id>); "none" records JSON files only.
    See `coadapt_core.results.storage.store_url_for_run`."""
    from coadapt_core.results.storage import store_url_for_run

    json_recorder = JsonRecorder(run_dir)
    url = store_url_for_run(run_dir, store)
    if url is None:
        return json_recorder
    return SqliteRecorder(url, run_dir=run_dir, tee=json_recorder)


class SqliteRecorder:
    """Records a run in a `ResultsStore` (SQLite by default; any SQLAlchemy URL works)."""

    def __init__(
        self,
        store: ResultsStore | str | os.PathLike | None = None,
        *,
        run_dir: str | os.PathLike | None = None,
        tee: RunRecorder | None = None,
    ):
        self.store = store if isinstance(store, ResultsStore) else ResultsStore(store)
        # absolute, so reports and grids started from another folder still find them
        self.run_dir = None if run_dir is None else os.path.abspath(run_dir)
        self.tee = tee
        # next idx per (run, outer) for training phases
        self._next_train: dict[tuple[str, int], int] = defaultdict(int)

    @property
    def url(self) -> str:
        return self.store.url

    def start_run(self, config: dict[str, Any]) -> str:
        """Register the run. When teeing, the other recorder picks the id (it may name the
        run folder after it) and the store uses the same id; a `run_id` already in the
        store (resume) keeps its rows."""
        config = dict(config)
        run_id = config.get("run_id")
        if self.tee is not None:
            run_id = self.tee.start_run(config)
        return self.store.create_run(config, run_id=run_id, run_dir=self.run_dir)

    def record_evaluations(self, run_id: str, **batch: Any) -> None:
        """A whole evaluation batch (see `batch_rows`) in one transaction, committed before
        returning: all or nothing, and a crash right after this call loses nothing."""
        self.store.record_evaluations(run_id, batch_rows(**batch))
        if self.tee is not None:
            self.tee.record_evaluations(run_id, **batch)

    def record_training(self, run_id: str, *, outer: int, result: TrainingResult) -> None:
        key = (run_id, int(outer))
        idx = self._next_train[key]
        self._next_train[key] = idx + 1
        self.store.record_training(
            run_id,
            outer=outer,
            idx=idx,
            steps=result.steps,
            seconds=result.seconds,
            final_reward=result.mean_reward,
            extra=dict(result.extra),
        )
        if self.tee is not None:
            self.tee.record_training(run_id, outer=outer, result=result)

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None:
        self.store.record_checkpoint(run_id, outer=outer, path=os.path.abspath(path))
        if self.tee is not None:
            self.tee.record_checkpoint(run_id, outer=outer, path=path)

    def refill_from_run_folder(self, run_id: str, run_dir: str | os.PathLike) -> dict[str, int]:
        """Record again what the run folder holds and the store lost (a store emptied, replaced
        or restored from an old copy): evaluations missing by (outer, inner, kind, idx),
        training phases of outer iterations the store has none of, and checkpoints inside the
        run folder. Called on resume, before the run continues; returns the counts refilled."""
        import math
        from pathlib import Path

        from coadapt_core.errors import UserError
        from coadapt_core.validation import inside

        folder = Path(run_dir)
        have = {(e.outer, e.inner, e.kind, e.idx) for e in self.store.evaluations(run_id)}

        def number(value: Any) -> float:
            return math.nan if value is None else float(value)

        rows = [
            {
                **r,
                "costs": {k: number(v) for k, v in (r.get("costs") or {}).items()},
                "surrogate_error": None
                if r.get("surrogate_error") is None
                else {k: number(v) for k, v in r["surrogate_error"].items()},
            }
            for r in read_evaluations(folder)
            if (int(r["outer"]), int(r["inner"]), str(r["kind"]), int(r["idx"])) not in have
        ]
        self.store.record_evaluations(run_id, rows)
        trained = {int(t["outer"]) for t in self.store.training(run_id)}
        per_outer: dict[int, int] = defaultdict(int)
        refilled_training = 0
        for t in read_jsonl(folder / "trainings.jsonl"):
            outer = int(t["outer"])
            if outer in trained:
                continue
            self.store.record_training(
                run_id,
                outer=outer,
                idx=per_outer[outer],
                steps=int(t["steps"]),
                seconds=float(t["seconds"]),
                final_reward=t.get("mean_reward"),
                extra=t.get("extra") or {},
            )
            per_outer[outer] += 1
            refilled_training += 1
        known = {(c["outer"], c["path"]) for c in self.store.checkpoints(run_id)}
        refilled_checkpoints = 0
        for c in read_jsonl(folder / "checkpoints.jsonl"):
            parts = Path(str(c.get("path", ""))).parts[
                -2:
            ]  # checkpoints/<file>, wherever the folder was
            try:  # a path read from a file is used only inside the run folder
                path = str(inside(folder, Path(*parts), field="checkpoint")) if parts else None
            except UserError:
                path = None
            if path is None:
                continue
            if (int(c["outer"]), path) not in known:
                self.store.record_checkpoint(run_id, outer=int(c["outer"]), path=path)
                refilled_checkpoints += 1
        return {
            "evaluations": len(rows),
            "training_phases": refilled_training,
            "checkpoints": refilled_checkpoints,
        }

    def finish(self, run_id: str, summary: dict[str, Any], status: str = "finished") -> None:
        self.store.finish_run(run_id, summary, status)
        if self.tee is not None:
            self.tee.finish(run_id, summary, status)
