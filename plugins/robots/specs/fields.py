"""A spec's field readers (`spec`): the one-line error naming a field, the checks of a
value's type, and the fields that fix the model where it lacks something, the model file left
as it is: `joints` (a range, armature or damping per joint pattern), `assets` (files the model
names by an absolute path, copied into the robot's folder), `balanceinertia`, `collision`
(how a collision mesh in a scaled link scales) and `urdf_fixes`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError

#: what `collision` may say: how a collision mesh in a scaled link scales (docs/your-robot.md)
COLLISION_RULES = ("stretch", "fit")


def spec_error(path: str, message: str) -> UserError:
    """The one-line error of a spec field."""
    return UserError(f"robot spec field '{path}': {message}", field=path)


_fail = spec_error


def _mapping(value: Any, path: str) -> dict:
    if not isinstance(value, dict):
        raise _fail(path, f"needs a mapping, got {type(value).__name__}")
    return value


def _list(value: Any, path: str) -> list:
    if not isinstance(value, list):
        raise _fail(path, f"needs a list, got {type(value).__name__}")
    return value


def _number(value: Any, path: str, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _fail(path, f"needs a finite number, got {value!r}")
    if positive and value <= 0:
        raise _fail(path, f"needs a positive number, got {value!r}")
    return float(value)


def _text(value: Any, path: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise _fail(path, f"needs a non-empty name, got {value!r}")
    return value.strip()


def _unknown(data: dict, allowed: set[str], path: str) -> None:
    extra = sorted(set(data) - allowed)
    if extra:
        where = f"{path}." if path else ""
        raise _fail(f"{where}{extra[0]}", f"unknown key; accepted: {', '.join(sorted(allowed))}")


def _joint_fixes(raw: Any) -> dict[str, dict[str, Any]]:
    data = _mapping(raw, "joints")
    out: dict[str, dict[str, Any]] = {}
    for pattern, row in data.items():
        where = f"joints.{pattern}"
        try:
            re.compile(str(pattern))
        except re.error as exc:
            raise _fail(where, f"not a regular expression ({exc})") from None
        row = _mapping(row, where)
        _unknown(row, {"range", "armature", "damping"}, where)
        fix: dict[str, Any] = {}
        if "range" in row:
            pair = _list(row["range"], f"{where}.range")
            if len(pair) != 2:
                raise _fail(f"{where}.range", f"needs [low, high] in rad, got {pair!r}")
            lo, hi = (_number(x, f"{where}.range") for x in pair)
            if not lo < hi:
                raise _fail(f"{where}.range", f"needs low < high, got {pair!r}")
            fix["range"] = (lo, hi)
        for key in ("armature", "damping"):
            if key in row:
                value = _number(row[key], f"{where}.{key}")
                if value < 0:
                    raise _fail(f"{where}.{key}", f"needs a number >= 0, got {value:g}")
                fix[key] = value
        out[str(pattern)] = fix
    return out


def _assets(raw: Any) -> dict[str, str]:
    out = {}
    for ref, target in _mapping(raw, "assets").items():
        where = f"assets.{ref}"
        path = Path(_text(target, where))
        if path.is_absolute() or ".." in path.parts:
            raise _fail(where, f"'{target}' must be a path inside the robot's folder")
        out[str(ref)] = path.as_posix()
    return out


def _flag(value: Any, path: str) -> bool:
    if not isinstance(value, bool):
        raise _fail(path, f"needs true or false, got {value!r}")
    return value


def _locked(raw: Any) -> tuple[list[str], dict[str, float]]:
    """(the joint names, {name: value} of those welded at a value): `locked_joints` is a list
    of joint names (each welded where the model draws it) or one-entry mappings
    `{NAME: VALUE}` (welded at that value: m for a slide, rad for a hinge)."""
    names, at = [], {}
    for k, entry in enumerate(_list(raw, "locked_joints")):
        where = f"locked_joints[{k}]"
        if isinstance(entry, dict):
            if len(entry) != 1:
                raise _fail(where, f"needs one NAME: VALUE, got {len(entry)} entries")
            ((name, value),) = entry.items()
            name = _text(name, where)
            at[name] = _number(value, f"{where}.{name}")
        else:
            name = _text(entry, where)
        names.append(name)
    return names, at


def _collision(value: Any) -> str:
    if value not in COLLISION_RULES:
        raise _fail("collision", f"{value!r} is not one of: {', '.join(COLLISION_RULES)}")
    return value


def _quaternion(value: Any) -> tuple[float, float, float, float] | None:
    """`base_orientation`: a unit quaternion [w, x, y, z] (normalised), or None."""
    if value is None:
        return None
    four = _list(value, "base_orientation")
    if len(four) != 4:
        raise _fail("base_orientation", f"needs a quaternion [w, x, y, z], got {four!r}")
    q = [_number(x, "base_orientation") for x in four]
    norm = math.sqrt(sum(x * x for x in q))
    if abs(norm - 1.0) > 1e-3:
        raise _fail("base_orientation", f"needs a unit quaternion, got one of norm {norm:.4g}")
    return tuple(x / norm for x in q)


def _tips(raw: Any, name: str = "tips") -> dict[str, tuple[float, float, float]]:
    """`tips`: {body: [x, y, z] in its frame}, the foot points the model has no body for
    (`pins` alike: the points a loop pins that are no body's origin)."""
    out = {}
    for body, point in _mapping(raw, name).items():
        where = f"{name}.{body}"
        three = _list(point, where)
        if len(three) != 3:
            raise _fail(where, f"needs a point [x, y, z] in the body's frame, got {three!r}")
        out[str(body)] = tuple(_number(x, where) for x in three)
    return out


def _urdf_fixes(raw: Any) -> tuple[str, ...]:
    """`urdf_fixes`: a list of the names in `urdffix.URDF_FIXES`."""
    from coadapt_plugins.robots.specs.urdffix import URDF_FIXES

    out = []
    for k, name in enumerate(_list(raw, "urdf_fixes")):
        if name not in URDF_FIXES:
            raise _fail(f"urdf_fixes[{k}]", f"{name!r} is not one of: {', '.join(URDF_FIXES)}")
        out.append(name)
    return tuple(out)


def _loops(raw: Any) -> tuple[tuple[str, str, tuple[str, ...]], ...]:
    """`loops`: [{bodies: [A, B], passive: [joint, ...]}, ...], each two bodies whose
    origins the robot holds together and the hinges on their chains no motor drives."""
    out = []
    for k, entry in enumerate(_list(raw, "loops")):
        where = f"loops[{k}]"
        data = _mapping(entry, where)
        _unknown(data, {"bodies", "passive"}, where)
        bodies = _list(data.get("bodies"), f"{where}.bodies")
        if len(bodies) != 2:
            raise _fail(f"{where}.bodies", f"needs two bodies [A, B], got {bodies!r}")
        a, b = (_text(x, f"{where}.bodies") for x in bodies)
        if a == b:
            raise _fail(f"{where}.bodies", f"needs two different bodies, got '{a}' twice")
        passive = tuple(
            _text(j, f"{where}.passive") for j in _list(data.get("passive", []), f"{where}.passive")
        )
        out.append((a, b, passive))
    return tuple(out)
