"""The robot spec file: what it says and the checks that need no model.

A spec is one YAML file beside the robot's own model file (docs/your-robot.md has the
format). Reading it checks every field's type and range and names the field on a mistake
(`UserError`); the checks that need the model (bodies and joints exist, a link has a child,
a foot ends a leg chain) happen when `model.SpecModel` loads it. The field readers and the
fields that fix the model (`joints`, `assets`, `balanceinertia`, `collision`) are in `fields`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from coadapt_plugins.robots.specs import SPEC_FILE
from coadapt_plugins.robots.specs.fields import (
    _assets,
    _collision,
    _fail,
    _flag,
    _joint_fixes,
    _list,
    _locked,
    _loops,
    _mapping,
    _number,
    _quaternion,
    _text,
    _tips,
    _unknown,
    _urdf_fixes,
    spec_error,
)

from coadapt_core.errors import UserError

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: designs closer than this are the same model (cache key rounding), as for every robot
DESIGN_DECIMALS = 6
#: what a parameter's `mass` rule may say (docs/your-robot.md#mass-rules)
MASS_RULES = ("stretch", "fixed")
NAME_PATTERN = re.compile(r"^[a-z][a-z0-9_\-]{0,63}$")


@dataclass(frozen=True)
class Parameter:
    """A continuous design parameter: the value divided by `nominal` scales every link."""

    name: str
    low: float
    high: float
    nominal: float
    links: tuple[tuple[str, str], ...]  # (parent body, child body): the child's position vector
    mass: str = "stretch"
    stretch_share: float = 1.0
    unit: str = ""


@dataclass(frozen=True)
class MotorParameter:
    """A discrete design parameter: the motor type of `joints`."""

    name: str
    joints: tuple[str, ...]  # joint names or full-match patterns
    nominal: int


@dataclass(frozen=True)
class MotorType:
    torque: float  # peak, N m
    speed: float  # no-load, rad/s
    mass: float = 0.0  # kg; the difference to the nominal type is added at the joint


@dataclass(frozen=True)
class LegSpec:
    name: str
    foot: str  # the foot body: the end of the leg chain, the point the IK places
    phase: float  # gait phase offset in [0, 1)
    hip: str | None = None  # the body whose origin feet are measured from (default: first)
    contact_points: tuple[tuple[float, float, float], ...] | None = None  # foot frame


@dataclass(frozen=True)
class RobotSpec:
    """A robot spec as read and checked (fields in docs/your-robot.md)."""

    name: str
    folder: Path
    model: str  # the model file's name, inside `folder`
    parameters: tuple[Parameter, ...]
    legs: tuple[LegSpec, ...]
    standing_pose: dict[str, float] | str  # joint values, or a keyframe's name
    gains: dict[str, dict[str, float]]  # pattern -> {"kp", "kd"}; "default" applies to all
    torque: dict[str, float] = field(default_factory=dict)  # pattern -> peak N m
    speed: dict[str, float] = field(default_factory=dict)  # pattern -> no-load rad/s
    motor_types: dict[int, MotorType] = field(default_factory=dict)
    motor_joints: dict[str, int] = field(default_factory=dict)  # pattern -> nominal type
    motor_parameters: tuple[MotorParameter, ...] = ()
    base: str | None = None
    locked_joints: tuple[str, ...] = ()
    locked_at: dict[str, float] = field(default_factory=dict)  # joint -> value it is welded at
    gain_scale_exponent: float = 0.0  # gains x (leg length / nominal) ** k
    description: str = ""
    collision: str = "stretch"  # collision meshes in scaled links: "stretch" or "fit"
    #: model fixes (the user's file stays as it is): pattern -> {"range": (lo, hi),
    #: "armature": kg m^2, "damping": N m s/rad}
    joints: dict[str, dict[str, Any]] = field(default_factory=dict)
    balanceinertia: bool = False  # MuJoCo's compiler option, for inertias it would refuse
    #: a body with a mass and a zero inertia gets that of the box bounding its collision
    #: geoms (`orient`)
    inertia_from_shape: bool = False
    #: [w, x, y, z] from the model's base frame to the robot's (x forward, z up), `orient`
    base_orientation: tuple[float, float, float, float] | None = None
    #: foot points the model has no body for: body -> [x, y, z] in its frame (`orient`)
    tips: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    #: each foot under its hip at this share of its leg's length, solved per design (None:
    #: the standing pose's joint angles at every design)
    standing_share: float | None = None
    #: files the model names by an absolute path -> their copy inside `folder`
    assets: dict[str, str] = field(default_factory=dict)
    #: URDF forms MuJoCo refuses, read as PyBullet reads them (`urdffix`)
    urdf_fixes: tuple[str, ...] = ()
    #: closed loops the model file leaves open (`loops`): (body A, body B, passive hinges)
    loops: tuple[tuple[str, str, tuple[str, ...]], ...] = ()
    #: points a loop pins that are no body's origin: body -> [x, y, z], a body BODY_pin
    pins: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    @property
    def model_path(self) -> Path:
        return self.folder / self.model

    @property
    def asset_paths(self) -> dict[str, Path]:
        """The `assets` map with each copy's full path."""
        return {ref: self.folder / rel for ref, rel in self.assets.items()}


