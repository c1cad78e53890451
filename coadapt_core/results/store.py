"""The results store: every run, evaluated design, training phase and checkpoint in one
database (SQLite file `./coadapt.db` by default, any SQLAlchemy URL otherwise).

Writes commit immediately, one transaction per call, so a crash loses nothing that was
recorded. Rows are keyed so that recording the same evaluation twice (a resumed run redoing
the batch it was interrupted in) replaces the row instead of duplicating it.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import time
import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from coadapt_core import __version__
from coadapt_core.errors import UserError
from coadapt_core.io import jsonable
from coadapt_core.methods import DEFAULT_METHOD

#: environment variable naming the store (a path or an SQLAlchemy URL)
ENV_STORE = "COADAPT_STORE"
#: set by `coadapt grid` for the runs it launches: which grid and which cell a run belongs to
ENV_GRID_ID = "COADAPT_GRID_ID"
ENV_GRID_CELL = "COADAPT_GRID_CELL"
#: default store file, relative to the working directory (the project folder)
DEFAULT_STORE_FILE = "coadapt.db"

#: evaluation kinds: the loop's two, plus transfer to a second simulator (report), the
#: common yardstick (report) and the grid evaluations of `coadapt landscape` (stored as "real")
EVALUATION_KINDS = ("real", "surrogate", "sim2sim", "common")
#: rows of sim-to-sim transfer (coadapt_core.experiments.transfer): their kind, and the outer
#: index they are stored with (they belong to no iteration of the run)
TRANSFER_KIND, TRANSFER_OUTER = "sim2sim", -1
#: rows of the common yardstick (coadapt_core.experiments.yardstick): their kind and outer index
COMMON_KIND, COMMON_OUTER = "common", -2
#: the method recorded by cost-landscape runs (coadapt_core.experiments.landscape)
LANDSCAPE_METHOD = "landscape"
#: statuses the store and the grid use (the loop may report others; they are kept as given)
RUN_STATUSES = ("running", "finished", "failed", "interrupted")

metadata = sa.MetaData()

runs = sa.Table(
    "runs",
    metadata,
    sa.Column("id", sa.String(80), primary_key=True),
    sa.Column("grid_id", sa.String(80), index=True),
    sa.Column("cell", sa.String(200), index=True),  # grid cell key, see grid.Cell.key
    sa.Column("method", sa.String(40), index=True),
    sa.Column("objectives", sa.String(200)),  # comma list, in cost order
    sa.Column("terrain", sa.String(40)),
    sa.Column("optimizer", sa.String(40)),
    sa.Column("simulator", sa.String(40)),
    sa.Column("robot", sa.String(40)),
    sa.Column("preset", sa.String(40)),
    sa.Column("seed", sa.Integer),
    sa.Column("config", sa.Text),  # JSON, the run's full configuration
    sa.Column("code_version", sa.String(40)),  # coadapt package version
    sa.Column("git_commit", sa.String(60)),  # commit of the source tree, "+dirty" when modified
    sa.Column("status", sa.String(20), nullable=False),
    sa.Column("run_dir", sa.Text),
    sa.Column("created_at", sa.Float, nullable=False),  # unix seconds
    sa.Column("updated_at", sa.Float, nullable=False),
    sa.Column("finished_at", sa.Float),
    sa.Column("summary", sa.Text),  # JSON, what the run reported at the end
)

evaluations = sa.Table(
    "evaluations",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
    sa.Column("outer", sa.Integer, nullable=False),  # outer iteration n of Algorithm 4
    sa.Column("inner", sa.Integer, nullable=False),  # optimizer iteration j within it
    sa.Column("idx", sa.Integer, nullable=False),  # position within the (outer, inner, kind) batch
    sa.Column("kind", sa.String(20), nullable=False),  # real | surrogate | sim2sim
    sa.Column("design", sa.Text, nullable=False),  # JSON list of design variable values
    sa.Column("costs", sa.Text, nullable=False),  # JSON {objective: cost}
    sa.Column("surrogate_error", sa.Text),  # JSON {objective: surrogate - real}, when known
    sa.Column("interactions", sa.BigInteger, nullable=False),
    sa.Column("seconds", sa.Float, nullable=False),
    sa.Column("simulator", sa.String(40)),  # set for sim2sim rows
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "outer", "inner", "kind", "idx", name="uq_evaluation"),
    sa.Index("ix_evaluations_run", "run_id", "kind"),
)

training_phases = sa.Table(
    "training_phases",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
    sa.Column("outer", sa.Integer, nullable=False),
    sa.Column("idx", sa.Integer, nullable=False),  # several phases per outer iteration (BO)
    sa.Column("steps", sa.BigInteger, nullable=False),  # environment interactions
    sa.Column("seconds", sa.Float, nullable=False),
    sa.Column("final_reward", sa.Float),
    sa.Column("extra", sa.Text),  # JSON
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "outer", "idx", name="uq_training_phase"),
)

checkpoints = sa.Table(
    "checkpoints",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False),
    sa.Column("outer", sa.Integer, nullable=False),
    sa.Column("path", sa.Text, nullable=False),
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "outer", "path", name="uq_checkpoint"),
)

grids = sa.Table(
    "grids",
    metadata,
    sa.Column("id", sa.String(80), primary_key=True),
    sa.Column("spec", sa.Text, nullable=False),  # JSON GridSpec
    sa.Column("created_at", sa.Float, nullable=False),
    sa.Column("updated_at", sa.Float, nullable=False),
)

grid_cells = sa.Table(
    "grid_cells",
    metadata,
    sa.Column("grid_id", sa.String(80), sa.ForeignKey("grids.id", ondelete="CASCADE"), primary_key=True),
    sa.Column("cell", sa.String(200), primary_key=True),
    sa.Column("run_id", sa.String(80)),
    sa.Column("status", sa.String(20), nullable=False),  # pending | running | finished | failed | skipped
    sa.Column("attempts", sa.Integer, nullable=False, default=0),
    sa.Column("last_error", sa.Text),
    sa.Column("updated_at", sa.Float, nullable=False),
)

TABLES = ("runs", "evaluations", "training_phases", "checkpoints", "grids", "grid_cells")


def resolve_store_url(store: str | os.PathLike | None = None) -> str:
    """An SQLAlchemy URL from `--store`: a URL (`postgresql://...`, `sqlite:///x.db`) is used
    as is, anything else is a file path; no value means `$COADAPT_STORE`, else ./coadapt.db."""
    value = str(store) if store is not None else os.environ.get(ENV_STORE) or DEFAULT_STORE_FILE
    if "://" in value:
        try:
            sa.engine.make_url(value)
        except Exception:
            raise UserError(
                f"store '{value}' is not a valid database URL; give a file path or a URL such as "
                "sqlite:///coadapt.db or postgresql://user@host/db",
                field="store",
            ) from None
        return value
    path = Path(value).expanduser().resolve()
    if path.is_dir():
        path = path / DEFAULT_STORE_FILE
    if not path.parent.is_dir():
        raise UserError(f"store '{value}': folder {path.parent} does not exist", field="store")
    return f"sqlite:///{path}"


#: `--store none` (or `$COADAPT_STORE=none`): a run writes its JSON files only
NO_STORE = ("none", "off", "no")


def store_url_for_run(run_dir: str | os.PathLike, store: str | os.PathLike | None = None) -> str | None:
    """The store a run records into: `store` when given, else `$COADAPT_STORE`, else
    coadapt.db beside the runs folder (the parent of the run folder's parent: ./coadapt.db
    for ./runs/<run id>, the same file `coadapt report` and `coadapt grid` use by default).
    None when the store is switched off ("none")."""
    value = str(store) if store else os.environ.get(ENV_STORE) or ""
    if value.strip().lower() in NO_STORE:
        return None
    if not value:
        project = Path(run_dir).resolve().parent.parent
        project.mkdir(parents=True, exist_ok=True)
        value = str(project / DEFAULT_STORE_FILE)
    return resolve_store_url(value)


def code_commit() -> str | None:
    """Git commit of the coadapt source tree, with '+dirty' when it has local changes; None
    when coadapt is not installed from a git checkout."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5
        )
        if head.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
        )
        return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


