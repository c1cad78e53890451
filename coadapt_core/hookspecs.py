"""The pluggy hook specifications: one per plugin kind.

Each hook returns a list of classes (subclasses of the kind's abstract base class). The
registry in `coadapt_core.plugins` turns them into `{name: class}` per kind.
"""

from __future__ import annotations

import pluggy

hookspec = pluggy.HookspecMarker("coadapt")
hookimpl = pluggy.HookimplMarker("coadapt")


@hookspec
def coadapt_register_robots() -> list[type]:
    """Return Robot subclasses this plugin provides."""


@hookspec
def coadapt_register_simulators() -> list[type]:
    """Return Simulator subclasses this plugin provides."""


@hookspec
def coadapt_register_optimizers() -> list[type]:
    """Return Optimizer subclasses this plugin provides."""


@hookspec
def coadapt_register_objectives() -> list[type]:
    """Return Objective subclasses this plugin provides."""
