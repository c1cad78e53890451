"""Where spec robots are found: the folders of `COADAPT_ROBOT_PATH`, and any plugin's own.

A robot folder holds `robot.yaml` and the model file it names. `COADAPT_ROBOT_PATH` lists
folders (separated like PATH) that hold robot folders or are one; unset, it is
`~/.coadapt/robots`, where `coadapt robot new` writes. A plugin registers the spec robots of
a folder it ships by returning `spec_robots_in(folder)[0]` from `coadapt_register_robots`.
"""

from __future__ import annotations

import os
from pathlib import Path

from coadapt_core.errors import UserError
from coadapt_core.robot_spec.spec import SPEC_FILE

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


def spec_robots_in(*folders: Path) -> tuple[list[type], list[tuple[str, str]]]:
    """(Robot classes of every readable spec in `folders`, (its folder's name, one line) per
    spec that is not)."""
    from coadapt_core.robot_spec.robot import spec_robot_class

    classes, problems, seen = [], [], set()
    for folder in folders:
        for robot in robot_folders(Path(folder)):
            try:
                cls = spec_robot_class(robot)
            except UserError as exc:
                problems.append((robot.name, f"{robot / SPEC_FILE}: {exc}"))
                continue
            if cls.name in seen:
                problems.append(
                    f"{robot / SPEC_FILE}: robot name '{cls.name}' is taken earlier on the path"
                )
                continue
            seen.add(cls.name)
            classes.append(cls)
    return classes, problems


class SpecFolders:
    """The plugin that registers the spec robots of `COADAPT_ROBOT_PATH` (the registry
    adds it after every entry point): a spec that does not read, or whose name another
    robot already has, is reported as a broken plugin line instead of stopping the rest."""

    COADAPT_PLUGIN_API = "2.2"
    distribution = f"robot specs ({ENV_ROBOT_PATH})"

    def __init__(self, taken: set[str]):
        self.taken = taken
        self.problems: list[tuple[str, str]] = []

    def coadapt_register_robots(self) -> list[type]:
        classes, self.problems = spec_robots_in(*search_path())
        kept = []
        for cls in classes:
            if cls.name in self.taken:
                self.problems.append(
                    (
                        cls.name,
                        f"{cls.spec_path / SPEC_FILE}: robot name '{cls.name}' is taken by an "
                        "installed plugin; rename the spec",
                    )
                )
            else:
                kept.append(cls)
        return kept
