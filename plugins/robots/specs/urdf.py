"""A compiled spec model written as URDF, for the simulators and tools that read URDF
(PyBullet, Pinocchio): the same bodies, frames, masses, inertias and primitive geoms.

URDF puts a joint's frame at its child link's origin and allows one joint per link. A body
whose hinges are several, or off its origin, becomes a chain: one intermediate link per hinge,
placed at that hinge's anchor (MuJoCo applies a body's hinges in order, each about its anchor
in the frame the previous ones turned), then the body's own link, fixed to the last
intermediate link at minus the last anchor where that is not the body's origin. Every body's
link frame is then its MuJoCo body frame, and a hinge's URDF angle is its MuJoCo angle (a
hinge's `ref` turns its joint origin). Intermediate links carry a tiny mass and inertia
(`TINY_MASS`, `TINY_INERTIA`; Bullet integrates a zero-mass moving link badly), named
`<body>__<joint>`; `intermediate_links` lists them.

A mesh is written as a file the URDF names, `coadapt_<hash>.obj` (its compiled vertices and
faces, the hash of its text: a stretched design's mesh is another file), which the robot
model carries beside the URDF as format `urdf:<file>` (`mesh_files`); a reader writes those
files beside the URDF (PyBullet's engine, `coadapt robot export -o`). A visual mesh (a geom
that does not collide) is a `<visual>` only, stretched as the MJCF's is, in its MuJoCo
colour, so PyBullet's GUI shows the robot as MuJoCo does.
"""

from __future__ import annotations

import hashlib
import re

import mujoco
import numpy as np

#: an intermediate link's mass (kg) and principal moments (kg m^2): a millionth of a small
#: robot's link, far below anything the dynamics notice, far above Bullet's zero
TINY_MASS = 1e-6
TINY_INERTIA = 1e-9
#: what separates the body and the joint in an intermediate link's name
SEPARATOR = "__"


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


def _obj(model: mujoco.MjModel, mesh: int) -> str:
    """The compiled mesh `mesh` as Wavefront OBJ text (its own frame)."""
    v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
    lines = [f"v {_v(v)}" for v in model.mesh_vert[v0 : v0 + nv]]
    lines += [f"f {' '.join(str(int(i) + 1) for i in f)}" for f in model.mesh_face[f0 : f0 + nf]]
    return "\n".join(lines) + "\n"


def _geometry(model: mujoco.MjModel, g: int, files: dict[str, str]) -> str | None:
    size, kind = model.geom_size[g], mujoco.mjtGeom(int(model.geom_type[g]))
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        text = _obj(model, int(model.geom_dataid[g]))
        name = f"coadapt_{hashlib.sha1(text.encode()).hexdigest()[:16]}.obj"
        files[name] = text
        return f'<mesh filename="{name}"/>'
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return f'<sphere radius="{_f(size[0])}"/>'
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return f'<capsule radius="{_f(size[0])}" length="{_f(2 * size[1])}"/>'
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return f'<cylinder radius="{_f(size[0])}" length="{_f(2 * size[1])}"/>'
    if kind in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        return f'<box size="{_v(2 * size)}"/>'
    return None


def _colour(model: mujoco.MjModel, g: int) -> str:
    """A mesh's colour as MuJoCo draws it (its material's, else its own), as a URDF
    material named by its value."""
    mat = int(model.geom_matid[g])
    rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
    name = "coadapt_" + "_".join(f"{x:.3f}" for x in rgba)
    return f'<material name="{name}"><color rgba="{_v(rgba)}"/></material>'


def _link(model: mujoco.MjModel, b: int, files: dict[str, str]) -> tuple[str | None, str]:
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
        shape = _geometry(model, g, files)
        collides = bool(model.geom_contype[g] or model.geom_conaffinity[g])
        if shape is None:
            if collides:
                why = f"body '{name}' has a collision geom URDF cannot describe (a plane?)"
                return why, ""
            continue
        origin = f'<origin xyz="{_v(model.geom_pos[g])}" rpy="{_v(_rpy(model.geom_quat[g]))}"/>'
        body = f"{origin}<geometry>{shape}</geometry>"
        colour = _colour(model, g) if shape.startswith("<mesh") else ""
        parts.append(f"<visual>{body}{colour}</visual>")
        if collides:
            parts.append(f"<collision>{body}</collision>")
    return None, "".join(parts) + "</link>"


def _tiny_link(name: str) -> str:
    i = _f(TINY_INERTIA)
    return (
        f'  <link name="{name}"><inertial><origin xyz="0 0 0" rpy="0 0 0"/>'
        f'<mass value="{_f(TINY_MASS)}"/><inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" '
        f'iyz="0" izz="{i}"/></inertial></link>'
    )


