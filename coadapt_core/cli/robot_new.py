"""`coadapt robot new NAME --from FILE`: a new robot written from a model file by an
installed robot plugin that offers it (a robot class's optional classmethod
`write_from_model`, docs/plugins.md; coadapt's spec robots write a robot spec,
docs/your-robot.md)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from coadapt_core.cli.common import fail
from coadapt_core.cli.options import filled, options_of, register
from coadapt_core.settings import setting, settings


@settings
class RobotNew:
    """`coadapt robot new`'s settings."""

    name: str = setting(..., "The new robot's name (lower case, digits, _ and -).", argument="NAME")
    source: Path = setting(
        ..., "The robot's model file (MJCF, or URDF as MuJoCo reads it).", names=("--from",)
    )
    package_path: list[str] | None = setting(
        None,
        "A folder holding the ROS packages a URDF's package://NAME/... URIs name (a folder "
        "NAME in it, or it is NAME); repeat it for more. Searched after the model's folder "
        "and each folder above it.",
        names=("--package-path",),
    )
    into: Path | None = setting(
        None,
        "Folder to write the robot's folder in (default: the plugin's; for robot specs the "
        "first folder of COADAPT_ROBOT_PATH, else ~/.coadapt/robots).",
    )


_NEW = options_of(RobotNew)


def new_command(**values: Any) -> None:
    """Write a starting robot from a model file and list what to check."""
    from coadapt_core.plugins import get_registry

    o = filled(values, _NEW)
    registry = get_registry()
    writers: dict[Any, Any] = {}  # each writer once, however many robots share it
    for robot in registry.names("robot"):
        write = getattr(registry.get("robot", robot), "write_from_model", None)
        if callable(write):
            writers.setdefault(getattr(write, "__func__", write), write)
    into = None if o["into"] is None else str(o["into"])
    made = None
    # only asked for when given, so a writer without the option still answers
    extra = {"package_path": list(o["package_path"])} if o["package_path"] else {}
    for write in writers.values():
        made = write(o["name"], str(o["source"]), into, **extra)
        if made is not None:
            break
    if made is None:
        fail(f"--from '{o['source']}': no installed robot plugin writes a robot from a model file")
    folder = Path(made["folder"])
    print(f"wrote {folder} from {Path(o['source']).name}")
    copied = made.get("copied") or []
    if copied:
        print(f"copied {len(copied)} files the model needs into it:")
        for line in copied:
            print(f"  {line}")
    print(f"check (then edit it and run `coadapt robot validate {o['name']}`):")
    for line in made.get("notes") or []:
        print(f"  - {line}")
    if made.get("hint"):
        print(made["hint"], file=sys.stderr)


def register_new(app: Any) -> None:
    register(app, "new", new_command, _NEW, path="robot new")
