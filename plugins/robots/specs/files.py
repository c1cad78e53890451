"""The files a model file needs, found where they live (docs/your-robot.md#where-a-model-lives).

An MJCF names its includes (`<include file>`, nested, each relative to the including file's
folder or the main file's) and its assets (mesh, texture, height field and skin files, under
`<compiler meshdir texturedir assetdir>`); a URDF names its meshes by a path (relative to its
folder) or a ROS `package://NAME/...` URI. `model_files` lists them with where each is,
reading the XML only (no MuJoCo): `robot new` copies them beside the spec, the spec robot's
version hashes them, and `loader_assets` hands MuJoCo the bytes of those it cannot find
itself (a `package://` URI; a file the spec's `assets` maps into the robot's folder).

A `package://NAME/rest` is looked for in the model's folder and each folder above it (a
folder `NAME` there, or the folder itself when it is named `NAME`), then in each of the
`package_paths` likewise; one that resolves nowhere is refused in one line naming the package
and the folders searched.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from coadapt_core.errors import UserError

PACKAGE = "package://"
_TEXTURE_FILES = ("file", "fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")


@dataclass(frozen=True)
class ModelFile:
    """A file the model names: `reference` as written, `path` where it is (absolute)."""

    reference: str
    path: Path
    kind: str  # include, mesh, texture, hfield, skin, model

    @property
    def packaged(self) -> tuple[str, str] | None:
        """(package name, path inside it) of a `package://` reference, else None."""
        if not self.reference.startswith(PACKAGE):
            return None
        name, _, rest = self.reference[len(PACKAGE) :].partition("/")
        return name, rest


def _xml(path: Path, what: str) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        first = " ".join(str(exc).split())
        raise UserError(
            f"{what} '{path.name}' is not readable XML: {first}", field="model"
        ) from None


def package_folder(name: str, model: Path, package_paths: tuple[Path, ...] = ()) -> Path:
    """The folder of ROS package `name` for a model at `model` (module docstring)."""
    here = Path(model).resolve().parent
    searched = [here, *here.parents]
    searched += [Path(p).expanduser().resolve() for p in package_paths]
    for folder in searched:
        if folder.name == name and folder.is_dir():
            return folder
        if (folder / name).is_dir():
            return folder / name
    where = ", ".join(str(f) for f in searched)
    raise UserError(
        f"package '{name}' (package://{name}/...) is in none of the folders searched: {where}; "
        "give its parent folder with --package-path",
        field="package-path",
    )


def _resolved(base: Path, folder: str, name: str) -> Path:
    if os.path.isabs(name):
        return Path(name)
    return base / folder / name if folder else base / name


def _mjcf_files(model: Path, root: ET.Element, assets: dict[str, Path]) -> list[ModelFile]:
    """Includes first (depth first, as MuJoCo reads them), then assets."""
    home = model.parent
    out: list[ModelFile] = []
    elements: list[ET.Element] = []

    def walk(element: ET.Element, here: Path) -> None:
        elements.append(element)
        for child in element:
            if child.tag == "include" and child.get("file"):
                ref = child.get("file", "")
                candidates = [_resolved(here, "", ref), _resolved(home, "", ref)]
                found = next((c for c in candidates if c.is_file()), candidates[0])
                out.append(ModelFile(ref, found.resolve(), "include"))
                if found.is_file():
                    walk(_xml(found, "included file"), found.parent)
            else:
                walk(child, here)

    walk(root, home)
    compiler: dict[str, str] = {}
    for e in elements:
        if e.tag == "compiler":
            compiler.update({k: v for k, v in e.attrib.items() if k.endswith("dir")})
    assetdir = compiler.get("assetdir", "")
    meshdir = compiler.get("meshdir", assetdir)
    texturedir = compiler.get("texturedir", assetdir)
    seen = {f.reference for f in out}
    for e in elements:
        if e.tag in ("mesh", "hfield", "skin", "model"):
            names, folders = ["file"], [meshdir, assetdir, ""]
        elif e.tag == "texture":
            names, folders = list(_TEXTURE_FILES), [texturedir, assetdir, ""]
        else:
            continue
        for attr in names:
            ref = e.get(attr)
            if not ref or ref in seen:
                continue
            seen.add(ref)
            if ref in assets:
                out.append(ModelFile(ref, assets[ref], e.tag))
                continue
            candidates = [_resolved(home, f, ref) for f in folders]
            found = next((c for c in candidates if c.is_file()), candidates[0])
            out.append(ModelFile(ref, found.resolve(), e.tag))
    return out


def _urdf_files(
    model: Path, root: ET.Element, package_paths: tuple[Path, ...], assets: dict[str, Path]
) -> list[ModelFile]:
    home = model.parent
    meshdir = ""
    for e in root.iter("compiler"):  # the <mujoco><compiler meshdir=.../> extension
        meshdir = e.get("meshdir", e.get("assetdir", meshdir))
    out, seen = [], set()
    for e in root.iter("mesh"):
        ref = e.get("filename")
        if not ref or ref in seen:
            continue
        seen.add(ref)
        if ref in assets:
            out.append(ModelFile(ref, assets[ref], "mesh"))
        elif ref.startswith(PACKAGE):
            name, _, rest = ref[len(PACKAGE) :].partition("/")
            out.append(ModelFile(ref, (package_folder(name, model, package_paths) / rest), "mesh"))
        else:
            plain = ref[len("file://") :] if ref.startswith("file://") else ref
            candidates = [_resolved(home, meshdir, plain), _resolved(home, "", plain)]
            found = next((c for c in candidates if c.is_file()), candidates[0])
            out.append(ModelFile(ref, found.resolve(), "mesh"))
    return out


def is_urdf(model: Path) -> bool:
    return Path(model).suffix.lower() == ".urdf" or _xml(Path(model), "model").tag == "robot"


def model_files(
    model: Path, package_paths: tuple[Path, ...] = (), assets: dict[str, Path] | None = None
) -> list[ModelFile]:
    """Every file `model` names (module docstring), in the order it names them; `assets`
    maps references to files found elsewhere (the spec's `assets`). A file that is not there
    is listed all the same (MuJoCo says so when it loads the model); a `package://` that
    resolves nowhere is a `UserError`."""
    model = Path(model).resolve()
    root = _xml(model, "model")
    assets = dict(assets or {})
    if root.tag == "robot":
        return _urdf_files(model, root, tuple(package_paths), assets)
    return _mjcf_files(model, root, assets)


def loader_assets(
    model: Path, package_paths: tuple[Path, ...] = (), assets: dict[str, Path] | None = None
) -> dict[str, bytes] | None:
    """{reference: bytes} of the files MuJoCo does not find by itself (`package://` URIs, the
    spec's `assets`), for `MjSpec.from_file(assets=...)`; None when there are none."""
    needed = {}
    for f in model_files(model, package_paths, assets):
        if (f.packaged or f.reference in (assets or {})) and f.path.is_file():
            needed[f.reference] = f.path.read_bytes()
    return needed or None


def copy_plan(
    model: Path, files: list[ModelFile]
) -> tuple[PurePosixPath, list[tuple[Path, PurePosixPath]], dict[str, str]]:
    """Where a robot folder holds the model and its files so the copy loads as the original
    does: (the model's path in the folder, [(source, path in the folder)], the spec's
    `assets` for references by absolute path). Relative references keep their layout below
    the lowest folder holding the model and all of them; a package goes to `NAME/` at the
    folder's top (found there by the upward search); an absolute path goes to `assets/`."""
    model = Path(model).resolve()
    relative = [
        f for f in files if not f.packaged and not os.path.isabs(f.reference) and f.path.is_file()
    ]
    top = Path(os.path.commonpath([str(model.parent), *(str(f.path.parent) for f in relative)]))
    plan: list[tuple[Path, PurePosixPath]] = []
    extra: dict[str, str] = {}
    taken: set[PurePosixPath] = set()
    for f in files:
        if not f.path.is_file():
            continue
        if f.packaged:
            name, rest = f.packaged
            target = PurePosixPath(name, *PurePosixPath(rest).parts)
        elif os.path.isabs(f.reference):
            target = PurePosixPath("assets", f.path.name)
            k = 1
            while target in taken:
                target = PurePosixPath("assets", f"{k}-{f.path.name}")
                k += 1
            extra[f.reference] = str(target)
        else:
            target = PurePosixPath(*f.path.relative_to(top).parts)
        if target not in taken:
            taken.add(target)
            plan.append((f.path, target))
    return PurePosixPath(*model.relative_to(top).parts), plan, extra
