"""The built-in PyBullet simulator plugin ("pybullet"), for sim-to-sim transfer.

PyBullet is an optional extra (`pip install 'coadapt[pybullet]'`): it is imported only
when a simulator is built, so `coadapt plugins` lists this plugin either way.
"""

from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator

from coadapt_core import hookimpl


@hookimpl
def coadapt_register_simulators() -> list[type]:
    return [PyBulletSimulator]


__all__ = ["PyBulletSimulator"]
