"""Errors coadapt raises on purpose.

A `UserError` is bad input from a person (a config value, a design, a plugin name): the CLI
prints its message as one line and exits with code 2 — never a traceback.
"""

from __future__ import annotations


class CoadaptError(Exception):
    """Base class of every error coadapt raises deliberately."""


class UserError(CoadaptError, ValueError):
    """Bad input. `field` names what was wrong; the message says what would be accepted."""

    def __init__(self, message: str, *, field: str | None = None):
        super().__init__(message)
        self.field = field


class DesignError(UserError):
    """A design outside its design space (bounds, arity, unknown discrete choice)."""


class PluginError(CoadaptError):
    """A plugin could not be loaded or conflicts with another plugin."""


def did_you_mean(value: object, accepted: list[str] | tuple[str, ...]) -> str:
    """ "; did you mean 'X'?" for the accepted value nearest `value` (a typo), else ''."""
    import difflib

    close = difflib.get_close_matches(str(value).lower(), [str(a) for a in accepted], 1, 0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


class UnknownPluginError(UserError):
    """A plugin name that no loaded plugin provides."""

    def __init__(
        self,
        kind: str,
        name: str,
        available: list[str],
        broken: list[str] | None = None,
        reason: str | None = None,
    ):
        listing = ", ".join(sorted(available)) or "(none loaded)"
        message = f"unknown {kind} '{name}'; available: {listing}" + did_you_mean(name, available)
        if broken:  # the name may belong to a plugin that failed to load: say which and why
            message += "; " + "; ".join(broken)
        if reason:  # the plugin of that name is known and refused: its reason alone
            message = reason
        super().__init__(message, field=kind)
        self.broken = list(broken or [])
        self.kind = kind
        self.name = name
        self.available = sorted(available)


class BackendUnavailable(CoadaptError):
    """A learner backend that cannot be built here (a simulator whose library is missing, a
    broken plugin); the message says why and is shown to the user as is."""


class NotYetAvailable(CoadaptError):
    """A command or feature whose implementation arrives with a later piece of work."""
