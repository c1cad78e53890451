"""Where spec robots are found: the folders of `COADAPT_ROBOT_PATH`, and any plugin's own.

A robot folder holds `robot.yaml` and the model file it names. `COADAPT_ROBOT_PATH` lists
folders (separated like PATH) that hold robot folders or are one; unset, it is
`~/.coadapt/robots`, where `coadapt robot new` writes. A plugin registers the spec robots of
a folder it ships by returning `spec_robots_in(folder)[0]` from `coadapt_register_robots`.
"""

from __future__ import annotations

import os
from pathlib import Path

from coadapt_plugins.robots.specs import SPEC_FILE

from coadapt_core.errors import UserError

ENV_ROBOT_PATH = "COADAPT_ROBOT_PATH"


def default_folder() -> Path:
    return Path.home() / ".coadapt" / "robots"


def search_path() -> list[Path]:
    """The folders spec robots are looked for in, in order."""
    raw = os.environ.get(ENV_ROBOT_PATH)
    if raw is None:
        return [default_folder()]
    return [Path(p).expanduser() for p in raw.split(os.pathsep) if p.strip()]


def robot_folders(folder: Path) -> list[Path]:
    """`folder` itself when it holds a spec, else its sub-folders that do (sorted)."""
    if (folder / SPEC_FILE).is_file():
        return [folder]
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if (p / SPEC_FILE).is_file())


def spec_robots_in(
    *folders: Path, user: bool = False, by_folder: bool = False
) -> tuple[list[type], list[str]]:
    """(Robot classes of every spec in `folders`, one line per spec that does not read).
    A spec that does not read still gives a class, named by its folder, that the registry
    refuses with that line (`Robot.unavailable`), so `--robot NAME` says what is wrong with
    it. `user`: robots of a user's folders, which give way to a plugin's robot of the same
    name (`yields_name`). `by_folder`: each robot named by its folder and read on first use
    (`folder_robot_class`: listing their names reads no file), for folders whose specs are
    known to read and to name their folders (a plugin's own, checked by its tests)."""
    from coadapt_plugins.robots.specs.robot import SpecRobot, folder_robot_class, spec_robot_class

    classes, problems, seen = [], [], set()
    for folder in folders:
        for robot in robot_folders(Path(folder)):
            try:
                cls = folder_robot_class(robot) if by_folder else spec_robot_class(robot)
            except UserError as exc:
                line = f"{robot / SPEC_FILE}: {exc}"
                problems.append(line)
                cls = type(f"UnreadableSpec_{len(problems)}", (SpecRobot,), {})
                cls.name, cls.unavailable, cls.spec_path = robot.name, line, robot
            if cls.name in seen:
                continue  # the first folder on the path wins, as on PATH
            seen.add(cls.name)
            cls.yields_name = user
            classes.append(cls)
    return classes, problems
