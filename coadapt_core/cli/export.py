"""`coadapt export`: the results store as flat CSV (or Parquet) tables."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import typer

from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.settings import setting, settings, shared


@settings
class ExportCommand:
    """`coadapt export`'s settings."""

    out: Path = setting(help="Folder to write the tables into.", names=("-o", "--out"))
    format: Literal["csv", "parquet"] = setting(
        "csv", "Table format (parquet needs coadapt[parquet])."
    )
    run: list[str] | None = setting(None, "Export only this run (repeatable).", names=("--run",))
    store: Any = shared(CommonOptions)


def register(app: typer.Typer) -> None:
    options = options_of(ExportCommand)

    def export_command(**values: Any) -> None:
        """Write runs, evaluations, training phases, checkpoints and verifications, one file per
        table."""
        o = filled(values, options)  # a bad value is refused before the store's library loads
        from coadapt_core.results.export import export_tables
        from coadapt_core.results.store import ResultsStore

        with ResultsStore(o["store"]) as results:
            written = export_tables(results, o["out"], fmt=o["format"], run_ids=o["run"] or None)
        for table, path in written.items():
            print(f"{table}: {path}")

    register_command(app, "export", export_command, options)