def intermediate_links(urdf: str) -> list[str]:
    """The names of the intermediate links `urdf_text` wrote into `urdf`."""
    pattern = re.escape(_tiny_link("@")).replace("@", f'([^"]*{SEPARATOR}[^"]*)')
    return re.findall(pattern, urdf)


def _joints(model: mujoco.MjModel, b: int, limit: dict) -> list[str]:
    """The joint elements, and intermediate links, that hang body b below its parent."""
    name, parent = model.body(b).name, model.body(int(model.body_parentid[b])).name
    hinges = [j for j in range(model.njnt) if model.jnt_bodyid[j] == b]
    body_origin = (
        np.array(model.body_pos[b], dtype=float), _rpy(model.body_quat[b])
    )  # fmt: skip
    if not hinges:
        return [
            f'  <joint name="{name}_fixed" type="fixed">'
            f'<origin xyz="{_v(body_origin[0])}" rpy="{_v(body_origin[1])}"/>'
            f'<parent link="{parent}"/><child link="{name}"/></joint>'
        ]
    out = []
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.body_quat[b])
    previous, anchor = parent, None
    for k, j in enumerate(hinges):
        jname = model.joint(j).name
        here = np.array(model.jnt_pos[j], dtype=float)
        last = k == len(hinges) - 1
        exact = last and np.linalg.norm(here) <= 1e-12
        child = name if exact else f"{name}{SEPARATOR}{jname}"
        # MuJoCo turns a hinge by its angle less its `ref`; URDF by its angle: the origin
        # takes the turn by -ref, so both read the same angle
        ref = float(model.qpos0[model.jnt_qposadr[j]])
        turn = np.array([1.0, 0.0, 0.0, 0.0])
        if ref:
            mujoco.mju_axisAngle2Quat(turn, model.jnt_axis[j], -ref)
        if anchor is None:  # the first hinge: the body's offset and turn, then its anchor
            xyz, rpy = body_origin[0], body_origin[1]
            if np.linalg.norm(here) > 1e-12:
                xyz = xyz + rot.reshape(3, 3) @ here
            if ref:
                both = np.zeros(4)
                mujoco.mju_mulQuat(both, model.body_quat[b], turn)
                rpy = _rpy(both)
        else:
            xyz, rpy = here - anchor, _rpy(turn) if ref else np.zeros(3)
        effort, velocity = limit.get(jname, (0.0, 0.0))  # a loop's passive hinge: no motor
        lo, hi = model.jnt_range[j]
        kind, bounds = "revolute", f'lower="{_f(lo)}" upper="{_f(hi)}" '
        if not model.jnt_limited[j]:  # only a passive hinge may have no range
            kind, bounds = "continuous", ""
        damping = model.dof_damping[model.jnt_dofadr[j]]
        if not exact:
            out.append(_tiny_link(child))
        out.append(
            f'  <joint name="{jname}" type="{kind}"><origin xyz="{_v(xyz)}" rpy="{_v(rpy)}"/>'
            f'<parent link="{previous}"/><child link="{child}"/>'
            f'<axis xyz="{_v(model.jnt_axis[j])}"/>'
            f'<limit {bounds}effort="{_f(effort)}" '
            f'velocity="{_f(velocity)}"/><dynamics damping="{_f(damping)}" friction="0"/></joint>'
        )
        previous, anchor = child, here
    if previous != name:
        out.append(
            f'  <joint name="{name}_fixed" type="fixed">'
            f'<origin xyz="{_v(-anchor)}" rpy="0 0 0"/>'
            f'<parent link="{previous}"/><child link="{name}"/></joint>'
        )
    return out


def mesh_files(formats) -> dict[str, str]:
    """File name -> text of the files a model's URDF names (its `urdf:<file>` formats)."""
    return {k.split(":", 1)[1]: v for k, v in formats.items() if k.startswith("urdf:")}


def urdf_text(
    model: mujoco.MjModel,
    name: str,
    joints: list[str],
    torque: np.ndarray,
    speed: np.ndarray,
    files: dict[str, str] | None = None,
) -> tuple[str | None, str]:
    """(URDF text, "") of the robot in `model` (its first body below the world is the
    floating base), or (None, why not); the mesh files it names go into `files`."""
    files = {} if files is None else files
    limit = dict(zip(joints, zip(torque, speed, strict=True), strict=True))
    out = ['<?xml version="1.0"?>', f'<robot name="{name}">']
    for b in range(1, model.nbody):
        why, link = _link(model, b, files)
        if why:
            return None, why
        out.append(link)
        if int(model.body_parentid[b]) != 0:
            out += _joints(model, b, limit)
    return "\n".join([*out, "</robot>", ""]), ""
