"""`coadapt plugins`: what is installed, by kind, with its distribution and version."""

from __future__ import annotations

import json
import sys

import typer
from rich.console import Console
from rich.table import Table

from coadapt_core.plugins import KINDS, get_registry


def register(app: typer.Typer) -> None:
    @app.command("plugins")
    def plugins_command(
        as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
    ) -> None:
        """List the robots, simulators, optimizers and objectives that are installed."""
        registry = get_registry()
        if as_json:
            out = {
                "plugins": {kind: [info.to_dict() for info in sorted(registry.entries[kind].values(), key=lambda i: i.name)] for kind in KINDS},
                "broken": [{"entry_point": b.entry_point, "distribution": b.distribution, "error": b.error} for b in registry.broken],
            }
            print(json.dumps(out, indent=2))
        else:
            table = Table(title="coadapt plugins")
            for column in ("kind", "name", "distribution", "version", "description"):
                table.add_column(column)
            for info in registry.all():
                table.add_row(info.kind, info.name, info.distribution, info.version, getattr(info.cls, "description", ""))
            Console().print(table)
        for broken in registry.broken:
            print(broken.line(), file=sys.stderr)
