"""A starting spec written from a model file (`coadapt robot new NAME --from FILE`).

From the model alone: the floating base (the body with the free joint, else the root body),
the legs (leaf bodies below the base whose chain has at least two hinges), paired left and
right by the sign of their foot's y and ordered front to back, the gait (biped alternating,
quadruped trotting, hexapod tripod, else evenly spread), a parameter per leg segment kind
(the two longest links nearest each foot: upper and lower leg), torque limits from the
model's actuators, gains from those limits, the standing pose from a keyframe. What it had to
guess is listed for the user to check.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import mujoco
import numpy as np
import yaml
from coadapt_plugins.robots.specs.model import load_mjspec
from coadapt_plugins.robots.specs.spec import NAME_PATTERN, SPEC_FILE

from coadapt_core.errors import UserError

#: the no-load speed written for every joint when the model cannot tell it, rad/s
GUESSED_SPEED = 20.0
#: a link counts as a leg segment when at least this share of its chain's longest link
SEGMENT_SHARE = 0.25
#: the stiffness written per N m of a joint's peak torque (the peak at 1 rad of error), and
#: the damping-to-stiffness ratio (legged_gym's A1 and Unitree's G1 settings: 0.02-0.025)
KP_PER_TORQUE = 1.0
KD_RATIO = 0.025


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
            notes.append(
                f"joint '{name}': no actuator limit in the model; peak torque set to 50 N m"
            )
    return found


def starting_spec(name: str, model_file: Path) -> tuple[dict, list[str]]:
    """(spec data, lines for the user to check) for the model in `model_file`."""
    if not NAME_PATTERN.match(name):
        raise UserError(f"robot name '{name}': use lower case, digits, _ and -", field="name")
    spec = load_mjspec(model_file)
    model = spec.compile()
    data = mujoco.MjData(model)
    notes: list[str] = []
    if model.nkey:
        key = next((k for k in range(model.nkey) if model.key(k).name in ("home", "stand")), 0)
        data.qpos[:] = model.key_qpos[key]
        pose: dict = {"keyframe": model.key(key).name}
        if not model.key(key).name:
            pose, notes = {"joints": {}}, [*notes, "the first keyframe has no name: pose left at 0"]
    else:
        data.qpos[:] = model.qpos0
        pose = {"joints": _inside_ranges(model, data, notes)}
        notes.append("no keyframe: the standing pose is every joint at 0 or its nearest limit")
    mujoco.mj_kinematics(model, data)
    base = _base(model)
    legs = _legs(model, data, base)
    torques = _torques(model, notes)
    notes.append(f"no-load joint speeds are not in the model: {GUESSED_SPEED:g} rad/s written")
    params = _segments(model, legs)
    collision = _collision_rule(model, params, notes)
    data_out = {
        "name": name,
        "description": f"{name}: written by coadapt robot new from {model_file.name}; check it",
        "model": model_file.name,
        "base": model.body(base).name,
        "design": params,
        "limits": {
            "torque": {re.escape(j): round(t, 6) for j, t in torques.items()},
            "speed": {".*": GUESSED_SPEED},
        },
        "legs": [
            {
                "name": f"leg{k}" if len(legs) > 2 else ("left", "right")[k],
                "foot": model.body(g["foot"]).name,
                "phase": phase,
            }
            for k, (g, phase) in enumerate(zip(legs, _gait(len(legs)), strict=True))
        ],
        "standing_pose": pose,
        "gains": {
            re.escape(j): {"kp": round(KP_PER_TORQUE * t, 6), "kd": round(KD_RATIO * t, 6)}
            for j, t in torques.items()
        },
    }
    if collision:
        data_out["collision"] = collision
    notes.append("gains are the peak torque per rad (kd 0.025 x kp); check that each design stands")
    return data_out, notes


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


def _body_geoms(model: mujoco.MjModel, body: int) -> list[int]:
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]


def write_robot(name: str, model_file: Path, into: Path) -> tuple[Path, list[str]]:
    """Write `<into>/<name>/robot.yaml` beside a copy of `model_file` (and the mesh files it
    names); refuses an existing folder. Returns (the folder, the lines to check)."""
    from coadapt_plugins.robots.specs.robot import spec_robot_class

    model_file = Path(model_file)
    if not model_file.is_file():
        raise UserError(f"--from '{model_file}' is not a file", field="from")
    folder = into / name
    if folder.exists():
        raise UserError(f"'{folder}' exists already; pick another name or --into", field="name")
    data, notes = starting_spec(name, model_file)
    meshes = [Path(m.file) for m in load_mjspec(model_file).meshes if m.file]
    folder.mkdir(parents=True)
    try:
        shutil.copy2(model_file, folder / model_file.name)
        for mesh in meshes:
            source = model_file.parent / mesh
            if source.is_file():
                (folder / mesh).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, folder / mesh)
        text = yaml.safe_dump(data, sort_keys=False, width=100, default_flow_style=None)
        (folder / SPEC_FILE).write_text(
            "# written by `coadapt robot new`; check every line (docs/your-robot.md)\n" + text,
            encoding="utf-8",
        )
        robot = spec_robot_class(folder)()
        robot.build(_nominal(data))  # it must build
        notes += [f"fitted: {line}" for line in robot._built.prepared.fits]
    except Exception:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return folder, notes


def _nominal(data: dict) -> np.ndarray:
    return np.array([p["nominal"] for p in data["design"]], dtype=float)
