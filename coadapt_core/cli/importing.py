"""`coadapt import`: load an export (CSV or Parquet, as `coadapt export` writes it) into a
store, merging without duplicating runs."""

from __future__ import annotations

import json
from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command("import")
    def import_command(
        source: Path = typer.Argument(..., metavar="EXPORT", help="The folder `coadapt export -o` wrote, or a file in it."),
        fmt: str = typer.Option(None, "--format", help="csv or parquet (default: what the folder holds)."),
        store: str = typer.Option(None, "--store", help="Results store: a path or SQLAlchemy URL (default $COADAPT_STORE or ./coadapt.db)."),
        as_json: bool = typer.Option(False, "--json", help="Print what was imported as one JSON line."),
    ) -> None:
        """Merge exported runs into a store: new runs are added, a run already there is replaced only by a copy further along (finished, or updated later)."""
        from coadapt_core.results.importer import export_files, import_tables
        from coadapt_core.results.store import ResultsStore

        export_files(source, fmt)  # a bad path or format is one line before the store is opened or made
        with ResultsStore(store) as results:
            done = import_tables(results, source, fmt=fmt)
            url = results.url
        if as_json:
            print(json.dumps({**done.to_dict(), "store": url}))
            return
        rows = ", ".join(f"{n} {t}" for t, n in done.rows.items())
        print(f"imported {done.source} ({done.fmt}) into {url}: {len(done.added)} runs added, "
              f"{len(done.replaced)} replaced, {len(done.skipped)} already there; rows written: {rows}")