def _dumps(value: Any) -> str:
    # numpy scalars and arrays, paths and dataclass configs end up in run configs; NaN costs stay NaN
    return json.dumps(jsonable(value, nan=math.nan), default=str, sort_keys=True)


def _loads(text: str | None) -> Any:
    return None if text is None else json.loads(text)


def _objective_list(config: dict[str, Any]) -> list[str]:
    value = config.get("objectives", config.get("objective"))
    if value is None:
        return []
    if isinstance(value, str):
        return [v.strip() for v in value.split(",") if v.strip()]
    return [str(v) for v in value]


@dataclass
class Evaluation:
    """One stored evaluated design."""

    run_id: str
    outer: int
    inner: int
    idx: int
    kind: str
    design: list[float]
    costs: dict[str, float]
    surrogate_error: dict[str, float] | None
    interactions: int
    seconds: float
    simulator: str | None
    created_at: float


class StoreError(UserError):
    """The results store cannot be used (not a database, damaged, unreachable): one line
    naming it and how to recover."""

    def __init__(self, url: str, exc: BaseException):
        detail = " ".join(str(getattr(exc, "orig", None) or exc).split())[:160]
        hint = ""
        if url.startswith("sqlite"):
            hint = (
                "; if the file is damaged, move it aside and run `coadapt run --resume <run folder>` for each run: "
                "a resumed run records its rows again from its run folder"
            )
        super().__init__(f"store '{url}' cannot be used: {detail}{hint}", field="store")


