"""Where a results store lives: `--store` and `$COADAPT_STORE` resolved to an SQLAlchemy
URL, the check that its database driver is installed, the engine (SQLite in WAL mode with a
busy timeout), the one-line error for a store that cannot be used, and the provenance a run
row records (the source tree's git commit)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from coadapt_core.errors import UserError

#: environment variable naming the store (a path or an SQLAlchemy URL)
ENV_STORE = "COADAPT_STORE"
#: set by `coadapt grid` for the runs it launches: which grid and which cell a run belongs to
ENV_GRID_ID = "COADAPT_GRID_ID"
ENV_GRID_CELL = "COADAPT_GRID_CELL"
#: default store file, relative to the working directory (the project folder)
DEFAULT_STORE_FILE = "coadapt.db"


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


def store_url_for_run(
    run_dir: str | os.PathLike, store: str | os.PathLike | None = None
) -> str | None:
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


class StoreError(UserError):
    """The results store cannot be used (not a database, damaged, unreachable): one line
    naming it and how to recover."""

    def __init__(self, url: str, exc: BaseException):
        detail = " ".join(str(getattr(exc, "orig", None) or exc).split())[:160]
        hint = ""
        if url.startswith("sqlite"):
            hint = (
                "; if the file is damaged, move it aside and run "
                "`coadapt run --resume <run folder>` for each run: "
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
            "sqlite:///coadapt.db or postgresql://user@host/db",
            field=field,
        ) from None
    try:
        dialect = parsed.get_dialect()
    except Exception:
        raise UserError(
            f"{field} '{url}': unknown database kind '{parsed.drivername}'; accepted: a file path, "
            "sqlite:///file.db, postgresql://user@host/db (with psycopg installed) "
            "or another SQLAlchemy URL",
            field=field,
        ) from None
    try:
        dialect.import_dbapi() if hasattr(dialect, "import_dbapi") else dialect.dbapi()
    except ImportError as exc:
        raise UserError(
            f"{field} '{url}': the database driver for '{parsed.drivername}' is not installed "
            f"({exc.name or exc}); install it (for PostgreSQL: pip install 'psycopg[binary]') "
            "or use an SQLite file",
            field=field,
        ) from None
    return url


def make_engine(url: str) -> sa.Engine:
    """The engine of a checked store URL: SQLite with a 60 s busy timeout and the pragmas
    below, any server database with pre-ping (a dropped connection is replaced)."""
    if url.startswith("sqlite"):
        engine = sa.create_engine(url, connect_args={"timeout": 60})
        sa.event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return sa.create_engine(url, pool_pre_ping=True)


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    # WAL lets readers (reports, the grid) run while a run writes; NORMAL sync is durable
    # against process crashes, which is what a killed run is
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA busy_timeout=60000")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()