def _parameter(raw: Any, path: str) -> Parameter:
    data = _mapping(raw, path)
    _unknown(data, {"name", "bounds", "nominal", "links", "mass", "stretch_share", "unit"}, path)
    name = _text(data.get("name"), f"{path}.name")
    bounds = _list(data.get("bounds"), f"{path}.bounds")
    if len(bounds) != 2:
        raise _fail(f"{path}.bounds", f"needs [low, high], got {bounds!r}")
    low, high = (_number(b, f"{path}.bounds") for b in bounds)
    if not 0 < low < high:
        raise _fail(
            f"{path}.bounds",
            f"needs 0 < low < high (a scale of zero or less makes a link vanish), got {bounds!r}",
        )
    nominal = _number(data.get("nominal", 1.0), f"{path}.nominal", positive=True)
    if not low <= nominal <= high:
        raise _fail(f"{path}.nominal", f"{nominal:g} is outside the bounds [{low:g}, {high:g}]")
    links = []
    for k, link in enumerate(_list(data.get("links"), f"{path}.links")):
        where = f"{path}.links[{k}]"
        if not (isinstance(link, list) and len(link) == 2):
            raise _fail(where, f"needs [parent body, child body], got {link!r}")
        links.append((_text(link[0], where), _text(link[1], where)))
    if not links:
        raise _fail(f"{path}.links", "needs at least one [parent body, child body]")
    mass = str(data.get("mass", "stretch"))
    if mass not in MASS_RULES:
        raise _fail(
            f"{path}.mass", f"'{mass}' is not a mass rule; accepted: {', '.join(MASS_RULES)}"
        )
    share = _number(data.get("stretch_share", 1.0), f"{path}.stretch_share")
    if not 0.0 <= share <= 1.0:
        raise _fail(f"{path}.stretch_share", f"needs a share in [0, 1], got {share:g}")
    unit = str(data.get("unit", ""))
    return Parameter(name, low, high, nominal, tuple(links), mass, share, unit)


def _leg(raw: Any, path: str) -> LegSpec:
    data = _mapping(raw, path)
    _unknown(data, {"name", "foot", "phase", "hip", "contact_points"}, path)
    phase = _number(data.get("phase", 0.0), f"{path}.phase")
    if not 0.0 <= phase < 1.0:
        raise _fail(f"{path}.phase", f"needs a gait phase offset in [0, 1), got {phase:g}")
    points = data.get("contact_points")
    contact = None
    if points is not None:
        rows = _list(points, f"{path}.contact_points")
        if not rows or not all(isinstance(r, list) and len(r) == 3 for r in rows):
            raise _fail(f"{path}.contact_points", "needs a list of [x, y, z] in the foot frame")
        contact = tuple(tuple(_number(x, f"{path}.contact_points") for x in r) for r in rows)
    hip = data.get("hip")
    return LegSpec(
        _text(data.get("name"), f"{path}.name"),
        _text(data.get("foot"), f"{path}.foot"),
        phase,
        None if hip is None else _text(hip, f"{path}.hip"),
        contact,
    )


def _pattern_values(raw: Any, path: str) -> dict[str, float]:
    data = _mapping(raw, path)
    out = {}
    for pattern, value in data.items():
        try:
            re.compile(str(pattern))
        except re.error as exc:
            raise _fail(f"{path}.{pattern}", f"not a regular expression ({exc})") from None
        out[str(pattern)] = _number(value, f"{path}.{pattern}", positive=True)
    return out


