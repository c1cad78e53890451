"""The results store: every run, evaluated design, training phase and checkpoint in one
database (SQLite file `./coadapt.db` by default, any SQLAlchemy URL otherwise).

Writes commit immediately, one transaction per call, so a crash loses nothing that was
recorded. Rows are keyed so that recording the same evaluation twice (a resumed run redoing
the batch it was interrupted in) replaces the row instead of duplicating it.

The store's parts live beside it: the tables and their version in `schema`, the upgrade of
an older store in `migrate`, URLs, engine and provenance in `storage`, row decoding and the
run id scheme in `rows`, the grid's bookkeeping in `grid_cells`; import each name from the
module that defines it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Sequence
from typing import Any

import sqlalchemy as sa

from coadapt_core import __version__
from coadapt_core.errors import UserError
from coadapt_core.methods import DEFAULT_METHOD
from coadapt_core.results.grid_cells import GridCells
from coadapt_core.results.migrate import open_schema
from coadapt_core.results.rows import (
    Evaluation,
    dumps,
    loads,
    new_run_id,
    objective_list,
    run_dict,
)
from coadapt_core.results.schema import (
    EVALUATION_KINDS,
    checkpoints,
    evaluations,
    metadata,
    runs,
    training_phases,
    verifications,
)
from coadapt_core.results.storage import (
    ENV_GRID_CELL,
    ENV_GRID_ID,
    check_database_url,
    code_commit,
    make_engine,
    resolve_store_url,
)


class ResultsStore(GridCells):
    """SQLAlchemy Core access to the results database. Safe to share between processes
    (SQLite in WAL mode with a busy timeout; any server database as it is)."""

    def __init__(self, url: str | os.PathLike | None = None, *, create: bool = True):
        self.url = resolve_store_url(url)
        self.is_sqlite = self.url.startswith("sqlite")
        check_database_url(self.url, field="store")
        self.engine = make_engine(self.url)
        self.schema_version = open_schema(self.engine, self.url, create=create)

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> ResultsStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- runs ---------------------------------------------------------------------------
    def create_run(
        self, config: dict[str, Any], *, run_id: str | None = None, run_dir: str | None = None
    ) -> str:
        """Insert a run (status running); an existing id is marked running again (resume)
        and keeps its rows."""
        config = dict(config)
        objectives = objective_list(config)
        method = str(config.get("method", DEFAULT_METHOD))
        seed = config.get("seed")
        run_id = (
            run_id
            or config.get("run_id")
            or new_run_id(method, objectives, seed, config.get("optimizer"))
        )
        now = time.time()
        row = {
            "grid_id": config.get("grid_id") or os.environ.get(ENV_GRID_ID),
            "cell": config.get("grid_cell") or os.environ.get(ENV_GRID_CELL),
            "method": method,
            "objectives": ",".join(objectives),
            "terrain": config.get("terrain"),
            "optimizer": config.get("optimizer"),
            "simulator": config.get("sim", config.get("simulator")),
            "robot": config.get("robot"),
            "preset": config.get("preset"),
            "seed": int(seed) if seed is not None else None,
            "config": dumps(config),
            "code_version": __version__,
            "git_commit": code_commit(),
            "status": "running",
            "run_dir": run_dir or config.get("run_dir") or config.get("out"),
            "updated_at": now,
        }
        with self.engine.begin() as conn:
            existing = conn.execute(sa.select(runs.c.id).where(runs.c.id == run_id)).first()
            if existing is None:
                conn.execute(runs.insert().values(id=run_id, created_at=now, **row))
            else:
                # a resumed run: refresh what may have changed, keep creation time and rows
                keep = {k: v for k, v in row.items() if v is not None}
                keep["finished_at"] = None
                conn.execute(runs.update().where(runs.c.id == run_id).values(**keep))
        return str(run_id)

    def finish_run(
        self, run_id: str, summary: dict[str, Any] | None, status: str = "finished"
    ) -> None:
        now = time.time()
        values: dict[str, Any] = {"status": status, "updated_at": now}
        if summary is not None:
            values["summary"] = dumps(summary)
        if status == "finished":
            values["finished_at"] = now
        with self.engine.begin() as conn:
            result = conn.execute(runs.update().where(runs.c.id == run_id).values(**values))
        if result.rowcount == 0:
            raise UserError(f"run '{run_id}' is not in store {self.url}", field="run")

    def set_status(self, run_id: str, status: str) -> None:
        with self.engine.begin() as conn:
            conn.execute(
                runs.update()
                .where(runs.c.id == run_id)
                .values(status=status, updated_at=time.time())
            )

    def get_run(self, run_id: str) -> dict[str, Any]:
        with self.engine.connect() as conn:
            row = conn.execute(sa.select(runs).where(runs.c.id == run_id)).mappings().first()
        if row is None:
            raise UserError(f"run '{run_id}' is not in store {self.url}", field="run")
        return run_dict(row)

    def list_runs(
        self, *, grid_id: str | None = None, run_ids: Sequence[str] | None = None, **where: Any
    ) -> list[dict[str, Any]]:
        """Runs, oldest first, filtered by grid, ids or equality on columns."""
        query = sa.select(runs).order_by(runs.c.created_at, runs.c.id)
        if grid_id is not None:
            query = query.where(runs.c.grid_id == grid_id)
        if run_ids is not None:
            query = query.where(runs.c.id.in_(list(run_ids)))
        for column, value in where.items():
            query = query.where(runs.c[column] == value)
        with self.engine.connect() as conn:
            return [run_dict(r) for r in conn.execute(query).mappings()]

    def has_run(self, run_id: str) -> bool:
        with self.engine.connect() as conn:
            return conn.execute(sa.select(runs.c.id).where(runs.c.id == run_id)).first() is not None

    # -- evaluations ----------------------------------------------------------------------
    def record_evaluations(self, run_id: str, rows: Iterable[dict[str, Any]]) -> int:
        """Upsert evaluated designs in ONE transaction: a row with the same
        (run, outer, inner, kind, idx) as an existing one replaces it."""
        now = time.time()
        values = []
        for r in rows:
            kind = str(r["kind"])
            if kind not in EVALUATION_KINDS:
                raise UserError(
                    f"evaluation kind '{kind}' is not one of {', '.join(EVALUATION_KINDS)}",
                    field="kind",
                )
            values.append(
                {
                    "run_id": run_id,
                    "outer": int(r["outer"]),
                    "inner": int(r["inner"]),
                    "idx": int(r["idx"]),
                    "kind": kind,
                    "design": dumps([float(x) for x in r["design"]]),
                    "costs": dumps({str(k): float(v) for k, v in dict(r["costs"]).items()}),
                    "surrogate_error": None
                    if r.get("surrogate_error") is None
                    else dumps({str(k): float(v) for k, v in dict(r["surrogate_error"]).items()}),
                    "interactions": int(r.get("interactions", 0)),
                    "seconds": float(r.get("seconds", 0.0)),
                    "simulator": r.get("simulator"),
                    "created_at": now,
                }
            )
        if not values:
            return 0
        with self.engine.begin() as conn:
            for v in values:
                conn.execute(
                    evaluations.delete().where(
                        (evaluations.c.run_id == v["run_id"])
                        & (evaluations.c.outer == v["outer"])
                        & (evaluations.c.inner == v["inner"])
                        & (evaluations.c.kind == v["kind"])
                        & (evaluations.c.idx == v["idx"])
                    )
                )
            conn.execute(evaluations.insert(), values)
            conn.execute(runs.update().where(runs.c.id == run_id).values(updated_at=now))
        return len(values)

    def evaluations(
        self,
        run_id: str | None = None,
        *,
        kind: str | None = None,
        run_ids: Sequence[str] | None = None,
    ) -> list[Evaluation]:
        query = sa.select(evaluations).order_by(
            evaluations.c.run_id,
            evaluations.c.outer,
            evaluations.c.inner,
            evaluations.c.kind,
            evaluations.c.idx,
        )
        if run_id is not None:
            query = query.where(evaluations.c.run_id == run_id)
        if run_ids is not None:
            query = query.where(evaluations.c.run_id.in_(list(run_ids)))
        if kind is not None:
            query = query.where(evaluations.c.kind == kind)
        with self.engine.connect() as conn:
            return [
                Evaluation(
                    run_id=r["run_id"],
                    outer=r["outer"],
                    inner=r["inner"],
                    idx=r["idx"],
                    kind=r["kind"],
                    design=loads(r["design"]),
                    costs=loads(r["costs"]),
                    surrogate_error=loads(r["surrogate_error"]),
                    interactions=int(r["interactions"]),
                    seconds=float(r["seconds"]),
                    simulator=r["simulator"],
                    created_at=r["created_at"],
                )
                for r in conn.execute(query).mappings()
            ]

    def count_evaluations(self, run_id: str, kind: str | None = None) -> int:
        query = (
            sa.select(sa.func.count())
            .select_from(evaluations)
            .where(evaluations.c.run_id == run_id)
        )
        if kind is not None:
            query = query.where(evaluations.c.kind == kind)
        with self.engine.connect() as conn:
            return int(conn.execute(query).scalar_one())

    # -- training phases and checkpoints ----------------------------------------------------
    def record_training(
        self,
        run_id: str,
        *,
        outer: int,
        idx: int,
        steps: int,
        seconds: float,
        final_reward: float | None,
        extra: dict | None = None,
    ) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            conn.execute(
                training_phases.delete().where(
                    (training_phases.c.run_id == run_id)
                    & (training_phases.c.outer == outer)
                    & (training_phases.c.idx == idx)
                )
            )
            conn.execute(
                training_phases.insert().values(
                    run_id=run_id,
                    outer=int(outer),
                    idx=int(idx),
                    steps=int(steps),
                    seconds=float(seconds),
                    final_reward=None if final_reward is None else float(final_reward),
                    extra=dumps(extra or {}),
                    created_at=now,
                )
            )
            conn.execute(runs.update().where(runs.c.id == run_id).values(updated_at=now))

    def training(
        self, run_id: str | None = None, *, run_ids: Sequence[str] | None = None
    ) -> list[dict[str, Any]]:
        query = sa.select(training_phases).order_by(
            training_phases.c.run_id, training_phases.c.outer, training_phases.c.idx
        )
        if run_id is not None:
            query = query.where(training_phases.c.run_id == run_id)
        if run_ids is not None:
            query = query.where(training_phases.c.run_id.in_(list(run_ids)))
        with self.engine.connect() as conn:
            out = []
            for r in conn.execute(query).mappings():
                d = dict(r)
                d["extra"] = loads(d["extra"])
                out.append(d)
            return out

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            conn.execute(
                checkpoints.delete().where(
                    (checkpoints.c.run_id == run_id)
                    & (checkpoints.c.outer == outer)
                    & (checkpoints.c.path == str(path))
                )
            )
            conn.execute(
                checkpoints.insert().values(
                    run_id=run_id, outer=int(outer), path=str(path), created_at=now
                )
            )

    def checkpoints(self, run_id: str) -> list[dict[str, Any]]:
        query = (
            sa.select(checkpoints)
            .where(checkpoints.c.run_id == run_id)
            .order_by(checkpoints.c.outer, checkpoints.c.id)
        )
        with self.engine.connect() as conn:
            return [dict(r) for r in conn.execute(query).mappings()]

    # -- verifications (coadapt verify) ------------------------------------------------------
    def record_verification(self, run_id: str, result: dict[str, Any]) -> int:
        """One row per verified design of `result` (`coadapt_core.coadapt.verify.result_of`);
        a row with the same (run, key, role) is replaced. Returns the rows written."""
        now = time.time()
        values = []
        interactions = int(result.get("training_interactions") or 0) + int(
            result.get("evaluation_interactions") or 0
        )
        for entry in result.get("designs") or []:
            u, s = entry["universal"], entry["specialist"]
            values.append(
                {
                    "run_id": run_id,
                    "key": str(result["key"]),
                    "budget": int(result["budget"]),
                    "seed": int(result["seed"]),
                    "role": str(entry["role"]),
                    "design": dumps([float(x) for x in entry["design"]]),
                    "objective": str(entry["objective"]),
                    "universal_improvement": _float(u.get("improvement")),
                    "universal_improvement_se": _float(u.get("improvement_se")),
                    "specialist_improvement": _float(s.get("improvement")),
                    "specialist_improvement_se": _float(s.get("improvement_se")),
                    "difference": _float(entry.get("difference")),
                    "difference_se": _float(entry.get("difference_se")),
                    "verdict": str(entry["verdict"]),
                    "scenarios": int(result.get("scenarios") or 0),
                    "interactions": interactions,
                    "seconds": float(result.get("seconds") or 0.0),
                    "detail": dumps(
                        {
                            "universal": u,
                            "specialist": s,
                            "line": entry.get("line"),
                            "falls_more": entry.get("falls_more") or [],
                            "blocks": result.get("blocks"),
                        }
                    ),
                    "created_at": now,
                }
            )
        if not values:
            return 0
        with self.engine.begin() as conn:
            for v in values:
                conn.execute(
                    verifications.delete().where(
                        (verifications.c.run_id == run_id)
                        & (verifications.c.key == v["key"])
                        & (verifications.c.role == v["role"])
                    )
                )
            conn.execute(verifications.insert(), values)
            conn.execute(runs.update().where(runs.c.id == run_id).values(updated_at=now))
        return len(values)

    def verifications(self, run_ids: Sequence[str] | None = None) -> list[dict[str, Any]]:
        """Verification rows (design and detail decoded), by run, budget, seed and row id."""
        query = sa.select(verifications).order_by(
            verifications.c.run_id, verifications.c.budget, verifications.c.seed, verifications.c.id
        )
        if run_ids is not None:
            query = query.where(verifications.c.run_id.in_(list(run_ids)))
        with self.engine.connect() as conn:
            rows = [dict(r) for r in conn.execute(query).mappings()]
        for r in rows:
            r["design"] = loads(r["design"])
            r["detail"] = loads(r["detail"]) if r.get("detail") else {}
        return rows

    # -- raw tables (export) ----------------------------------------------------------------
    def table_rows(self, name: str, run_ids: Sequence[str] | None = None) -> list[dict[str, Any]]:
        table = metadata.tables[name]
        query = sa.select(table)
        if run_ids is not None:
            if "run_id" in table.c:
                query = query.where(table.c.run_id.in_(list(run_ids)))
            elif name == "runs":
                query = query.where(table.c.id.in_(list(run_ids)))
        with self.engine.connect() as conn:
            return [dict(r) for r in conn.execute(query).mappings()]


def _float(value: Any) -> float | None:
    return None if value is None else float(value)
