"""`coadapt robot ...`: inspect, export, validate and render a robot's designs."""

from __future__ import annotations

import typer

from coadapt_core.cli.common import not_available

app = typer.Typer(help="Inspect, export, validate and render robot designs.", no_args_is_help=True)


@app.command("show")
def show_command() -> None:
    """A table of lengths, masses, motor limits and validation findings for one design."""
    not_available("robot show", "the Kuafu robot plugin (issue 3)")
