"""Robots described by data: a YAML spec over the robot's own MJCF or URDF file
(docs/your-robot.md). This plugin registers the spec robots it ships (every folder beside
this file holding a `robot.yaml`: nezha and jingwei, which have no Python of their own) and
those of the user's folders (`COADAPT_ROBOT_PATH`, else `~/.coadapt/robots`); its robots write a
starting spec from a model file for `coadapt robot new` (`SpecRobot.write_from_model`).

`spec` reads the file (`fields` its field readers), `model` scales a model per design with
MuJoCo's `MjSpec` (`meshes` the meshes of scaled links), `build` makes each design's
`RobotModel` (`mjcf` and `urdf` write it), `kinematics` is the batched numeric leg IK,
`validation` the checks, `robot` the `Robot` a spec becomes, `discovery` where specs are
found, `new` the starting spec (with `legs`, `assumed` and `stand`).
"""

from __future__ import annotations

from pathlib import Path

from coadapt_core import hookimpl

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.2"
HERE = Path(__file__).resolve().parent
#: the spec's file name inside a robot folder (`<folder>/robot.yaml`)
SPEC_FILE = "robot.yaml"


@hookimpl
def coadapt_register_robots() -> list[type]:
    """The shipped robots by their folders' names, each read on first use (a test reads them
    all: a shipped spec that does not read, or names another robot, is a bug of this
    package), then the user's, read here (their names are in their specs, and a spec that
    does not read is listed with its problem)."""
    from coadapt_plugins.robots.specs.discovery import search_path, spec_robots_in

    shipped, _ = spec_robots_in(HERE, by_folder=True)
    users, _ = spec_robots_in(*search_path(), user=True)  # each problem is its class's line
    return shipped + users
