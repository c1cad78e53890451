"""What `robot new` assumes where the model is silent, and the spec text that says so
(`new`): peak torques from the model's actuators (else 50 N m), no-load speeds from a URDF's
limits (else GUESSED_SPEED), a range, armature and damping for a joint without one,
`collision: fit` for collision meshes in scaled links; each assumption is a line for the user
to check and a comment in the written spec (`spec_text`).
"""

from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np
import yaml

#: the no-load speed written for every joint when the model cannot tell it, rad/s
GUESSED_SPEED = 20.0
#: where the model gives none: a joint's range (rad, either way), its rotor armature
#: (kg m^2) and its damping (N m s/rad) per N m of peak torque
ASSUMED_RANGE = 3.141593
ARMATURE_PER_TORQUE = 2e-4
DAMPING_PER_TORQUE = 2e-3


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


def _collision_rule(model: mujoco.MjModel, params: list[dict], notes: list[str]) -> str | None:
    """ "fit" when a scaled body holds a collision mesh, else None: one off its link cannot
    stretch, and one MuJoCo batch shares mesh assets across designs, so each becomes a
    fitted primitive (`collision: fit`)."""
    from coadapt_plugins.robots.specs.meshes import off_link_degrees

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


def _speed_table(
    model_file: Path, joints: list[str], notes: list[str], comments: dict[str, str]
) -> dict[str, float]:
    """The spec's `limits.speed`: the URDF's joint speeds, GUESSED_SPEED for the others."""
    speeds = _urdf_speeds(model_file)
    speed_table: dict[str, float] = {}
    if any(j not in speeds for j in joints):
        speed_table[".*"] = GUESSED_SPEED
        notes.append(
            f"no-load joint speeds the model does not give: {GUESSED_SPEED:g} rad/s written"
        )
        comments["limits"] = f"speed '.*': {GUESSED_SPEED:g} rad/s assumed (not in the model)"
    speed_table.update({re.escape(j): speeds[j] for j in joints if j in speeds})
    return speed_table
