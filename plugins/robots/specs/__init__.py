"""Spec robots shipped as data: every folder beside this file that holds a `robot.yaml` and
its model file is a robot (`coadapt_core.robot_spec`); none has Python of its own."""

from __future__ import annotations

from pathlib import Path

from coadapt_core import hookimpl

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.2"


@hookimpl
def coadapt_register_robots() -> list[type]:
    from coadapt_core.robot_spec.discovery import spec_robots_in

    classes, problems = spec_robots_in(Path(__file__).parent)
    if problems:  # a shipped spec that does not read is a bug of this package
        raise RuntimeError("; ".join(line for _, line in problems))
    return classes
