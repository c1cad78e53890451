"""The built-in PyBullet simulator plugin ("pybullet"), for sim-to-sim transfer.

PyBullet is an optional extra (`pip install 'coadapt[pybullet]'`): it is imported only
when a simulator is built, so `coadapt plugins` lists this plugin either way.
"""

from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator

from coadapt_core import hookimpl

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"


@hookimpl
def coadapt_register_simulators() -> list[type]:
    return [PyBulletSimulator]


__all__ = ["PyBulletSimulator"]