def check_database_url(url: str, *, field: str = "store") -> str:
    """`url` if SQLAlchemy knows its dialect and the database driver is installed; a one-line
    `UserError` naming `field` otherwise (e.g. 'bad://x', or PostgreSQL without psycopg)."""
    try:
        parsed = sa.engine.make_url(url)
    except Exception:
        raise UserError(
            f"{field} '{url}' is not a valid database URL; give a file path or a URL such as "
            "sqlite:///coadapt.db or postgresql://user@host/db", field=field) from None
    try:
        dialect = parsed.get_dialect()
    except Exception:
        raise UserError(
            f"{field} '{url}': unknown database kind '{parsed.drivername}'; accepted: a file path, "
            "sqlite:///file.db, postgresql://user@host/db (with psycopg installed) or another SQLAlchemy URL",
            field=field) from None
    try:
        dialect.import_dbapi() if hasattr(dialect, "import_dbapi") else dialect.dbapi()
    except ImportError as exc:
        raise UserError(
            f"{field} '{url}': the database driver for '{parsed.drivername}' is not installed ({exc.name or exc}); "
            "install it (for PostgreSQL: pip install 'psycopg[binary]') or use an SQLite file",
            field=field) from None
    return url


def run_folder_of(run: dict[str, Any]) -> Path | None:
    """The run folder a store row names, or None when the row cannot be trusted with a path:
    its id must be a well-formed run id and its `run_dir` a folder named after that id (every
    run folder coadapt makes is `<out>/<run id>`). Store rows are data anyone sharing the
    store may have written; they never steer a path anywhere else."""
    from coadapt_core.validation import is_run_id

    run_id, run_dir = run.get("id"), run.get("run_dir")
    if not is_run_id(run_id) or not isinstance(run_dir, str) or not run_dir:
        return None
    folder = Path(run_dir).resolve()
    return folder if folder.name == run_id else None


def checkpoint_of(run: dict[str, Any], path: str | None) -> Path | None:
    """A checkpoint path from a store row (`checkpoints.path`, a summary's `checkpoint`),
    resolved inside the run's own folder (`run_folder_of`); None when it lies elsewhere."""
    from coadapt_core.validation import inside

    folder = run_folder_of(run)
    if folder is None or not path:
        return None
    try:
        return inside(folder, str(path))
    except UserError:
        return None


def best_of(run: dict[str, Any], real: Sequence[Evaluation]) -> tuple[list[float] | None, Any]:
    """(best design, its cost) of a run: what its summary recorded, else its real evaluation
    with the lowest cost of the first objective; (None, None) when it has neither."""
    summary = run.get("summary") or {}
    design, cost = summary.get("best_design"), summary.get("best_cost")
    first = run["objectives"][0] if run.get("objectives") else None
    if (design is None or cost is None) and real and first:
        best = min(real, key=lambda e: e.costs.get(first, float("inf")))
        design, cost = best.design, best.costs.get(first)
    return design, cost


