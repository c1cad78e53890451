"""The design's model files for the handoff folder: the robot plugin's MJCF and URDF, with
every file they reference (meshes, textures, height fields, included files) copied into
`assets/` beside them and the references rewritten to point there, so the folder opens in
MuJoCo, Pinocchio or a URDF viewer wherever it is moved.

A reference is looked up as given when absolute, else against the model's own asset
folders (MJCF `compiler` meshdir / texturedir / assetdir) under the folder of the module
that defines the robot class (where a plugin keeps its package data); `package://` and
`file://` URIs are resolved the same way after their scheme; a file the model carries in
memory (its "FORMAT:FILE" formats, e.g. a mesh stretched for the design) is written from
there. A referenced file that cannot be found is a one-line `UserError` naming it.
"""

from __future__ import annotations

import inspect
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.robot import carried_files

ASSET_DIR = "assets"
MJCF_NAME = "robot.xml"
URDF_NAME = "robot.urdf"
#: MJCF elements whose `file` attribute names a file of the model
_MJCF_COMPILER_DIRS = {
    "mesh": "meshdir",
    "skin": "meshdir",
    "hfield": "assetdir",
    "texture": "texturedir",
}


@dataclass
class ModelFiles:
    mjcf: Path
    urdf: Path
    assets: list[Path] = field(default_factory=list)  # copied files, inside the folder


def robot_folder(robot: Any) -> Path | None:
    """Folder of the module that defines the robot class (its package data lives there)."""
    try:
        return Path(inspect.getfile(type(robot))).resolve().parent
    except (TypeError, OSError):
        return None


def _strip_scheme(ref: str) -> str:
    for scheme in ("package://", "file://"):
        if ref.startswith(scheme):
            return ref[len(scheme) :]
    return ref


def _find(ref: str, bases: list[Path], what: str) -> Path:
    plain = _strip_scheme(ref)
    path = Path(plain)
    candidates = [path] if path.is_absolute() else [base / path for base in bases]
    for candidate in candidates:
        if candidate.is_file():
            return candidate.resolve()
    raise UserError(
        f"the robot's {what} references '{ref}', which is not a file (looked in "
        f"{', '.join(str(c.parent) for c in candidates) or 'nowhere'}); the handoff needs every "
        "model file",
        field="robot",
    )


class _Copier:
    """Copies referenced files into `<folder>/assets/`, one name per distinct source."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.copied: dict[Path, str] = {}

    def place(self, source: Path) -> str:
        if source not in self.copied:
            self.copied[source] = self._free_name(Path(source.name))
            shutil.copy2(source, self.folder / self.copied[source])
        return self.copied[source]

    def put(self, name: str, text: str) -> str:
        """A file the model carries in memory (a mesh stretched for this design)."""
        key = Path("<model>") / Path(name).name
        if key not in self.copied:
            self.copied[key] = self._free_name(Path(Path(name).name))
            (self.folder / self.copied[key]).write_text(text)
        return self.copied[key]

    def _free_name(self, wanted: Path) -> str:
        (self.folder / ASSET_DIR).mkdir(exist_ok=True)
        taken = set(self.copied.values())
        name, k = wanted.name, 1
        while f"{ASSET_DIR}/{name}" in taken:
            name, k = f"{wanted.stem}_{k}{wanted.suffix}", k + 1
        return f"{ASSET_DIR}/{name}"


def _mjcf_with_assets(
    text: str, bases: list[Path], copier: _Copier, carried: dict[str, str]
) -> str:
    if "file=" not in text:
        return text
    root = ET.fromstring(text)
    compiler = root.find("compiler")
    dirs = (
        {}
        if compiler is None
        else {k: compiler.get(k) for k in ("meshdir", "texturedir", "assetdir")}
    )
    changed = False
    for element in root.iter():
        ref = element.get("file")
        if ref is None:
            continue
        own = dirs.get(_MJCF_COMPILER_DIRS.get(element.tag, "")) or dirs.get("assetdir")
        search = [b / own for b in bases] + bases if own else bases
        if ref in carried:
            element.set("file", copier.put(ref, carried[ref]))
        else:
            element.set("file", copier.place(_find(ref, search, f"MJCF <{element.tag}>")))
        changed = True
    if changed and compiler is not None:  # references now name the folder's own files
        for key in ("meshdir", "texturedir", "assetdir"):
            if key in compiler.attrib:
                del compiler.attrib[key]
    return ET.tostring(root, encoding="unicode") + "\n" if changed else text


def _urdf_with_assets(
    text: str, bases: list[Path], copier: _Copier, carried: dict[str, str]
) -> str:
    if "filename=" not in text:
        return text
    root = ET.fromstring(text)
    for element in root.iter():
        ref = element.get("filename")
        if ref in carried:
            element.set("filename", copier.put(ref, carried[ref]))
        elif ref is not None:
            element.set("filename", copier.place(_find(ref, bases, f"URDF <{element.tag}>")))
    return ET.tostring(root, encoding="unicode") + "\n"


def write_model_files(robot: Any, model: Any, folder: Path) -> ModelFiles:
    """Write `model`'s MJCF and URDF (a `RobotModel` of `robot`) and their assets into `folder`."""
    home = robot_folder(robot)
    bases = [home] if home is not None else []
    copier = _Copier(folder)
    try:
        mjcf = _mjcf_with_assets(
            model.text("mjcf"), bases, copier, carried_files(model.formats, "mjcf")
        )
        urdf = _urdf_with_assets(
            model.text("urdf"), bases, copier, carried_files(model.formats, "urdf")
        )
    except ET.ParseError as exc:
        raise UserError(
            f"robot '{robot.name}' gives a model that is not XML ({exc})", field="robot"
        ) from None
    (folder / MJCF_NAME).write_text(mjcf)
    (folder / URDF_NAME).write_text(urdf)
    return ModelFiles(
        folder / MJCF_NAME, folder / URDF_NAME, [folder / rel for rel in copier.copied.values()]
    )
