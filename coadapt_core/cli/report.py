"""`coadapt report`: Table 6/7 layouts and figures from stored results."""

from __future__ import annotations

import typer

from coadapt_core.cli.common import not_available


def register(app: typer.Typer) -> None:
    @app.command("report")
    def report_command() -> None:
        """Write tables (Markdown, CSV) and figures (PNG, HTML) from a run or grid."""
        not_available("report", "the results store and reports (issue 7)")
