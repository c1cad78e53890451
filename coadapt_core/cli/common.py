"""Helpers shared by the CLI commands: registry-backed choices and one-line user errors."""

from __future__ import annotations

import sys
from typing import NoReturn

import typer

from coadapt_core.errors import UnknownPluginError
from coadapt_core.plugins import get_registry

#: exit code for bad input (usage errors, bad config, unknown plugin names)
EXIT_USAGE = 2
#: exit code for a command that is not available yet
EXIT_NOT_AVAILABLE = 3


def fail(message: str, code: int = EXIT_USAGE) -> NoReturn:
    """Print one line to stderr and exit."""
    print(f"error: {message}", file=sys.stderr)
    raise typer.Exit(code)


def not_available(command: str, arrives_with: str) -> NoReturn:
    """A command whose implementation arrives with a later piece of work: say so, exit 3."""
    print(
        f"coadapt {command}: not available yet — it arrives with {arrives_with}. "
        "Nothing was run.",
        file=sys.stderr,
    )
    raise typer.Exit(EXIT_NOT_AVAILABLE)


def choices(kind: str) -> list[str]:
    """Registered names for a plugin kind (empty when the registry cannot be built)."""
    try:
        return get_registry().names(kind)
    except Exception:
        return []


def choice_help(kind: str, text: str) -> str:
    names = choices(kind)
    return f"{text} One of: {', '.join(names)}." if names else text


def resolve(kind: str, name: str) -> type:
    """The plugin class for `name`, or a one-line error listing what is available."""
    try:
        return get_registry().get(kind, name)
    except UnknownPluginError as exc:
        fail(str(exc))
