"""`SqliteRecorder`: the `RunRecorder` protocol (coadapt_core/fitness.py) on the results
store, optionally teeing every call to a second recorder (the loop's JSON files).

Idempotence is what makes resume safe: each evaluation is keyed by (run, outer, inner,
kind, idx), idx counting the designs recorded for that (outer, inner, kind) in this
process. A resumed run that redoes the batch it was interrupted in records the same keys
again, so those rows are replaced, never duplicated, and the batches finished before the
crash stay as they were.
"""

from __future__ import annotations

import os
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

from coadapt_core.fitness import RunRecorder, TrainingResult
from coadapt_core.results.store import ResultsStore


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
        # next idx per (run, outer, inner, kind) and per (run, outer) for training phases
        self._next_eval: dict[tuple[str, int, int, str], int] = defaultdict(int)
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
        **extra: Any,
    ) -> None:
        key = (run_id, int(outer), int(inner), str(kind))
        idx = self._next_eval[key] if index is None else int(index)
        self._next_eval[key] = max(self._next_eval[key], idx + 1)
        # committed before returning: a crash right after this call loses nothing
        self.store.record_evaluations(
            run_id,
            [
                {
                    "outer": outer,
                    "inner": inner,
                    "idx": idx,
                    "kind": kind,
                    "design": list(design),
                    "costs": costs,
                    "surrogate_error": surrogate_error,
                    "interactions": interactions,
                    "seconds": seconds,
                    "simulator": extra.get("simulator"),
                }
            ],
        )
        if self.tee is not None:
            self.tee.record_evaluation(
                run_id,
                outer=outer,
                inner=inner,
                design=design,
                costs=costs,
                kind=kind,
                interactions=interactions,
                seconds=seconds,
                surrogate_error=surrogate_error,
            )

    def record_evaluation_batch(
        self,
        run_id: str,
        *,
        outer: int,
        inner: int,
        designs: Sequence[Sequence[float]],
        costs: Sequence[dict[str, float]],
        kind: str,
        interactions: Sequence[int] | int,
        seconds: Sequence[float] | float,
        surrogate_errors: Sequence[dict[str, float] | None] | None = None,
    ) -> None:
        """A whole evaluation batch in one transaction (idx 0..K-1): all or nothing."""
        k = len(designs)
        inter = [int(interactions)] * k if isinstance(interactions, int) else list(interactions)
        secs = [float(seconds)] * k if isinstance(seconds, int | float) else list(seconds)
        errs = list(surrogate_errors) if surrogate_errors is not None else [None] * k
        rows = [
            {
                "outer": outer,
                "inner": inner,
                "idx": i,
                "kind": kind,
                "design": list(designs[i]),
                "costs": costs[i],
                "surrogate_error": errs[i],
                "interactions": inter[i],
                "seconds": secs[i],
            }
            for i in range(k)
        ]
        self.store.record_evaluations(run_id, rows)
        key = (run_id, int(outer), int(inner), str(kind))
        self._next_eval[key] = max(self._next_eval[key], k)
        if self.tee is not None:
            for r in rows:
                self.tee.record_evaluation(
                    run_id,
                    outer=outer,
                    inner=inner,
                    design=r["design"],
                    costs=r["costs"],
                    kind=kind,
                    interactions=r["interactions"],
                    seconds=r["seconds"],
                    surrogate_error=r["surrogate_error"],
                )

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

        from coadapt_core.results.recorders import read_evaluations, read_jsonl
        from coadapt_core.errors import UserError
        from coadapt_core.validation import inside

        folder = Path(run_dir)
        have = {(e.outer, e.inner, e.kind, e.idx) for e in self.store.evaluations(run_id)}

        def number(value: Any) -> float:
            return math.nan if value is None else float(value)

        rows = [
            {**r, "costs": {k: number(v) for k, v in (r.get("costs") or {}).items()},
             "surrogate_error": None if r.get("surrogate_error") is None
             else {k: number(v) for k, v in r["surrogate_error"].items()}}
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
            self.store.record_training(run_id, outer=outer, idx=per_outer[outer], steps=int(t["steps"]),
                                       seconds=float(t["seconds"]), final_reward=t.get("mean_reward"),
                                       extra=t.get("extra") or {})
            per_outer[outer] += 1
            refilled_training += 1
        known = {(c["outer"], c["path"]) for c in self.store.checkpoints(run_id)}
        refilled_checkpoints = 0
        for c in read_jsonl(folder / "checkpoints.jsonl"):
            parts = Path(str(c.get("path", ""))).parts[-2:]  # checkpoints/<file>, wherever the folder was
            try:  # a path read from a file is used only inside the run folder
                path = str(inside(folder, Path(*parts), field="checkpoint")) if parts else None
            except UserError:
                path = None
            if path is None:
                continue
            if (int(c["outer"]), path) not in known:
                self.store.record_checkpoint(run_id, outer=int(c["outer"]), path=path)
                refilled_checkpoints += 1
        return {"evaluations": len(rows), "training_phases": refilled_training, "checkpoints": refilled_checkpoints}

    def finish(self, run_id: str, summary: dict[str, Any], status: str = "finished") -> None:
        self.store.finish_run(run_id, summary, status)
        if self.tee is not None:
            self.tee.finish(run_id, summary, status)
