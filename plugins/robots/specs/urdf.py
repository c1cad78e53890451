"""A compiled spec model written as URDF, for the simulators and tools that read URDF
(PyBullet, Pinocchio): the same bodies, frames, masses, inertias and primitive geoms.

URDF puts a joint's frame at its child link's origin and allows one joint per link, so a
body with several joints, a joint off its body's origin or a collision mesh has no URDF;
`urdf_text` then says why in one line and the robot writes MJCF alone.
"""

from __future__ import annotations

import mujoco
import numpy as np


def _f(x: float) -> str:
    return repr(float(x))


def _v(values) -> str:
    return " ".join(_f(x) for x in values)


def _rpy(quat) -> np.ndarray:
    """URDF roll-pitch-yaw (fixed axes x, y, z) of a MuJoCo quaternion (w, x, y, z)."""
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(quat, dtype=float))
    r = m.reshape(3, 3)
    pitch = np.arcsin(-np.clip(r[2, 0], -1.0, 1.0))
    if abs(r[2, 0]) < 1 - 1e-12:
        roll, yaw = np.arctan2(r[2, 1], r[2, 2]), np.arctan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: put the whole turn in yaw
        roll, yaw = 0.0, np.arctan2(-r[0, 1], r[1, 1])
    return np.array([roll, pitch, yaw])


def _geometry(model: mujoco.MjModel, g: int) -> str | None:
    size, kind = model.geom_size[g], mujoco.mjtGeom(int(model.geom_type[g]))
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return f'<sphere radius="{_f(size[0])}"/>'
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return f'<capsule radius="{_f(size[0])}" length="{_f(2 * size[1])}"/>'
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return f'<cylinder radius="{_f(size[0])}" length="{_f(2 * size[1])}"/>'
    if kind in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        return f'<box size="{_v(2 * size)}"/>'
    return None


def _link(model: mujoco.MjModel, b: int) -> tuple[str | None, str]:
    name = model.body(b).name
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, model.body_iquat[b])
    rot = m.reshape(3, 3)
    tensor = rot @ np.diag(model.body_inertia[b]) @ rot.T
    parts = [
        f'  <link name="{name}"><inertial><origin xyz="{_v(model.body_ipos[b])}" rpy="0 0 0"/>'
        f'<mass value="{_f(model.body_mass[b])}"/><inertia ixx="{_f(tensor[0, 0])}" '
        f'ixy="{_f(tensor[0, 1])}" ixz="{_f(tensor[0, 2])}" iyy="{_f(tensor[1, 1])}" '
        f'iyz="{_f(tensor[1, 2])}" izz="{_f(tensor[2, 2])}"/></inertial>'
    ]
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != b:
            continue
        shape = _geometry(model, g)
        collides = bool(model.geom_contype[g] or model.geom_conaffinity[g])
        if shape is None:
            if collides:
                return f"body '{name}' has a collision geom URDF cannot describe (a mesh?)", ""
            continue
        origin = f'<origin xyz="{_v(model.geom_pos[g])}" rpy="{_v(_rpy(model.geom_quat[g]))}"/>'
        body = f"{origin}<geometry>{shape}</geometry>"
        parts.append(f"<visual>{body}</visual>")
        if collides:
            parts.append(f"<collision>{body}</collision>")
    return None, "".join(parts) + "</link>"


def urdf_text(
    model: mujoco.MjModel, name: str, joints: list[str], torque: np.ndarray, speed: np.ndarray
) -> tuple[str | None, str]:
    """(URDF text, "") of the robot in `model` (its first body below the world is the
    floating base), or (None, why not)."""
    limit = dict(zip(joints, zip(torque, speed, strict=True), strict=True))
    out = ['<?xml version="1.0"?>', f'<robot name="{name}">']
    for b in range(1, model.nbody):
        why, link = _link(model, b)
        if why:
            return None, why
        out.append(link)
        parent = int(model.body_parentid[b])
        if parent == 0:
            continue
        hinges = [j for j in range(model.njnt) if model.jnt_bodyid[j] == b]
        if len(hinges) > 1:
            return None, f"body '{model.body(b).name}' has {len(hinges)} joints (URDF: one a link)"
        origin = (
            f'<origin xyz="{_v(model.body_pos[b])}" rpy="{_v(_rpy(model.body_quat[b]))}"/>'
            f'<parent link="{model.body(parent).name}"/><child link="{model.body(b).name}"/>'
        )
        if not hinges:
            out.append(f'  <joint name="{model.body(b).name}_fixed" type="fixed">{origin}</joint>')
            continue
        j = hinges[0]
        if np.linalg.norm(model.jnt_pos[j]) > 1e-12:
            return None, f"joint '{model.joint(j).name}' is off its body's origin"
        jname = model.joint(j).name
        effort, velocity = limit[jname]
        lo, hi = model.jnt_range[j]
        damping = model.dof_damping[model.jnt_dofadr[j]]
        out.append(
            f'  <joint name="{jname}" type="revolute">{origin}<axis xyz="{_v(model.jnt_axis[j])}"/>'
            f'<limit lower="{_f(lo)}" upper="{_f(hi)}" effort="{_f(effort)}" '
            f'velocity="{_f(velocity)}"/><dynamics damping="{_f(damping)}" friction="0"/></joint>'
        )
    return "\n".join([*out, "</robot>", ""]), ""
