"""`coadapt --version`: its callback, shared by the root command (`cli/__init__.py`, made
without pydantic) and its declaration (`cli/common_options.py`'s `RootOptions`)."""

from __future__ import annotations

import typer


def print_version(value: bool) -> None:
    """Print coadapt's version and end the command, when `--version` was given."""
    if value:
        from coadapt_core import __version__

        print(f"coadapt {__version__}")
        raise typer.Exit(0)
