"""A starting spec written from a model file (`coadapt robot new NAME --from FILE`).

From the model alone: the floating base (the body with the free joint, else the root body),
the legs (leaf bodies below the base whose chain has at least two hinges), paired left and
right by the sign of their foot's y and ordered front to back, the gait (biped alternating,
quadruped trotting, hexapod tripod, else evenly spread), a parameter per leg segment kind
(the two longest links nearest each foot: upper and lower leg), torque limits from the
model's actuators, gains from those limits, the standing pose from a keyframe or else solved
by the generic leg IK (each foot under its hip at STAND_SHARE of the leg's length, solved
again at each design: `standing_pose.solve`), joints several legs share locked, the legs
named by their bodies' names. What the model lacks is assumed in the spec, never in the
model file: a range for a joint without one, armature and damping where it has none,
`balanceinertia` where MuJoCo refuses an inertia; each such line carries a comment, and the
gains are raised until the nominal design and every corner pass the stand test
(`validation`). What it had to guess is listed for the user to check.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import mujoco
import numpy as np
import yaml
from coadapt_plugins.robots.specs.files import is_urdf
from coadapt_plugins.robots.specs.model import load_mjspec
from coadapt_plugins.robots.specs.spec import NAME_PATTERN, SPEC_FILE

from coadapt_core.errors import UserError

#: the no-load speed written for every joint when the model cannot tell it, rad/s
GUESSED_SPEED = 20.0
#: a leaf body is a foot when it lies this share of the base's height above the lowest leaf
#: at most (a humanoid's hands are not)
FOOT_BAND = 0.25
#: a link counts as a leg segment when at least this share of its chain's longest link
SEGMENT_SHARE = 0.25
#: the stiffness written per N m of a joint's peak torque (the peak at 1 rad of error), and
#: the damping-to-stiffness ratio (legged_gym's A1 and Unitree's G1 settings: 0.02-0.025)
KP_PER_TORQUE = 1.0
KD_RATIO = 0.025
#: the factors `robot new` tries on those gains, in turn, until the nominal design stands
GAIN_FACTORS = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
#: where the model gives none: a joint's range (rad, either way), its rotor armature
#: (kg m^2) and its damping (N m s/rad) per N m of peak torque
ASSUMED_RANGE = 3.141593
ARMATURE_PER_TORQUE = 2e-4
DAMPING_PER_TORQUE = 2e-3
#: a solved standing pose puts each foot under its hip at this share of the leg's length;
#: the IK starts with each leg's last hinge bent either way by BEND rad too
STAND_SHARE = 0.75
BEND = 0.6


def _base(model: mujoco.MjModel) -> int:
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            return int(model.jnt_bodyid[j])
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if len(roots) != 1:
        raise UserError(f"the model has {len(roots)} root bodies and no free joint", field="model")
    return roots[0]


def _chain(model: mujoco.MjModel, base: int, leaf: int) -> list[int]:
    path, b = [], leaf
    while b != base and b != 0:
        path.append(b)
        b = int(model.body_parentid[b])
    return list(reversed(path)) if b == base else []


def _hinges(model: mujoco.MjModel, bodies: list[int]) -> int:
    return sum(
        1
        for j in range(model.njnt)
        if model.jnt_bodyid[j] in bodies and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    )


def _common_kind(names: list[str]) -> str:
    """What the legs' body names share once their side or leg tokens are dropped: the longest
    common run of trailing tokens ("FL_thigh", "RR_thigh" -> "thigh"; "ml_femur_link",
    "fr_femur_link" -> "femur"), else of leading ones, else ""."""
    split = [[t for t in re.split(r"[_\-.]+", n.lower()) if t] for n in names]
    for tokens in split:
        while tokens and tokens[-1] in ("link", "body"):
            tokens.pop()
    tail = []
    for group in zip(*(reversed(t) for t in split), strict=False):
        if len(set(group)) != 1:
            break
        tail.insert(0, group[0])
    if not tail:
        for group in zip(*split, strict=False):
            if len(set(group)) != 1:
                break
            tail.append(group[0])
    kind = "_".join(tail)
    return re.sub(r"[^a-z0-9_]+", "_", kind).strip("_")


def _gait(count: int) -> list[float]:
    if count == 2:
        return [0.0, 0.5]
    if count == 4:  # trot: the diagonal pairs together (legs ordered front left, front right, ...)
        return [0.0, 0.5, 0.5, 0.0]
    if count == 6:  # tripod: front and hind of one side with the middle of the other
        return [0.0, 0.5, 0.5, 0.0, 0.0, 0.5]
    return [round(k / count, 6) for k in range(count)]


def _legs(model, data, base: int) -> list[dict]:
    leaves = [
        b
        for b in range(1, model.nbody)
        if not any(model.body_parentid[c] == b for c in range(1, model.nbody))
    ]
    legs = []
    for leaf in leaves:
        chain = _chain(model, base, leaf)
        if len(chain) >= 2 and _hinges(model, chain) >= 2:
            legs.append({"foot": leaf, "chain": chain, "pos": data.xpos[leaf].copy()})
    if not legs:
        raise UserError(
            "found no legs: no leaf body below the base ends a chain of two or more hinges",
            field="model",
        )
    # feet near the ground: a leaf well above the lowest foot is an arm or a tail
    lowest = min(float(g["pos"][2]) for g in legs)
    reach = max(float(data.xpos[base][2]) - lowest, 1e-9)
    legs = [g for g in legs if float(g["pos"][2]) <= lowest + FOOT_BAND * reach]
    # front to back (x rounded to a centimetre), then left (y > 0) before right
    legs.sort(key=lambda g: (-round(float(g["pos"][0]), 2), -float(g["pos"][1])))
    return legs


def _segments(model, legs: list[dict]) -> list[dict]:
    """Up to two parameters (upper, lower leg) from the longest links nearest the feet."""
    per_leg = []
    for leg in legs:
        links = [(model.body_parentid[b], b) for b in leg["chain"][1:]]
        lengths = [float(np.linalg.norm(model.body_pos[c])) for _, c in links]
        longest = max(lengths, default=0.0)
        kept = [
            link
            for link, length in zip(links, lengths, strict=True)
            if length >= SEGMENT_SHARE * longest
        ]
        per_leg.append(kept[-2:])
    count = min(len(k) for k in per_leg)
    params = []
    for k in range(count):
        links = [kept[len(kept) - count + k] for kept in per_leg]
        kind = _common_kind([model.body(int(p)).name for p, _ in links])
        name = (kind or ("upper_leg", "lower_leg")[k % 2]) + "_scale"
        length = float(np.linalg.norm(model.body_pos[links[0][1]]))
        params.append(
            {
                "name": name,
                "bounds": [0.7, 1.3],
                "nominal": 1.0,
                "unit": f"x {length:.3g} m",
                "links": [[model.body(int(p)).name, model.body(int(c)).name] for p, c in links],
                "mass": "stretch",
                "stretch_share": 1.0,
            }
        )
    return params


def _torques(model: mujoco.MjModel, notes: list[str]) -> dict[str, float]:
    found: dict[str, float] = {}
    guessed: list[str] = []
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        joint = model.joint(int(model.actuator_trnid[a, 0])).name
        gear = abs(float(model.actuator_gear[a, 0]))
        if model.actuator_forcelimited[a]:
            found[joint] = float(np.abs(model.actuator_forcerange[a]).max())
        elif model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED and model.actuator_biastype[
            a
        ] == int(mujoco.mjtBias.mjBIAS_NONE):
            found[joint] = float(np.abs(model.actuator_ctrlrange[a]).max()) * gear
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        name = model.joint(j).name
        if name not in found and model.jnt_actfrclimited[j]:
            found[name] = float(np.abs(model.jnt_actfrcrange[j]).max())
        if name not in found or found[name] <= 0:
            found[name] = 50.0
            guessed.append(name)
    if guessed:
        notes.append(
            f"joints without an actuator limit in the model ({_few(guessed)}): peak torque set "
            "to 50 N m"
        )
    return found


def _load(model_file: Path, package_paths: tuple, notes: list[str]) -> tuple[mujoco.MjSpec, bool]:
    """The model as MuJoCo reads it from where it lives; an inertia MuJoCo refuses (A + B >=
    C) is balanced by its own compiler option, written to the spec and said."""
    try:
        return load_mjspec(model_file, package_paths=package_paths), False
    except UserError as exc:
        if "balanceinertia" not in str(exc):
            raise
        spec = load_mjspec(model_file, package_paths=package_paths, balanceinertia=True)
        why = str(exc).split("does not load in MuJoCo: ", 1)[-1]
        notes.append(f"balanceinertia: true (MuJoCo refused an inertia: {why})")
        return spec, True


def _shared_joints(model: mujoco.MjModel, legs: list[dict]) -> list[str]:
    """The hinge joints on the chains of two legs or more (a humanoid's abdomen), in model
    order."""
    count: dict[int, int] = {}
    for g in legs:
        for j in range(model.njnt):
            if (
                model.jnt_bodyid[j] in g["chain"]
                and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
            ):
                count[j] = count.get(j, 0) + 1
    return [model.joint(j).name for j in sorted(count) if count[j] > 1]


def _actuated(model: mujoco.MjModel, base: int) -> list[str]:
    """The hinge joints of the base's subtree, in model order (as `model.prepare` lists them)."""
    out = []
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        b = int(model.jnt_bodyid[j])
        while b not in (base, 0):
            b = int(model.body_parentid[b])
        if b == base:
            out.append(model.joint(j).name)
    return out


def _urdf_speeds(model_file: Path) -> dict[str, float]:
    """Each URDF joint's `<limit velocity>` (rad/s) where it gives one above 0."""
    import xml.etree.ElementTree as ET

    root = ET.parse(model_file).getroot()
    if root.tag != "robot":
        return {}
    out = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        try:
            speed = float(limit.get("velocity", "0")) if limit is not None else 0.0
        except ValueError:
            continue
        if speed > 0 and joint.get("name"):
            out[joint.get("name")] = speed
    return out


def _fixes(
    model: mujoco.MjModel, joints: list[str], torques: dict[str, float], notes: list[str]
) -> dict[str, tuple[dict, str]]:
    """{joint: (its fixes, why)}: a range where the model gives none, armature and damping
    where it has none (scaled by the joint's peak torque)."""
    out: dict[str, tuple[dict, str]] = {}
    assumed: dict[str, list[str]] = {"range": [], "armature": [], "damping": []}
    for name in joints:
        j = model.joint(name).id
        dof = model.jnt_dofadr[j]
        fix, why = {}, []
        if not model.jnt_limited[j]:
            fix["range"] = [-ASSUMED_RANGE, ASSUMED_RANGE]
            why.append("no range in the model")
            assumed["range"].append(name)
        if model.dof_armature[dof] <= 0:
            fix["armature"] = round(ARMATURE_PER_TORQUE * torques[name], 6)
            why.append("no armature")
            assumed["armature"].append(name)
        if model.dof_damping[dof] <= 0:
            fix["damping"] = round(DAMPING_PER_TORQUE * torques[name], 6)
            why.append("no damping")
            assumed["damping"].append(name)
        if fix:
            out[name] = (fix, "assumed: " + ", ".join(why))
    if assumed["range"]:
        notes.append(
            f"joints without a range ({_few(assumed['range'])}): range [-{ASSUMED_RANGE:g}, "
            f"{ASSUMED_RANGE:g}] rad written under joints:"
        )
    if assumed["armature"] or assumed["damping"]:
        notes.append(
            f"joints without armature or damping ({_few(assumed['armature'] + assumed['damping'])})"
            ":"
            f" armature {ARMATURE_PER_TORQUE:g} kg m^2 and damping {DAMPING_PER_TORQUE:g} N m s/rad"
            " per N m of peak torque written under joints:"
        )
    return out


def _few(names: list[str]) -> str:
    unique = list(dict.fromkeys(names))
    return ", ".join(unique[:3]) + (f" and {len(unique) - 3} more" if len(unique) > 3 else "")


_SIDE_TOKENS = re.compile(
    r"^(fl|fr|rl|rr|hl|hr|lf|rf|lh|rh|ml|mr|l|r|left|right|front|back|rear|hind|fore|middle|mid"
    r"|[0-9]+)$"
)


def _tokens(name: str) -> list[str]:
    spaced = re.sub(r"([a-z0-9])([A-Z])|([A-Za-z])([0-9])", r"\1\3_\2\4", name)
    return [t for t in re.split(r"[_\-.\s]+", spaced) if t]


def _leg_names(model: mujoco.MjModel, legs: list[dict]) -> list[str]:
    """Each leg's name from its bodies' names: the tokens that tell its foot's name from the
    other feet's (FL_toe -> FL, left_foot -> left, front_left_foot -> front_left), else from
    the next body up its chain; by position when no body tells them apart."""
    for depth in range(max(len(g["chain"]) for g in legs)):
        names = [model.body(g["chain"][max(len(g["chain"]) - 1 - depth, 0)]).name for g in legs]
        split = [_tokens(n) for n in names]
        common = set.intersection(*(set(t.lower() for t in ts) for ts in split))
        found = []
        for ts in split:
            own = [t for t in ts if t.lower() not in common]
            sides = [t for t in own if _SIDE_TOKENS.match(t.lower())]
            found.append("_".join(sides or own))
        if all(found) and len(set(f.lower() for f in found)) == len(found):
            if not all(f.isdigit() for f in found):  # numbers say less than positions
                return found
            break
    if len(legs) == 2:
        return ["left", "right"]
    if len(legs) == 4:
        return ["FL", "FR", "RL", "RR"]
    return [f"leg{k}" for k in range(len(legs))]


def _leg_length(model: mujoco.MjModel, leg: dict, params: list[dict]) -> float:
    """The leg's length: its design links' lengths summed (its chain's below the hip when
    it has none)."""
    names = {model.body(b).name for b in leg["chain"]}
    links = [c for p in params for parent, c in p["links"] if parent in names and c in names]
    bodies = [model.body(c).id for c in links] or leg["chain"][1:]
    return float(sum(np.linalg.norm(model.body_pos[b]) for b in bodies))


def _solve_standing(
    model: mujoco.MjModel,
    base: int,
    joints: list[str],
    legs: list[dict],
    params: list[dict],
    guess: np.ndarray,
    ranges: dict[str, tuple[float, float]],
    quadruped_like: bool,
) -> tuple[np.ndarray, list[str]]:
    """A standing pose with each foot under its hip at STAND_SHARE of its leg's length, by
    the generic leg IK from three starts (the guess, and its last hinge per leg bent either
    way); per leg the start whose answer is inside the joint ranges and nearest its target,
    a quadruped's knee behind its hip-foot line and a biped's in front on a tie. Returns the
    pose and the legs (by index) it could not place, which keep the guess."""
    import torch
    from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain

    links = [set(map(tuple, p["links"])) for p in params]
    nominal = np.ones(len(params))
    feet = [(model.body(g["foot"]).name, None) for g in legs]
    starts = []
    for bend in (0.0, BEND, -BEND):
        start = guess.copy()
        for g in legs:
            hinges = [
                joints.index(model.joint(j).name)
                for j in range(model.njnt)
                if model.jnt_bodyid[j] in g["chain"] and model.joint(j).name in joints
            ]
            if hinges and bend:
                k = hinges[-1]
                lo, hi = ranges[joints[k]]
                start[k] = float(np.clip(start[k] + bend, lo, hi))
        starts.append(start)
    designs = torch.tensor(nominal[None, :])
    try:
        first = LegKinematics(
            build_chain(model, model.body(base).name, joints, feet, links, starts[0], nominal)
        )
    except ValueError:  # legs that share a joint (a humanoid's abdomen): no leg IK for them
        return guess.copy(), list(range(len(legs)))
    rel, _, _ = first.standing(designs)
    targets = torch.zeros_like(rel)
    for k, g in enumerate(legs):
        targets[0, k, 1] = rel[0, k, 1]
        targets[0, k, 2] = -STAND_SHARE * _leg_length(model, g, params)
    best: list[tuple[float, np.ndarray] | None] = [None] * len(legs)
    pose = guess.copy()
    lo = np.array([ranges[j][0] for j in joints])
    hi = np.array([ranges[j][1] for j in joints])
    for start in starts:
        kin = LegKinematics(
            build_chain(model, model.body(base).name, joints, feet, links, start, nominal)
        )
        q = kin.inverse(designs, targets)[0].numpy()
        chain = kin.chain
        x = kin.leg_angles(torch.tensor(q[None, :]))
        foot, _, hip, _, anchors = kin.forward(kin.scales(designs), x)
        for k, g in enumerate(legs):
            slots = chain.joint_index[k][chain.joint_index[k] >= 0].numpy()
            inside = bool(np.all((q[slots] >= lo[slots] - 1e-9) & (q[slots] <= hi[slots] + 1e-9)))
            error = float(torch.linalg.norm(foot[0, k] - hip[0, k] - targets[0, k]))
            length = _leg_length(model, g, params)
            if not inside or error > 0.02 * length:
                continue
            last = int(torch.nonzero(chain.slot[k] >= 0)[-1])
            knee_x = float(anchors[0, k, last, 0] - 0.5 * (foot[0, k, 0] + hip[0, k, 0]))
            behind = knee_x < 0 if quadruped_like else knee_x > 0
            score = error + (0.0 if behind else 0.01 * length)
            if best[k] is None or score < best[k][0]:
                best[k] = (score, q[slots].copy(), slots)
    missed = []
    for k, found in enumerate(best):
        if found is None:
            missed.append(k)
            continue
        pose[found[2]] = found[1]
    return pose, missed


def starting_spec(
    name: str, model_file: Path, package_paths: tuple = ()
) -> tuple[dict, list[str], dict[str, str]]:
    """(spec data, lines for the user to check, a comment per top-level key saying what was
    assumed there) for the model in `model_file`."""
    if not NAME_PATTERN.match(name):
        raise UserError(f"robot name '{name}': use lower case, digits, _ and -", field="name")
    notes: list[str] = []
    comments: dict[str, str] = {}
    spec, balance = _load(model_file, tuple(package_paths), notes)
    model = spec.compile()
    data = mujoco.MjData(model)
    base = _base(model)
    if model.nkey:
        key = next((k for k in range(model.nkey) if model.key(k).name in ("home", "stand")), 0)
        data.qpos[:] = model.key_qpos[key]
    else:
        data.qpos[:] = model.qpos0
        _inside_ranges(model, data, [])
    mujoco.mj_kinematics(model, data)
    legs = _legs(model, data, base)
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
        legs = _legs(model, data, base)
        comments["locked_joints"] = (
            "assumed: joints on the chains of several legs (the gait's leg IK needs each leg's "
            "own chain)"
        )
        notes.append(
            f"joints on the chains of several legs, locked: {', '.join(shared)} (locked_joints)"
        )
    torques = _torques(model, notes)
    joints = _actuated(model, base)
    fixes = _fixes(model, joints, torques, notes)
    params = _segments(model, legs)
    ranges = {
        j: tuple(fixes[j][0]["range"]) if j in fixes and "range" in fixes[j][0]
        else tuple(float(x) for x in model.jnt_range[model.joint(j).id])
        for j in joints
    }  # fmt: skip
    if model.nkey and model.key(key).name:
        pose: dict = {"keyframe": model.key(key).name}
    else:
        if model.nkey:
            notes.append("the first keyframe has no name: it is not used")
        guess = np.array([data.qpos[model.jnt_qposadr[model.joint(j).id]] for j in joints])
        guess = np.clip(guess, [ranges[j][0] for j in joints], [ranges[j][1] for j in joints])
        solved, missed = _solve_standing(
            model, base, joints, legs, params, guess, ranges, len(legs) >= 4
        )
        pose = {
            "joints": {
                j: round(float(v), 6) for j, v in zip(joints, solved, strict=True) if abs(v) > 1e-12
            }
        }
        if not missed:  # every foot placed: solved again at each design from this pose
            pose["solve"] = STAND_SHARE
        placed = len(legs) - len(missed)
        comments["standing_pose"] = (
            f"solved by robot new: feet {STAND_SHARE:g} of the leg's length under their hips "
            "(generic leg IK)"
            + ("; solve: solved so at every design" if not missed else "")
            + (f"; {len(missed)} legs out of reach keep 0 or their nearest limit" if missed else "")
        )
        notes.append(
            f"no keyframe: standing pose solved with {placed} of {len(legs)} feet "
            f"{STAND_SHARE:g} of the leg's length under their hips"
            + ("" if not missed else "; the others at 0 or their nearest limit")
        )
    speeds = _urdf_speeds(model_file)
    speed_table: dict[str, float] = {}
    if any(j not in speeds for j in joints):
        speed_table[".*"] = GUESSED_SPEED
        notes.append(
            f"no-load joint speeds the model does not give: {GUESSED_SPEED:g} rad/s written"
        )
        comments["limits"] = f"speed '.*': {GUESSED_SPEED:g} rad/s assumed (not in the model)"
    speed_table.update({re.escape(j): speeds[j] for j in joints if j in speeds})
    collision = _collision_rule(model, params, notes)
    names = _leg_names(model, legs)
    mass = float(model.body_subtreemass[base])
    kind = "URDF" if is_urdf(model_file) else "MJCF"
    what = spec.modelname or model_file.stem
    data_out: dict = {
        "name": name,
        "description": (
            f"{what}: {len(legs)} legs ({', '.join(names)}), {len(joints)} hinge joints, "
            f"{mass:.3g} kg, from {model_file.name} ({kind}); spec written by coadapt robot new"
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
            for leg_name, g, phase in zip(names, legs, _gait(len(legs)), strict=True)
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
    if shared and not model.nkey:
        data_out["locked_joints"] = shared
    if collision:
        data_out["collision"] = collision
    if balance:
        data_out["balanceinertia"] = True
        comments["balanceinertia"] = "assumed: MuJoCo refuses an inertia of the model (A + B < C)"
    if fixes:
        data_out["joints"] = {j: fix for j, (fix, _) in fixes.items()}
        comments["joints"] = "model fixes robot new assumed; the model file is unchanged"
        comments.update({f"joints.{j}": why for j, (_, why) in fixes.items()})
    comments.setdefault(
        "gains", f"kp {KP_PER_TORQUE:g} N m/rad per N m of peak torque, kd {KD_RATIO:g} x kp"
    )
    return data_out, notes, comments


def _collision_rule(model: mujoco.MjModel, params: list[dict], notes: list[str]) -> str | None:
    """ "fit" when a scaled body holds a collision mesh, else None: one off its link cannot
    stretch, and one MuJoCo batch shares mesh assets across designs, so each becomes a
    fitted primitive (`collision: fit`)."""
    from coadapt_plugins.robots.specs.model import off_link_degrees

    found = []
    for p in params:
        for parent, child in p["links"]:
            body, kid = model.body(parent).id, model.body(child).id
            u = model.body_pos[kid] / np.linalg.norm(model.body_pos[kid])
            for g in _body_geoms(model, body):
                if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
                    continue
                if model.geom_contype[g] or model.geom_conaffinity[g]:
                    name = f"'{model.geom(g).name}'" if model.geom(g).name else f"of '{parent}'"
                    found.append(f"{name} ({off_link_degrees(model, g, u):.0f} deg off its link)")
    if not found:
        return None
    notes.append(
        f"collision meshes in scaled links, {', '.join(found)}: `collision: fit` written "
        "(each becomes the primitive fitted to it; a MuJoCo batch shares mesh shapes)"
    )
    return "fit"


def _inside_ranges(model: mujoco.MjModel, data: mujoco.MjData, notes: list[str]) -> dict:
    """Joint angles for a pose: 0, or the nearest limit of a joint whose range excludes 0."""
    pose = {}
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or not model.jnt_limited[j]:
            continue
        lo, hi = (float(x) for x in model.jnt_range[j])
        if not lo <= 0.0 <= hi:
            angle = lo if abs(lo) < abs(hi) else hi
            pose[model.joint(j).name] = angle
            data.qpos[model.jnt_qposadr[j]] = angle
            notes.append(f"joint '{model.joint(j).name}': 0 is outside its range; {angle:g} rad")
    return pose


def _body_geoms(model: mujoco.MjModel, body: int) -> list[int]:
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]


def spec_text(data: dict, comments: dict[str, str]) -> str:
    """The spec as YAML with a comment above each key (or after each joint fix) saying
    what `robot new` assumed there."""
    import json

    out = ["# written by `coadapt robot new`; check every line (docs/your-robot.md)"]
    plain = {k: v for k, v in data.items() if k != "joints"}
    text = yaml.safe_dump(plain, sort_keys=False, width=100, default_flow_style=None)
    for line in text.splitlines():
        key = line.split(":", 1)[0] if line[:1].isalpha() else None
        if key in comments:
            out.append(f"# {key}: {comments[key]}")
        out.append(line)
    if "joints" in data:
        out.append(f"# joints: {comments['joints']}" if "joints" in comments else "")
        out.append("joints:")
        for joint, fix in data["joints"].items():
            flow = yaml.safe_dump(fix, default_flow_style=True, width=10_000).strip()
            line = f"  {json.dumps(re.escape(joint))}: {flow}"
            why = comments.get(f"joints.{joint}")
            out.append(f"{line}  # {why}" if why else line)
    return "\n".join(line for line in out if line) + "\n"


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
        factor, stand, nominal_ok = _raise_gains(folder, data, comments)
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


def _set_gains(data: dict, factor: float) -> None:
    for row, peak in zip(data["gains"].values(), data["limits"]["torque"].values(), strict=True):
        row["kp"] = round(factor * KP_PER_TORQUE * peak, 6)
        row["kd"] = round(factor * KD_RATIO * KP_PER_TORQUE * peak, 6)


def _raise_gains(folder: Path, data: dict, comments: dict):
    """(the first factor of GAIN_FACTORS at which the nominal design and every corner pass
    the stand test, else the last; the stand test that decided; the first factor at which
    the nominal design alone passed, or None)."""
    from coadapt_plugins.robots.specs.robot import spec_robot_class
    from coadapt_plugins.robots.specs.validation import corners, stand_test

    nominal_ok = None
    for factor in GAIN_FACTORS:
        _set_gains(data, factor)
        (folder / SPEC_FILE).write_text(spec_text(data, comments), encoding="utf-8")
        robot = spec_robot_class(folder)()
        stand = stand_test(robot.build(_nominal(data)))  # it must build
        if stand.ok:
            nominal_ok = factor if nominal_ok is None else nominal_ok
            stand = next(
                (t for t in (stand_test(robot.build(c)) for c in corners(robot)) if not t.ok),
                stand,
            )
        if stand.ok:
            return factor, stand, nominal_ok
    return factor, stand, nominal_ok


def _nominal(data: dict) -> np.ndarray:
    return np.array([p["nominal"] for p in data["design"]], dtype=float)
