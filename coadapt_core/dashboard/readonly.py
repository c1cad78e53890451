"""The results store opened read-only for the dashboard: SQLite through a `file:...?mode=ro`
URI with `query_only` on (no pragma, upgrade or table is written, so the file stays
byte-identical), a server database in a read-only session where its dialect offers one.
An older store is read as it is (never upgraded); a newer one, or a database that holds no
coadapt results, is one line naming the store."""

from __future__ import annotations

import sqlite3
import urllib.parse
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from coadapt_core.errors import UserError
from coadapt_core.results.schema import check_version, recorded_version
from coadapt_core.results.storage import StoreError, check_database_url, resolve_store_url
from coadapt_core.results.store import ResultsStore

#: seconds a read waits for a writer's lock (SQLite in rollback-journal mode)
BUSY_SECONDS = 10


def sqlite_path(url: str) -> Path | None:
    """The file of an SQLite URL, or None for any other database (or SQLite in memory)."""
    parsed = sa.engine.make_url(url)
    if parsed.get_backend_name() != "sqlite" or parsed.database in (None, "", ":memory:"):
        return None
    return Path(parsed.database)


def _sqlite_engine(path: Path) -> sa.Engine:
    uri = f"file:{urllib.parse.quote(str(path))}?mode=ro"

    def connect() -> sqlite3.Connection:
        connection = sqlite3.connect(uri, uri=True, timeout=BUSY_SECONDS, check_same_thread=False)
        connection.execute("PRAGMA query_only=ON")
        return connection

    return sa.create_engine("sqlite://", creator=connect, poolclass=sa.pool.QueuePool)


def _server_engine(url: str) -> sa.Engine:
    backend = sa.engine.make_url(url).get_backend_name()
    connect_args: dict[str, Any] = {}
    if backend == "postgresql":
        connect_args["options"] = "-c default_transaction_read_only=on"
    engine = sa.create_engine(url, pool_pre_ping=True, connect_args=connect_args)
    if backend in ("mysql", "mariadb"):

        @sa.event.listens_for(engine, "connect")
        def _read_only(dbapi_connection: Any, _record: Any) -> None:
            cursor = dbapi_connection.cursor()
            cursor.execute("SET SESSION TRANSACTION READ ONLY")
            cursor.close()

    return engine


class ReadOnlyStore(ResultsStore):
    """A `ResultsStore` whose engine cannot write; only its reading methods are used."""

    def __init__(self, store: str | None = None):  # no super(): it would create or upgrade
        self.url = resolve_store_url(store)
        self.is_sqlite = self.url.startswith("sqlite")
        check_database_url(self.url, field="store")
        path = sqlite_path(self.url)
        if self.is_sqlite and path is not None and not path.is_file():
            raise UserError(
                f"store '{self.url}': no such file; give the path or URL of a results store "
                "(--store, or $COADAPT_STORE; `coadapt run` makes ./coadapt.db)",
                field="store",
            )
        self.engine = _sqlite_engine(path) if path is not None else _server_engine(self.url)
        self.schema_version = self._check()

    def _check(self) -> int:
        try:
            with self.engine.connect() as conn:
                if not sa.inspect(conn).has_table("runs"):
                    raise UserError(
                        f"store '{self.url}' holds no coadapt results (no table 'runs'); "
                        "give the store `coadapt run` or `coadapt grid` wrote",
                        field="store",
                    )
                version = recorded_version(conn) or 1
        except UserError:
            self.close()
            raise
        except sa.exc.SQLAlchemyError as exc:
            self.close()
            raise StoreError(self.url, exc) from None
        check_version(version, self.url)
        return version