class ResultsStore:
    """SQLAlchemy Core access to the results database. Safe to share between processes
    (SQLite in WAL mode with a busy timeout; any server database as it is)."""

    def __init__(self, url: str | os.PathLike | None = None, *, create: bool = True):
        self.url = resolve_store_url(url)
        self.is_sqlite = self.url.startswith("sqlite")
        check_database_url(self.url, field="store")
        if self.is_sqlite:
            self.engine = sa.create_engine(self.url, connect_args={"timeout": 60})
            sa.event.listen(self.engine, "connect", _sqlite_pragmas)
        else:
            self.engine = sa.create_engine(self.url, pool_pre_ping=True)
        if create:
            self._create_tables()

    def _create_tables(self) -> None:
        for attempt in range(3):
            try:
                metadata.create_all(self.engine)
                return
            except sa.exc.OperationalError as exc:
                # two processes creating a fresh database at once: the loser sees the
                # winner's tables half made; looking again finds them all
                if "already exists" in str(exc.orig) and attempt < 2:
                    time.sleep(0.2)
                    continue
                raise UserError(f"store '{self.url}' cannot be opened: {exc.orig}", field="store") from None
            except sa.exc.SQLAlchemyError as exc:  # not a database, damaged, unreachable server
                raise StoreError(self.url, exc) from None

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> ResultsStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- runs ---------------------------------------------------------------------------
    def create_run(self, config: dict[str, Any], *, run_id: str | None = None, run_dir: str | None = None) -> str:
        """Insert a run (status running); an existing id is marked running again (resume)
        and keeps its rows."""
        config = dict(config)
        objectives = _objective_list(config)
        method = str(config.get("method", DEFAULT_METHOD))
        seed = config.get("seed")
        run_id = run_id or config.get("run_id") or new_run_id(method, objectives, seed, config.get("optimizer"))
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
            "config": _dumps(config),
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

    def finish_run(self, run_id: str, summary: dict[str, Any] | None, status: str = "finished") -> None:
        now = time.time()
        values: dict[str, Any] = {"status": status, "updated_at": now}
        if summary is not None:
            values["summary"] = _dumps(summary)
        if status == "finished":
            values["finished_at"] = now
        with self.engine.begin() as conn:
            result = conn.execute(runs.update().where(runs.c.id == run_id).values(**values))
        if result.rowcount == 0:
            raise UserError(f"run '{run_id}' is not in store {self.url}", field="run")

    def set_status(self, run_id: str, status: str) -> None:
        with self.engine.begin() as conn:
            conn.execute(runs.update().where(runs.c.id == run_id).values(status=status, updated_at=time.time()))

    def get_run(self, run_id: str) -> dict[str, Any]:
        with self.engine.connect() as conn:
            row = conn.execute(sa.select(runs).where(runs.c.id == run_id)).mappings().first()
        if row is None:
            raise UserError(f"run '{run_id}' is not in store {self.url}", field="run")
        return _run_dict(row)

    def list_runs(self, *, grid_id: str | None = None, run_ids: Sequence[str] | None = None, **where: Any) -> list[dict[str, Any]]:
        """Runs, oldest first, filtered by grid, ids or equality on columns."""
        query = sa.select(runs).order_by(runs.c.created_at, runs.c.id)
        if grid_id is not None:
            query = query.where(runs.c.grid_id == grid_id)
        if run_ids is not None:
            query = query.where(runs.c.id.in_(list(run_ids)))
        for column, value in where.items():
            query = query.where(runs.c[column] == value)
        with self.engine.connect() as conn:
            return [_run_dict(r) for r in conn.execute(query).mappings()]

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
                raise UserError(f"evaluation kind '{kind}' is not one of {', '.join(EVALUATION_KINDS)}", field="kind")
            values.append(
                {
                    "run_id": run_id,
                    "outer": int(r["outer"]),
                    "inner": int(r["inner"]),
                    "idx": int(r["idx"]),
                    "kind": kind,
                    "design": _dumps([float(x) for x in r["design"]]),
                    "costs": _dumps({str(k): float(v) for k, v in dict(r["costs"]).items()}),
                    "surrogate_error": None
                    if r.get("surrogate_error") is None
                    else _dumps({str(k): float(v) for k, v in dict(r["surrogate_error"]).items()}),
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

    def evaluations(self, run_id: str | None = None, *, kind: str | None = None, run_ids: Sequence[str] | None = None) -> list[Evaluation]:
        query = sa.select(evaluations).order_by(
            evaluations.c.run_id, evaluations.c.outer, evaluations.c.inner, evaluations.c.kind, evaluations.c.idx
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
                    design=_loads(r["design"]),
                    costs=_loads(r["costs"]),
                    surrogate_error=_loads(r["surrogate_error"]),
                    interactions=int(r["interactions"]),
                    seconds=float(r["seconds"]),
                    simulator=r["simulator"],
                    created_at=r["created_at"],
                )
                for r in conn.execute(query).mappings()
            ]

    def count_evaluations(self, run_id: str, kind: str | None = None) -> int:
        query = sa.select(sa.func.count()).select_from(evaluations).where(evaluations.c.run_id == run_id)
        if kind is not None:
            query = query.where(evaluations.c.kind == kind)
        with self.engine.connect() as conn:
            return int(conn.execute(query).scalar_one())

    # -- training phases and checkpoints ----------------------------------------------------
    def record_training(
        self, run_id: str, *, outer: int, idx: int, steps: int, seconds: float, final_reward: float | None, extra: dict | None = None
    ) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            conn.execute(
                training_phases.delete().where(
                    (training_phases.c.run_id == run_id) & (training_phases.c.outer == outer) & (training_phases.c.idx == idx)
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
                    extra=_dumps(extra or {}),
                    created_at=now,
                )
            )
            conn.execute(runs.update().where(runs.c.id == run_id).values(updated_at=now))

    def training(self, run_id: str | None = None, *, run_ids: Sequence[str] | None = None) -> list[dict[str, Any]]:
        query = sa.select(training_phases).order_by(training_phases.c.run_id, training_phases.c.outer, training_phases.c.idx)
        if run_id is not None:
            query = query.where(training_phases.c.run_id == run_id)
        if run_ids is not None:
            query = query.where(training_phases.c.run_id.in_(list(run_ids)))
        with self.engine.connect() as conn:
            out = []
            for r in conn.execute(query).mappings():
                d = dict(r)
                d["extra"] = _loads(d["extra"])
                out.append(d)
            return out

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            conn.execute(
                checkpoints.delete().where(
                    (checkpoints.c.run_id == run_id) & (checkpoints.c.outer == outer) & (checkpoints.c.path == str(path))
                )
            )
            conn.execute(checkpoints.insert().values(run_id=run_id, outer=int(outer), path=str(path), created_at=now))

    def checkpoints(self, run_id: str) -> list[dict[str, Any]]:
        query = sa.select(checkpoints).where(checkpoints.c.run_id == run_id).order_by(checkpoints.c.outer, checkpoints.c.id)
        with self.engine.connect() as conn:
            return [dict(r) for r in conn.execute(query).mappings()]

    # -- grids ----------------------------------------------------------------------------
    def save_grid(self, grid_id: str, spec: dict[str, Any]) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            if conn.execute(sa.select(grids.c.id).where(grids.c.id == grid_id)).first() is None:
                conn.execute(grids.insert().values(id=grid_id, spec=_dumps(spec), created_at=now, updated_at=now))
            else:
                conn.execute(grids.update().where(grids.c.id == grid_id).values(spec=_dumps(spec), updated_at=now))

    def get_grid(self, grid_id: str) -> dict[str, Any] | None:
        with self.engine.connect() as conn:
            row = conn.execute(sa.select(grids).where(grids.c.id == grid_id)).mappings().first()
        return None if row is None else {"id": row["id"], "spec": _loads(row["spec"]), "created_at": row["created_at"]}

    def list_grids(self) -> list[str]:
        with self.engine.connect() as conn:
            return [r[0] for r in conn.execute(sa.select(grids.c.id).order_by(grids.c.created_at))]

    def set_cell(self, grid_id: str, cell: str, *, status: str, run_id: str | None = None, error: str | None = None, attempt: bool = False) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            row = conn.execute(
                sa.select(grid_cells).where((grid_cells.c.grid_id == grid_id) & (grid_cells.c.cell == cell))
            ).mappings().first()
            if row is None:
                conn.execute(
                    grid_cells.insert().values(
                        grid_id=grid_id, cell=cell, run_id=run_id, status=status, attempts=int(attempt), last_error=error, updated_at=now
                    )
                )
            else:
                values: dict[str, Any] = {"status": status, "updated_at": now, "last_error": error}
                if run_id is not None:
                    values["run_id"] = run_id
                if attempt:
                    values["attempts"] = row["attempts"] + 1
                conn.execute(
                    grid_cells.update().where((grid_cells.c.grid_id == grid_id) & (grid_cells.c.cell == cell)).values(**values)
                )

    def cells(self, grid_id: str) -> dict[str, dict[str, Any]]:
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(grid_cells).where(grid_cells.c.grid_id == grid_id)).mappings()
            return {r["cell"]: dict(r) for r in rows}

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


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    # WAL lets readers (reports, the grid) run while a run writes; NORMAL sync is durable
    # against process crashes, which is what a killed run is
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA busy_timeout=60000")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()


def _run_dict(row: Any) -> dict[str, Any]:
    d = dict(row)
    d["config"] = _loads(d["config"]) or {}
    d["summary"] = _loads(d["summary"])
    d["objectives"] = [o for o in (d["objectives"] or "").split(",") if o]
    return d


def new_run_id(method: str, objectives: Sequence[str], seed: Any = None, optimizer: str | None = None) -> str:
    """The one run-id scheme, for run folders and store rows alike:
    `<UTC yyyymmdd-hhmmss>-<method>[-<optimizer>]-<objectives joined by +>[-s<seed>]-<6 hex>`
    (time first, so ids sort by start; random last, so two processes never share one)."""
    parts = [time.strftime("%Y%m%d-%H%M%S", time.gmtime()), str(method)]
    if optimizer:
        parts.append(str(optimizer))
    parts.append("+".join(objectives) or "run")
    if seed is not None:
        parts.append(f"s{seed}")
    return "-".join([*parts, uuid.uuid4().hex[:6]])
