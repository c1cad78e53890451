"""`coadapt plugins`: what is installed, by kind, with its distribution and version."""

from __future__ import annotations

import json
import sys
from typing import Any

import typer

from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.plugin_api import PLUGIN_API_VERSION
from coadapt_core.plugins import KINDS, get_registry
from coadapt_core.settings import settings, shared


@settings
class PluginsCommand:
    """`coadapt plugins`'s settings."""

    as_json: Any = shared(CommonOptions)


def register(app: typer.Typer) -> None:
    options = options_of(PluginsCommand)

    def plugins_command(**values: Any) -> None:
        """List the robots, simulators, optimizers and objectives that are installed, with
        the plugin API version each was written for (this coadapt's is shown in the title)."""
        registry = get_registry()
        if values["as_json"]:
            out = {
                "plugin_api": PLUGIN_API_VERSION,
                "plugins": {
                    kind: [
                        info.to_dict()
                        for info in sorted(registry.entries[kind].values(), key=lambda i: i.name)
                    ]
                    for kind in KINDS
                },
                "broken": [
                    {"entry_point": b.entry_point, "distribution": b.distribution, "error": b.error}
                    for b in registry.broken
                ],
            }
            print(json.dumps(out, indent=2))
        else:
            from rich.console import Console  # the table only: --json prints without rich
            from rich.table import Table

            table = Table(title=f"coadapt plugins (plugin API {PLUGIN_API_VERSION})")
            for column in ("kind", "name", "distribution", "version", "api", "description"):
                table.add_column(column)
            for info in registry.all():
                table.add_row(
                    info.kind,
                    info.name,
                    info.distribution,
                    info.version,
                    info.api or "-",
                    getattr(info.cls, "description", ""),
                )
            Console().print(table)
        for broken in registry.broken:
            print(broken.line(), file=sys.stderr)

    register_command(app, "plugins", plugins_command, options)
