"""The Kuafu humanoid (Du et al. 2025, section 4.1): a parametric model whose thigh and
shank lengths (and, in the mixed space, hip and knee motor types) are the design."""

from __future__ import annotations

from coadapt_core import hookimpl


@hookimpl
def coadapt_register_robots() -> list[type]:
    from coadapt_plugins.robots.kuafu.robot import Kuafu

    return [Kuafu]
