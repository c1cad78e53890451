"""The `coadapt` command line. Each command lives in its own module of this package; option
choices for plugins (`--robot`, `--sim`, `--optimizer`, `--objective`) come from the
registry, so a third-party plugin shows up in `--help` and in error messages."""

from __future__ import annotations

from typing import Any

import typer

from coadapt_core import __version__
from coadapt_core.cli import (
    dashboard,
    evaluate,
    export,
    grid,
    handoff,
    importing,
    landscape,
    plugins,
    report,
    robot,
    run,
    train,
)
from coadapt_core.cli.common import run_app
from coadapt_core.cli.options import DECLARED, bind, options_of
from coadapt_core.settings import setting, settings

app = typer.Typer(
    name="coadapt",
    help="Co-adapt a robot's design and its locomotion policy (Du et al. 2025).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        print(f"coadapt {__version__}")
        raise typer.Exit(0)


@settings
class RootOptions:
    """The options of `coadapt` itself, before a command."""

    version: bool = setting(False, "Print the version.", names=("--version",), callback=_version)


def _root(**values: Any) -> None:
    """Co-adapt a robot's design and its locomotion policy."""


_ROOT = options_of(RootOptions)
app.callback()(bind(_root, _ROOT))
DECLARED[""] = (_ROOT,)


run.register(app)
plugins.register(app)
app.add_typer(robot.app, name="robot")
train.register(app)
evaluate.register(app)
grid.register(app)
report.register(app)
export.register(app)
importing.register(app)
landscape.register(app)
handoff.register(app)
dashboard.register(app)


def main(argv: list[str] | None = None) -> int:
    """Entry point: runs the app and turns user errors into one line and exit code 2."""
    return run_app(app, argv)
