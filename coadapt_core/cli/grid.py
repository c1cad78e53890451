"""`coadapt grid`: ablation grids (method x objective x terrain x seed)."""

from __future__ import annotations

import typer

from coadapt_core.cli.common import not_available


def register(app: typer.Typer) -> None:
    @app.command("grid")
    def grid_command() -> None:
        """Run an ablation grid locally or on a Ray cluster, skipping finished cells."""
        not_available("grid", "the results store and grids (issue 7)")
