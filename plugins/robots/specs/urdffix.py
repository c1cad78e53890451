"""URDF forms MuJoCo's reader refuses and PyBullet reads, read as PyBullet reads them (spec
`urdf_fixes`; the model file stays as it is, the fix is made in memory when it loads):

- `first_axis`: a joint with more than one `<axis>` keeps its first (PyBullet's importer
  takes the first; MuJoCo refuses the file: "repeated element: 'axis'");
- `rpy_three`: an `rpy` of more than three numbers keeps its first three (PyBullet reads
  those; MuJoCo refuses "attribute 'rpy' has too much data").

`needed` says which a file needs and where; `fixed_xml` is the file's text with them made,
each mesh named by its full path (the text has no folder of its own to resolve them from).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

#: what `urdf_fixes` may say (module docstring)
URDF_FIXES = ("first_axis", "rpy_three")


def _root(path: Path) -> ET.Element:
    from coadapt_plugins.robots.specs.files import _xml

    return _xml(Path(path), "model")


def _where(root: ET.Element) -> dict[str, list[str]]:
    """{fix: the joints or links it changes} over a URDF's tree (empty for an MJCF)."""
    out: dict[str, list[str]] = {}
    if root.tag != "robot":
        return out
    for element in [*root.iter("joint"), *root.iter("link")]:
        name = element.get("name", "?")
        if element.tag == "joint" and len(element.findall("axis")) > 1:
            out.setdefault("first_axis", []).append(name)
        long = [e for e in element.iter("origin") if len(e.get("rpy", "").split()) > 3]
        if long and name not in out.get("rpy_three", []):
            out.setdefault("rpy_three", []).append(name)
    return out


def needed(path: Path) -> dict[str, list[str]]:
    """{fix: the joints or links of the model at `path` it changes}, the fixes in the order
    of `URDF_FIXES`."""
    found = _where(_root(path))
    return {fix: found[fix] for fix in URDF_FIXES if fix in found}


def fixed_xml(
    path: Path,
    fixes: tuple[str, ...],
    package_paths: tuple = (),
    assets: dict[str, Path] | None = None,
) -> str:
    """The URDF at `path` with `fixes` made and every mesh it names by its full path."""
    from coadapt_plugins.robots.specs.files import model_files

    root = _root(path)
    if "first_axis" in fixes:
        for joint in root.iter("joint"):
            for extra in joint.findall("axis")[1:]:
                joint.remove(extra)
    if "rpy_three" in fixes:
        for origin in root.iter("origin"):
            numbers = origin.get("rpy", "").split()
            if len(numbers) > 3:
                origin.set("rpy", " ".join(numbers[:3]))
    found = {
        f.reference: f.path
        for f in model_files(Path(path), package_paths, assets)
        if f.path.is_file()
    }
    for mesh in root.iter("mesh"):
        if mesh.get("filename") in found:
            mesh.set("filename", str(found[mesh.get("filename")]))
    return ET.tostring(root, encoding="unicode")
