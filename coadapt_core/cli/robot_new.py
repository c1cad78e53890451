"""`coadapt robot new NAME --from FILE`: a starting robot spec written from a model file
(`coadapt_core.robot_spec.new`), then checked as every spec robot is."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from coadapt_core.cli.options import filled, options_of, register
from coadapt_core.settings import setting, settings


@settings
class RobotNew:
    """`coadapt robot new`'s settings."""

    name: str = setting(..., "The new robot's name (lower case, digits, _ and -).", argument="NAME")
    source: Path = setting(
        ..., "The robot's model file (MJCF, or URDF as MuJoCo reads it).", names=("--from",)
    )
    into: Path | None = setting(
        None,
        "Folder to write the robot's folder in (default: the first folder of "
        "COADAPT_ROBOT_PATH, else ~/.coadapt/robots).",
    )


_NEW = options_of(RobotNew)


def new_command(**values: Any) -> None:
    """Write a starting robot spec from a model file and list what to check."""
    from coadapt_core.robot_spec.discovery import ENV_ROBOT_PATH, search_path
    from coadapt_core.robot_spec.new import write_robot

    o = filled(values, _NEW)
    into = o["into"] if o["into"] is not None else search_path()[0]
    folder, notes = write_robot(o["name"], Path(o["source"]), Path(into))
    print(f"wrote {folder / 'robot.yaml'} and a copy of {Path(o['source']).name}")
    print("check (then edit robot.yaml and run `coadapt robot validate " + o["name"] + "`):")
    for line in notes:
        print(f"  - {line}")
    on_path = any(folder.parent.resolve() == p.resolve() for p in search_path())
    if not on_path:
        print(
            f"{folder.parent} is not on the robot path: export {ENV_ROBOT_PATH}={folder.parent}",
            file=sys.stderr,
        )


def register_new(app: Any) -> None:
    register(app, "new", new_command, _NEW, path="robot new")
