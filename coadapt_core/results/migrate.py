"""Opening a store at this coadapt's schema version: a new database gets the tables and the
version; an older store is copied aside and upgraded in place by alembic, running the
scripts in `results/migrations/`; a newer one is refused (`schema.check_version`).

All of it happens in one transaction that holds SQLite's write lock from the first look
(`BEGIN IMMEDIATE`), so processes opening one store at once (a grid's first cells) wait for
each other instead of creating or upgrading it twice; a failed upgrade leaves the store as it
was. A new store gets no alembic table: its version is in `store_info`, and an upgrade stamps
the revision of that version before running the scripts after it.
"""

from __future__ import annotations

import sqlite3
import sys
import time
from pathlib import Path

import sqlalchemy as sa

from coadapt_core.errors import UserError
from coadapt_core.results.schema import (
    SCHEMA_VERSION,
    SCHEMA_VERSION_KEY,
    check_version,
    metadata,
    recorded_version,
    store_info,
)
from coadapt_core.results.storage import StoreError

#: the folder of alembic's environment and version scripts, shipped in the package
MIGRATIONS = Path(__file__).with_name("migrations")
#: the alembic revision of each schema version (versions/<revision>_*.py)
REVISIONS = {1: "0001", 2: "0002", 3: "0003"}
#: alembic's record of the revision; optuna's studies, which may share the database, keep
#: theirs in `alembic_version`
VERSION_TABLE = "coadapt_alembic_version"


def open_schema(engine: sa.Engine, url: str, *, create: bool) -> int:
    """The store's schema version once it is usable by this coadapt (always SCHEMA_VERSION
    unless an empty database is opened without `create`). Prints one line to stderr when it
    upgraded the store, naming the backup copy."""
    for attempt in range(3):
        try:
            with engine.connect() as conn:
                if engine.dialect.name == "sqlite":
                    conn.exec_driver_sql("BEGIN IMMEDIATE")
                version, note = _prepare(conn, url, create=create)
                conn.commit()
        except UserError:
            raise
        except (sa.exc.OperationalError, sa.exc.ProgrammingError, sa.exc.IntegrityError) as exc:
            # a server database has no BEGIN IMMEDIATE: two processes creating a fresh one at
            # once, the loser sees the winner's tables; looking again finds them
            if _raced(exc) and attempt < 2:
                time.sleep(0.2)
                continue
            raise StoreError(url, exc) from None
        except sa.exc.SQLAlchemyError as exc:  # not a database, damaged, unreachable server
            raise StoreError(url, exc) from None
        if note:
            print(note, file=sys.stderr, flush=True)
        return version
    raise AssertionError("unreachable")


def _raced(exc: sa.exc.SQLAlchemyError) -> bool:
    return isinstance(exc, sa.exc.IntegrityError) or "already exists" in str(exc.orig)


def _prepare(conn: sa.Connection, url: str, *, create: bool) -> tuple[int, str | None]:
    """(version, the line to print) for the store behind `conn`, created or upgraded."""
    if not sa.inspect(conn).has_table("runs"):
        if not create:
            return SCHEMA_VERSION, None  # an empty database, left as it is
        metadata.create_all(conn)
        conn.execute(store_info.insert().values(key=SCHEMA_VERSION_KEY, value=str(SCHEMA_VERSION)))
        return SCHEMA_VERSION, None
    version = recorded_version(conn) or 1  # none recorded: the layout before versions were
    check_version(version, url)
    if version == SCHEMA_VERSION:
        return version, None
    backup = backup_copy(conn, url, version)
    upgrade(conn, version)
    copied = (
        f"the store as it was is copied to {backup}"
        if backup
        else "no backup copy was made (a server database: back it up with its own tools)"
    )
    return SCHEMA_VERSION, (
        f"store '{url}' upgraded from schema version {version} to {SCHEMA_VERSION}; {copied}"
    )


def upgrade(conn: sa.Connection, version: int) -> None:
    """Run the alembic scripts after `version`'s revision up to this coadapt's, on `conn`
    and inside its transaction."""
    from alembic import command
    from alembic.config import Config
    from alembic.runtime.migration import MigrationContext

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS).replace("%", "%%"))
    config.attributes["connection"] = conn
    current = MigrationContext.configure(
        conn, opts={"version_table": VERSION_TABLE}
    ).get_current_revision()
    if current is None:
        command.stamp(config, REVISIONS[version])
    command.upgrade(config, REVISIONS[SCHEMA_VERSION])


def backup_copy(conn: sa.Connection, url: str, version: int) -> Path | None:
    """A copy of an SQLite store beside it, `<name>.v<version>-backup-<UTC time>.db`, made
    through SQLite's backup API (so rows still in the WAL file are in it); None for an
    in-memory or server database."""
    database = sa.engine.make_url(url).database
    if conn.dialect.name != "sqlite" or not database or database == ":memory:":
        return None
    path = Path(database)
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    target = path.with_name(f"{path.stem}.v{version}-backup-{stamp}.db")
    n = 1
    while target.exists():
        n += 1
        target = path.with_name(f"{path.stem}.v{version}-backup-{stamp}-{n}.db")
    # a second connection reads what is committed; `conn` holds the write lock, so that is
    # the store as the upgrade finds it
    source, copy = sqlite3.connect(path, timeout=60), sqlite3.connect(target)
    try:
        source.backup(copy)
    finally:
        copy.close()
        source.close()
    return target
