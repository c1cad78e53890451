"""Results that last: the results store (SQLite by default), its `RunRecorder` and export.
Experiments that write rows live in `coadapt_core.experiments`, reports in
`coadapt_core.analysis`."""

from coadapt_core.results.recorders import SqliteRecorder
from coadapt_core.results.storage import (
    DEFAULT_STORE_FILE,
    ENV_GRID_CELL,
    ENV_GRID_ID,
    ENV_STORE,
    resolve_store_url,
)
from coadapt_core.results.store import ResultsStore

__all__ = [
    "DEFAULT_STORE_FILE",
    "ENV_GRID_CELL",
    "ENV_GRID_ID",
    "ENV_STORE",
    "ResultsStore",
    "SqliteRecorder",
    "resolve_store_url",
]