def _gains(raw: Any) -> dict[str, dict[str, float]]:
    data = _mapping(raw, "gains")
    out = {}
    for pattern, pair in data.items():
        where = f"gains.{pattern}"
        pair = _mapping(pair, where)
        _unknown(pair, {"kp", "kd"}, where)
        if "kp" not in pair or "kd" not in pair:
            raise _fail(where, "needs both kp (N m/rad) and kd (N m s/rad)")
        out[str(pattern)] = {
            "kp": _number(pair["kp"], f"{where}.kp", positive=True),
            "kd": _number(pair["kd"], f"{where}.kd", positive=True),
        }
    return out


def _motors(raw: Any) -> tuple[dict[int, MotorType], dict[str, int], tuple[MotorParameter, ...]]:
    data = _mapping(raw, "motors")
    _unknown(data, {"types", "joints", "parameters"}, "motors")
    types = {}
    for key, row in _mapping(data.get("types"), "motors.types").items():
        where = f"motors.types.{key}"
        if isinstance(key, bool) or not isinstance(key, int) or key < 1:
            raise _fail(where, "motor types are numbered 1, 2, ...")
        row = _mapping(row, where)
        _unknown(row, {"torque", "speed", "mass"}, where)
        types[key] = MotorType(
            _number(row.get("torque"), f"{where}.torque", positive=True),
            _number(row.get("speed"), f"{where}.speed", positive=True),
            _number(row.get("mass", 0.0), f"{where}.mass"),
        )
    joints = {}
    for pattern, kind in _mapping(data.get("joints", {}), "motors.joints").items():
        if kind not in types:
            raise _fail(f"motors.joints.{pattern}", f"type {kind!r} is not in motors.types")
        joints[str(pattern)] = int(kind)
    params = []
    for k, raw_p in enumerate(_list(data.get("parameters", []), "motors.parameters")):
        where = f"motors.parameters[{k}]"
        p = _mapping(raw_p, where)
        _unknown(p, {"name", "joints", "nominal"}, where)
        nominal = p.get("nominal")
        if nominal not in types:
            raise _fail(f"{where}.nominal", f"type {nominal!r} is not in motors.types")
        names = tuple(
            _text(j, f"{where}.joints") for j in _list(p.get("joints"), f"{where}.joints")
        )
        params.append(MotorParameter(_text(p.get("name"), f"{where}.name"), names, int(nominal)))
    return types, joints, tuple(params)


def _standing_share(raw: Any) -> float | None:
    """`standing_pose.solve`: each foot under its hip at this share of its leg's length,
    solved per design (None: the pose's joint angles at every design)."""
    data = _mapping(raw, "standing_pose")
    if "solve" not in data:
        return None
    share = _number(data["solve"], "standing_pose.solve")
    if not 0.0 < share < 1.0:
        raise _fail(
            "standing_pose.solve", f"needs a share of the leg's length in (0, 1), got {share:g}"
        )
    if "keyframe" in data:
        raise _fail("standing_pose.solve", "goes with joints (the nominal pose), not a keyframe")
    return share


def _standing(raw: Any) -> dict[str, float] | str:
    data = _mapping(raw, "standing_pose")
    _unknown(data, {"keyframe", "joints", "solve"}, "standing_pose")
    if "keyframe" in data:
        return _text(data["keyframe"], "standing_pose.keyframe")
    joints = _mapping(data.get("joints"), "standing_pose.joints")
    return {str(k): _number(v, f"standing_pose.joints.{k}") for k, v in joints.items()}


_TOP = {
    "name", "description", "model", "base", "locked_joints", "design", "motors", "limits",
    "legs", "standing_pose", "gains", "gain_scale_exponent", "collision", "joints",
    "balanceinertia", "assets", "inertia_from_shape", "base_orientation",
    "tips", "urdf_fixes", "loops", "pins",
}  # fmt: skip


