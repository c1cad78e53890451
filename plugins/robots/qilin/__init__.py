"""Qilin: a 12-joint trotting quadruped modelled on the Unitree Go1's published description,
whose thigh and calf lengths (and, in the mixed space, hip and knee motor types) are the
design."""

from __future__ import annotations

from coadapt_core import hookimpl

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"


@hookimpl
def coadapt_register_robots() -> list[type]:
    from coadapt_plugins.robots.qilin.robot import Qilin

    return [Qilin]
