"""A starting spec written from a model file (`coadapt robot new NAME --from FILE`).

From the model alone: the floating base (the body with the free joint, else the root body),
the legs (leaf bodies below the base whose chain has at least two hinges), paired left and
right by the sign of their foot's y and ordered front to back, the gait (biped alternating,
quadruped trotting, hexapod tripod, else evenly spread), a parameter per leg segment kind
(the two longest links nearest each foot: upper and lower leg), torque limits from the
model's actuators, gains from those limits, the standing pose from a keyframe or else solved
by the generic leg IK (each foot under its hip at STAND_SHARE of the leg's length, solved
again at each design: `standing_pose.solve`), joints several legs share locked and the
slides between the base and the legs (`locks`), the legs named by their bodies' names. What
the model lacks is assumed in the spec, never in the model file: a range for a joint
without one, armature and damping where it has none, `balanceinertia` where MuJoCo refuses
an inertia; each such line carries a comment, and the gains are raised until the nominal
design and every corner pass the stand test (`validation`). What it had to guess is listed
for the user to check.

`legs` finds and names the legs, `assumed` writes what the model lacks and the spec's text,
`stand` solves the standing pose and raises the gains; this module puts them together.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import mujoco
from coadapt_plugins.robots.specs.assumed import (
    _collision_rule,
    _few,
    _fixes,
    _speed_table,
    _torques,
    spec_text,
)
from coadapt_plugins.robots.specs.files import is_urdf
from coadapt_plugins.robots.specs.fourbar import (
    four_bar_legs,
    four_bars,
    loop_entries,
    loop_tip,
    pair_names,
    write_loops,
)
from coadapt_plugins.robots.specs.legs import (
    _actuated,
    _base,
    _gait,
    _leg_names,
    _legs,
    _segments,
    _shared_joints,
)
from coadapt_plugins.robots.specs.locks import lock_slides
from coadapt_plugins.robots.specs.loops import PIN_SUFFIX, add_pins
from coadapt_plugins.robots.specs.model import load_mjspec
from coadapt_plugins.robots.specs.orient import add_tips, find_tips, reorient, up_rotation
from coadapt_plugins.robots.specs.spec import NAME_PATTERN, SPEC_FILE
from coadapt_plugins.robots.specs.stand import (
    GAIN_FACTORS,
    KD_RATIO,
    KP_PER_TORQUE,
    _inside_ranges,
    _nominal,
    _pose_entry,
    _set_gains,
    stand_by_gains,
)

from coadapt_core.errors import UserError

#: why each of `urdffix.URDF_FIXES` is made (the note and the spec line's comment)
_URDF_WHY = {
    "first_axis": "a joint has several <axis> (MuJoCo refuses it); its first kept, as PyBullet "
    "reads it",
    "rpy_three": "an rpy of more than three numbers (MuJoCo refuses it); its first three kept, "
    "as PyBullet reads it",
}


def _load(model_file: Path, package_paths: tuple, notes: list[str]) -> tuple:
    """(the model as MuJoCo reads it from where it lives, the loading fixes it needed): URDF
    forms MuJoCo refuses are read as PyBullet reads them (`urdffix`), an
    inertia MuJoCo refuses (A + B >= C) is balanced by its own compiler option, a body of
    mass and zero inertia gets its collision shape's box's (`orient`); each written to the
    spec and said."""
    from coadapt_plugins.robots.specs.urdffix import needed

    fixes = needed(model_file)
    flags = {"balanceinertia": False, "shape_inertia": False, "urdf_fixes": tuple(fixes)}
    for fix, where in fixes.items():
        notes.append(f"urdf_fixes: {fix} ({_few(where)}): {_URDF_WHY[fix]}")
    shaped: list[str] = []
    while True:
        try:
            spec = load_mjspec(model_file, package_paths=package_paths, shaped=shaped, **flags)
            break
        except UserError as exc:
            text = str(exc)
            why = text.split("does not load in MuJoCo: ", 1)[-1]
            if "balanceinertia" in text and not flags["balanceinertia"]:
                flags["balanceinertia"] = True
                notes.append(f"balanceinertia: true (MuJoCo refused an inertia: {why})")
            elif "mass and inertia of moving bodies" in text and not flags["shape_inertia"]:
                flags["shape_inertia"] = True
            else:
                raise
    if shaped:
        notes.append(
            f"bodies with a mass and zero inertia ({_few(shaped)}): inertia_from_shape: true "
            "(each gets the inertia of a box of its mass bounding its collision geoms, as "
            "Bullet approximates a mesh's)"
        )
    return spec, flags, shaped


def _upright(spec: mujoco.MjSpec, notes: list[str], comments: dict[str, str]) -> list | None:
    """The base turned upright when the model is not z-up (`orient.up_rotation`): the
    quaternion written to `base_orientation`, else None."""
    model = spec.compile()
    data = mujoco.MjData(model)
    base = _base(model)
    data.qpos[:] = model.qpos0
    _inside_ranges(model, data, [])
    mujoco.mj_kinematics(model, data)
    quat = up_rotation(model, data, base)
    if quat is None:
        return None
    reorient(spec.body(model.body(base).name), quat)
    quat = [round(float(x), 6) + 0.0 for x in quat]
    comments["base_orientation"] = (
        "assumed: the model's feet do not hang along its base's -z; this turns the base so "
        "that x points forward (the legs named front) and z up"
    )
    notes.append(f"the model is not z-up: base_orientation {quat} (w, x, y, z) written")
    return quat


def _model_legs(
    spec: mujoco.MjSpec, notes: list[str], comments: dict[str, str], band: bool = True,
    skip: frozenset = frozenset(),
) -> tuple:  # fmt: skip
    """(the model compiled, its data posed at its first "home" or "stand" keyframe (else its
    first) or at 0 inside the joint ranges, the base, that keyframe, the legs, the joints on
    several legs' chains); without a keyframe those joints are locked (deleted from `spec`
    with their actuators) and the legs found again; `band` and `skip` as `legs._legs` takes
    them."""
    model = spec.compile()
    data = mujoco.MjData(model)
    base = _base(model)
    key = 0
    if model.nkey:
        key = next((k for k in range(model.nkey) if model.key(k).name in ("home", "stand")), 0)
        data.qpos[:] = model.key_qpos[key]
    else:
        data.qpos[:] = model.qpos0
        _inside_ranges(model, data, [])
    mujoco.mj_kinematics(model, data)
    legs = _legs(model, data, base, band, skip)
    shared = _shared_joints(model, legs)
    if shared and not model.nkey:  # lock them: each leg needs a chain of its own
        for actuator in [a for a in spec.actuators if a.target in shared]:
            spec.delete(actuator)
        for joint in shared:
            spec.delete(spec.joint(joint))
        model = spec.compile()
        data = mujoco.MjData(model)
        data.qpos[:] = model.qpos0
        _inside_ranges(model, data, [])
        mujoco.mj_kinematics(model, data)
        legs = _legs(model, data, base, band, skip)
        why = (
            "assumed: joints on the chains of several legs (the gait's leg IK needs each leg's "
            "own chain)"
        )
        if why not in comments.get("locked_joints", ""):  # after the slides' (`locks`)
            comments["locked_joints"] = "; ".join(
                filter(None, [comments.get("locked_joints"), why])
            )
        notes.append(
            f"joints on the chains of several legs, locked: {', '.join(shared)} (locked_joints)"
        )
    return model, data, base, key, legs, shared


def _has_four_bars(spec: mujoco.MjSpec) -> bool:
    """Whether the model's legs at its zero pose hold four-bar halves (`fourbar`): its zero
    pose then says nothing about up (the minitaurs' legs point up there), so the file's z is
    taken as up, as PyBullet loads it; coaxial halves whose ends do not meet are refused."""
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    _inside_ranges(model, data, [])
    mujoco.mj_kinematics(model, data)
    base = _base(model)
    try:
        legs = _legs(model, data, base, band=False)
    except UserError:
        return False
    return bool(_shared_joints(model, legs) == [] and four_bars(model, data, base, legs))


def _loading_fixes(
    data_out: dict,
    flags: dict,
    shaped: list[str],
    turn: list | None,
    tips: dict,
    notes: list[str],
    comments: dict[str, str],
) -> None:
    """The spec lines (each with its comment) of what loading and placing the feet needed."""
    if flags["balanceinertia"]:
        data_out["balanceinertia"] = True
        comments["balanceinertia"] = "assumed: MuJoCo refuses an inertia of the model (A + B < C)"
    if flags["urdf_fixes"]:
        data_out["urdf_fixes"] = list(flags["urdf_fixes"])
        comments["urdf_fixes"] = "assumed: " + "; ".join(
            _URDF_WHY[fix] for fix in flags["urdf_fixes"]
        )
    if flags["shape_inertia"]:
        data_out["inertia_from_shape"] = True
        comments["inertia_from_shape"] = (
            f"assumed: {_few(shaped)} have a mass but zero inertia in the model (MuJoCo refuses "
            "it); each gets that of a box of its mass bounding its collision geoms"
        )
    if turn is not None:
        data_out["base_orientation"] = turn
    if tips and "loops" in data_out:
        data_out["tips"] = tips
        comments["tips"] = (
            "assumed: each four-bar half's end, where the pin goes: on the line through its "
            "collision geoms' centre, at their far end less the tip sphere's radius"
        )
    elif tips:
        data_out["tips"] = tips
        comments["tips"] = (
            "assumed: these legs' last bodies turn about their own origins (a knee, not a "
            "foot); a foot body BODY_tip at the point of their collision geoms farthest from it"
        )
        notes.append(
            f"legs ending in a knee ({_few(list(tips))}): a foot point at each one's tip "
            "written under tips:"
        )


def _feet(spec: mujoco.MjSpec, bars: bool, notes: list[str], comments: dict) -> tuple:
    """`_model_legs`'s values, the four-bar pairs (`fourbar`) and the `tips` written: a foot
    at each four-bar half's end (where the pin goes), else at the tip of each leg ending in a
    knee (`orient.find_tips`); the legs found again with them."""
    model, data, base, key, legs, shared = _model_legs(spec, notes, comments, not bars)
    pairs = four_bars(model, data, base, legs) if bars else []
    tips, pins = find_tips(model, legs), {}
    if pairs:
        ends = {model.body(g["foot"]).name: loop_tip(model, g["foot"]) for g in legs}
        tips = {b: [round(float(x), 6) + 0.0 for x in t] for b, t in ends.items() if t is not None}
        pins = {
            model.body(legs[a]["foot"]).name: [round(float(x), 6) + 0.0 for x in pin]
            for a, _, pin in pairs
            if pin is not None
        }
    if tips:
        add_tips(spec, tips)
        add_pins(spec, pins)
        skip = frozenset(body + PIN_SUFFIX for body in pins)
        model, data, base, key, legs, again = _model_legs(spec, notes, comments, not bars, skip)
        shared = shared or again
        pinned = {body: body + PIN_SUFFIX for body in pins}
        pairs = four_bars(model, data, base, legs, pinned) if bars else []
    return model, data, base, key, legs, shared, pairs, tips, pins


def _params(model, legs: list[dict], pairs: list, pinned: dict) -> list[dict]:
    """The design parameters (`legs._segments`; a four-bar's: its halves' last two links),
    a `pins` body listed with the link it is on (a pin on a scaled lower leg moves with it)."""
    params = _segments(model, legs, 0.0) if pairs else _segments(model, legs)
    for p in params:
        p["links"] += [[parent, pinned[parent]] for parent, _ in p["links"] if parent in pinned]
    return params


def _ranges(model, joints: list[str], fixes: dict) -> dict[str, tuple]:
    """{joint: (low, high)}: the range a fix writes, else the model's."""
    return {
        j: tuple(fixes[j][0]["range"]) if j in fixes and "range" in fixes[j][0]
        else tuple(float(x) for x in model.jnt_range[model.joint(j).id])
        for j in joints
    }  # fmt: skip


def starting_spec(
    name: str, model_file: Path, package_paths: tuple = ()
) -> tuple[dict, list[str], dict[str, str]]:
    """(spec data, lines for the user to check, a comment per top-level key saying what was
    assumed there) for the model in `model_file`."""
    if not NAME_PATTERN.match(name):
        raise UserError(f"robot name '{name}': use lower case, digits, _ and -", field="name")
    notes: list[str] = []
    comments: dict[str, str] = {}
    spec, flags, shaped = _load(model_file, tuple(package_paths), notes)
    slides = lock_slides(spec, notes, comments)
    bars = _has_four_bars(spec)
    turn = None if bars else _upright(spec, notes, comments)
    model, data, base, key, legs, shared, pairs, tips, pins = _feet(spec, bars, notes, comments)
    pinned = {body: body + PIN_SUFFIX for body in pins}
    torques = _torques(model, notes)
    loops, passive = loop_entries(model, legs, pairs, pinned)
    joints = [j for j in _actuated(model, base) if j not in passive]
    fixes = _fixes(model, joints, torques, notes)
    params = _params(model, legs, pairs, pinned)
    if pairs:
        halves = legs
        pose, hips, legs = four_bar_legs(model, legs, pairs, pinned, params, notes, comments)
    else:
        ranges = _ranges(model, joints, fixes)
        pose, hips = _pose_entry(
            model, data, key, base, joints, legs, params, ranges, notes, comments
        )
    speed_table = _speed_table(model_file, joints, notes, comments)
    collision = _collision_rule(model, params, notes)
    names = _leg_names(model, legs)
    if pairs:  # the tokens both halves' names share (front_left_L, front_left_R: front_left)
        names = pair_names(names, _leg_names(model, [halves[b] for _, b, _ in pairs]))
    mass = float(model.body_subtreemass[base])
    kind = "URDF" if is_urdf(model_file) else "MJCF"
    what = spec.modelname or model_file.stem
    data_out: dict = {
        "name": name,
        "description": (
            f"{what}: {len(legs)} legs ({', '.join(names)}), {len(joints)} hinge joints, "
            + (f"{len(passive)} passive ones closing four-bar legs, " if passive else "")
            + f"{mass:.3g} kg, from {model_file.name} ({kind}); spec written by coadapt robot new"
        ),
        "model": model_file.name,
        "base": model.body(base).name,
        "design": params,
        "limits": {
            "torque": {re.escape(j): round(torques[j], 6) for j in joints},
            "speed": speed_table,
        },
        "legs": [
            {"name": leg_name, "foot": model.body(g["foot"]).name, "phase": phase}
            | ({"hip": hips[k]} if hips else {})
            for k, (leg_name, g, phase) in enumerate(
                zip(names, legs, _gait(len(legs)), strict=True)
            )
        ],
        "standing_pose": pose,
        "gains": {
            re.escape(j): {
                "kp": round(KP_PER_TORQUE * torques[j], 6),
                "kd": round(KD_RATIO * torques[j], 6),
            }
            for j in joints
        },
    }
    if slides or (shared and not model.nkey):
        data_out["locked_joints"] = slides + (shared if not model.nkey else [])
    write_loops(data_out, loops, pins, comments)
    if collision:
        data_out["collision"] = collision
    _loading_fixes(data_out, flags, shaped, turn, tips, notes, comments)
    if fixes:
        data_out["joints"] = {j: fix for j, (fix, _) in fixes.items()}
        comments["joints"] = "model fixes robot new assumed; the model file is unchanged"
        comments.update({f"joints.{j}": why for j, (_, why) in fixes.items()})
    comments.setdefault(
        "gains", f"kp {KP_PER_TORQUE:g} N m/rad per N m of peak torque, kd {KD_RATIO:g} x kp"
    )
    return data_out, notes, comments


def write_robot(
    name: str, model_file: Path, into: Path, package_paths: tuple = ()
) -> tuple[Path, list[str], list[str]]:
    """Write `<into>/<name>/robot.yaml` beside a copy of `model_file` and of every file it
    needs (`files`), raise the gains until the nominal design stands (`validation`'s stand
    test); refuses an existing folder. Returns (the folder, the lines to check, the files
    copied, as paths inside the folder)."""
    from coadapt_plugins.robots.specs.files import copy_plan, model_files
    from coadapt_plugins.robots.specs.robot import spec_robot_class

    model_file = Path(model_file)
    if not model_file.is_file():
        raise UserError(f"--from '{model_file}' is not a file", field="from")
    folder = into / name
    if folder.exists():
        raise UserError(f"'{folder}' exists already; pick another name or --into", field="name")
    data, notes, comments = starting_spec(name, model_file, package_paths)
    files = model_files(model_file, tuple(package_paths))
    where, plan, absolute = copy_plan(model_file, files)
    data["model"] = str(where)
    if absolute:
        data["assets"] = absolute
        comments["assets"] = "files the model names by an absolute path, copied beside it"
    folder.mkdir(parents=True)
    try:
        (folder / where).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(model_file, folder / where)
        for source, target in plan:
            (folder / target).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, folder / target)
        factor, stand, nominal_ok, at_nominal_ok = stand_by_gains(folder, data, comments, notes)
        biped = len(data["legs"]) < 3
        if not stand.ok and not biped:
            raise UserError(
                f"the stand test fails with gains up to {GAIN_FACTORS[-1]:g} x the peak "
                f"torque per rad: {stand.text()}; give a standing pose (a keyframe) or "
                "stronger motors",
                field="gains",
            )
        if not stand.ok:  # a biped: its policy balances it; PD alone need not
            factor = nominal_ok if nominal_ok is not None else 1.0
            stand = at_nominal_ok or stand  # the corner that falls at the gains written
            what = (
                "the nominal design stands 3 s under joint PD, a corner does not"
                if nominal_ok is not None
                else "no gain makes it stand under joint PD alone"
            )
            notes.append(
                f"gains {factor * KP_PER_TORQUE:g} N m/rad per N m of peak torque: {what} "
                f"({stand.text()}); a biped is balanced by its policy"
            )
        elif factor != 1.0:
            notes.append(
                f"gains raised to {factor * KP_PER_TORQUE:g} N m/rad per N m of peak torque: the "
                "nominal design and every corner stand 3 s under joint PD"
            )
        else:
            notes.append(
                f"gains {KP_PER_TORQUE:g} N m/rad per N m of peak torque (kd {KD_RATIO:g} x kp): "
                "the nominal design and every corner stand 3 s under joint PD"
            )
        _set_gains(data, factor)
        if factor != 1.0:
            comments["gains"] = (
                f"kp {factor * KP_PER_TORQUE:g} N m/rad per N m of peak torque (raised by robot "
                f"new until the robot stands under joint PD), kd {KD_RATIO:g} x kp"
            )
        (folder / SPEC_FILE).write_text(spec_text(data, comments), encoding="utf-8")
        robot = spec_robot_class(folder)()
        robot.build(_nominal(data))  # it must build
        notes += [f"fitted: {line}" for line in robot._built.prepared.fits]
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return folder, notes, [str(where), *(str(t) for _, t in plan)]
