"""The built-in PyBullet simulator plugin ("pybullet"), for sim-to-sim transfer.

PyBullet is an optional extra (`pip install 'coadapt[pybullet]'`): it is imported only
when a simulator is built, so `coadapt plugins` lists this plugin either way. The simulator's
module is imported when the simulators are first listed (by the hook) or `PyBulletSimulator`
is named, not with this package: naming the robots loads none of it.
"""

from __future__ import annotations

from typing import Any

from coadapt_core import hookimpl

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"


@hookimpl
def coadapt_register_simulators() -> list[type]:
    from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator

    return [PyBulletSimulator]


def __getattr__(name: str) -> Any:
    """`PyBulletSimulator`, imported on first use (`from ... import PyBulletSimulator`)."""
    if name == "PyBulletSimulator":
        from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator

        return PyBulletSimulator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["PyBulletSimulator"]
