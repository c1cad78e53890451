"""The MuJoCo simulator plugin: many environments, one compiled model per design, stepped
on a C thread pool by `mujoco.batch` (see docs/simulators.md)."""

from __future__ import annotations

from coadapt_core import hookimpl

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.1"


@hookimpl
def coadapt_register_simulators() -> list[type]:
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    return [MujocoSimulator]
