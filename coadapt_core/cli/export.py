"""`coadapt export`: the results store as flat CSV (or Parquet) tables."""

from __future__ import annotations

from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command("export")
    def export_command(
        out: Path = typer.Option(..., "-o", "--out", help="Folder to write the tables into."),
        fmt: str = typer.Option("csv", "--format", help="csv, or parquet (needs coadapt[parquet])."),
        run: list[str] = typer.Option(None, "--run", help="Export only this run (repeatable)."),
        store: str = typer.Option(None, "--store", help="Results store: a path or SQLAlchemy URL (default $COADAPT_STORE or ./coadapt.db)."),
    ) -> None:
        """Write runs, evaluations, training phases and checkpoints, one file per table."""
        from coadapt_core.results.export import export_tables
        from coadapt_core.results.store import ResultsStore

        with ResultsStore(store) as results:
            written = export_tables(results, out, fmt=fmt, run_ids=run or None)
        for table, path in written.items():
            print(f"{table}: {path}")
