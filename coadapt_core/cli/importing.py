"""`coadapt import`: load an export (CSV or Parquet, as `coadapt export` writes it) into a
store, merging without duplicating runs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.settings import setting, settings, shared


@settings
class ImportCommand:
    """`coadapt import`'s settings."""

    source: Path = setting(
        help="The folder `coadapt export -o` wrote, or a file in it.", argument="EXPORT"
    )
    format: str | None = setting(None, "csv or parquet (default: what the folder holds).")
    store: Any = shared(CommonOptions)
    as_json: Any = shared(CommonOptions)


def register(app: typer.Typer) -> None:
    options = options_of(ImportCommand)

    def import_command(**values: Any) -> None:
        """Merge exported runs into a store: new runs are added, a run already there is
        replaced only by a copy further along (finished, or updated later)."""
        o = filled(values, options)
        source, fmt = o["source"], o["format"]
        from coadapt_core.results.import_files import export_files

        export_files(
            source, fmt
        )  # a bad path or format is one line before the store is opened or made
        from coadapt_core.results.importer import import_tables
        from coadapt_core.results.store import ResultsStore

        with ResultsStore(o["store"]) as results:
            done = import_tables(results, source, fmt=fmt)
            url = results.url
        if o["as_json"]:
            print(json.dumps({**done.to_dict(), "store": url}))
            return
        rows = ", ".join(f"{n} {t}" for t, n in done.rows.items())
        print(
            f"imported {done.source} ({done.fmt}) into {url}: {len(done.added)} runs added, "
            f"{len(done.replaced)} replaced, {len(done.skipped)} already there; rows written: "
            f"{rows}"
        )

    register_command(app, "import", import_command, options)