def parse_spec(data: Any, folder: Path, *, fallback_name: str = "") -> RobotSpec:
    """A `RobotSpec` from the YAML file's data; `UserError` naming the first bad field."""
    data = _mapping(data, "(top level)")
    _unknown(data, _TOP, "")
    name = str(data.get("name", fallback_name))
    if not NAME_PATTERN.match(name):
        raise _fail("name", f"'{name}' is not a robot name (lower case, digits, _ and -)")
    if "standing_pose" not in data:
        raise _fail("standing_pose", "missing: give joints: {name: angle} or keyframe: NAME")
    legs = tuple(_leg(r, f"legs[{k}]") for k, r in enumerate(_list(data.get("legs"), "legs")))
    if not legs:
        raise _fail("legs", "needs at least one leg")
    params = tuple(
        _parameter(r, f"design[{k}]") for k, r in enumerate(_list(data.get("design"), "design"))
    )
    if not params:
        raise _fail("design", "needs at least one parameter")
    names = [p.name for p in params]
    limits = _mapping(data.get("limits", {}), "limits")
    _unknown(limits, {"torque", "speed"}, "limits")
    types, motor_joints, motor_params = (
        _motors(data["motors"]) if "motors" in data else ({}, {}, ())
    )
    names += [p.name for p in motor_params]
    if len(set(names)) != len(names):
        raise _fail("design", f"parameter names repeat: {names}")
    locked, locked_at = _locked(data.get("locked_joints", []))
    return RobotSpec(
        name=name,
        folder=folder,
        model=_text(data.get("model"), "model"),
        parameters=params,
        legs=legs,
        standing_pose=_standing(data["standing_pose"]),
        standing_share=_standing_share(data["standing_pose"]),
        gains=_gains(data.get("gains")),
        torque=_pattern_values(limits.get("torque", {}), "limits.torque"),
        speed=_pattern_values(limits.get("speed", {}), "limits.speed"),
        motor_types=types,
        motor_joints=motor_joints,
        motor_parameters=motor_params,
        base=None if data.get("base") is None else _text(data["base"], "base"),
        locked_joints=tuple(locked),
        locked_at=locked_at,
        gain_scale_exponent=_number(data.get("gain_scale_exponent", 0.0), "gain_scale_exponent"),
        description=str(data.get("description", "")),
        collision=_collision(data.get("collision", "stretch")),
        joints=_joint_fixes(data.get("joints", {})),
        balanceinertia=_flag(data.get("balanceinertia", False), "balanceinertia"),
        assets=_assets(data.get("assets", {})),
        inertia_from_shape=_flag(data.get("inertia_from_shape", False), "inertia_from_shape"),
        base_orientation=_quaternion(data.get("base_orientation")),
        tips=_tips(data.get("tips", {})),
        urdf_fixes=_urdf_fixes(data.get("urdf_fixes", [])),
        loops=_loops(data.get("loops", [])),
        pins=_tips(data.get("pins", {}), "pins"),
    )


def read_spec(path: str | Path) -> RobotSpec:
    """The spec in `path` (a robot.yaml, or a folder holding one); `UserError` on a missing
    file, bad YAML or a bad field."""
    import yaml

    path = Path(path)
    if path.is_dir():
        path = path / SPEC_FILE
    if not path.is_file():
        raise UserError(f"robot spec '{path}' does not exist", field="robot")
    # the safe loader (plain data only: no tag builds an object or runs code), parsed by libyaml
    # where PyYAML has it (15 x faster than the pure-Python parser)
    safe_loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        loader = safe_loader(path.read_text(encoding="utf-8"))
        try:
            data = loader.get_single_data()
        finally:
            loader.dispose()
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise UserError(
            f"robot spec '{path}' is not readable YAML: {first}", field="robot"
        ) from None
    return parse_spec(data, path.parent.resolve(), fallback_name=path.parent.name)


def match_value(patterns: dict[str, Any], joint: str) -> Any | None:
    """The value of the last pattern that matches `joint` whole (later entries refine
    earlier ones), or None."""
    found = None
    for pattern, value in patterns.items():
        if pattern != "default" and re.fullmatch(pattern, joint):
            found = value
    if found is None and "default" in patterns:
        found = patterns["default"]
    return found


def joint_values(patterns: dict[str, Any], joints: list[str], what: str) -> list[Any]:
    """Each joint's value from full-match patterns; `UserError` naming a joint none match."""
    out = []
    for joint in joints:
        value = match_value(patterns, joint)
        if value is None:
            raise spec_error(what, f"no entry matches joint '{joint}' (patterns match whole names)")
        out.append(value)
    return out


def readonly(values: Any) -> np.ndarray:
    import numpy as np

    a = np.array(values, dtype=float)
    a.setflags(write=False)
    return a
