"""A compiled spec model written back as MJCF with every number at full precision.

`MjSpec.to_xml` rounds numbers to six significant digits; a design's model must keep the
bodies, masses and inertias it was built with, so the robot is written from its compiled
`MjModel`: every value explicit (no defaults, inertials given, meshes inline), one motor
per actuated joint. Tendons are not written (`prepare` refuses them); the only equality
constraints are the spec's loops (`loops`), written as a connect between two sites.
"""

from __future__ import annotations

import mujoco
import numpy as np


def _n(x: float) -> str:
    return repr(float(x))


def _v(values) -> str:
    return " ".join(_n(x) for x in np.ravel(values))


_GEOM_TYPES = {
    int(mujoco.mjtGeom.mjGEOM_PLANE): "plane",
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    int(mujoco.mjtGeom.mjGEOM_MESH): "mesh",
}


def _geom(model: mujoco.MjModel, g: int) -> str:
    kind = _GEOM_TYPES.get(int(model.geom_type[g]))
    if kind is None:
        raise ValueError(f"geom {g} has a type MJCF output does not cover")
    name = model.geom(g).name
    attrs = [
        f'name="{name}"' if name else "",
        f'type="{kind}"',
        f'size="{_v(model.geom_size[g])}"',
        f'pos="{_v(model.geom_pos[g])}"',
        f'quat="{_v(model.geom_quat[g])}"',
        f'contype="{int(model.geom_contype[g])}"',
        f'conaffinity="{int(model.geom_conaffinity[g])}"',
        f'condim="{int(model.geom_condim[g])}"',
        f'friction="{_v(model.geom_friction[g])}"',
        f'solref="{_v(model.geom_solref[g])}"',
        f'solimp="{_v(model.geom_solimp[g])}"',
        f'margin="{_n(model.geom_margin[g])}"',
        f'gap="{_n(model.geom_gap[g])}"',
        f'priority="{int(model.geom_priority[g])}"',
        f'group="{int(model.geom_group[g])}"',
        f'rgba="{_v(model.geom_rgba[g])}"',
    ]
    if kind == "mesh":
        attrs.append(f'mesh="coadapt_mesh{int(model.geom_dataid[g])}"')
    return "<geom " + " ".join(a for a in attrs if a) + "/>"


def _joint(model: mujoco.MjModel, j: int) -> str:
    name = model.joint(j).name
    if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
        return f'<freejoint name="{name}"/>' if name else "<freejoint/>"
    dof = model.jnt_dofadr[j]
    attrs = [
        f'name="{name}"',
        'type="hinge"',
        f'pos="{_v(model.jnt_pos[j])}"',
        f'axis="{_v(model.jnt_axis[j])}"',
        f'ref="{_n(model.qpos0[model.jnt_qposadr[j]])}"',
        f'damping="{_n(model.dof_damping[dof])}"',
        f'armature="{_n(model.dof_armature[dof])}"',
        f'frictionloss="{_n(model.dof_frictionloss[dof])}"',
        f'stiffness="{_n(model.jnt_stiffness[j])}"',
    ]
    if model.jnt_limited[j]:
        attrs.append(f'limited="true" range="{_v(model.jnt_range[j])}"')
    else:
        attrs.append('limited="false"')
    return "<joint " + " ".join(attrs) + "/>"


def _body(model: mujoco.MjModel, b: int, children: dict[int, list[int]], depth: int) -> list[str]:
    pad = "  " * depth
    out = [
        f'{pad}<body name="{model.body(b).name}" pos="{_v(model.body_pos[b])}" '
        f'quat="{_v(model.body_quat[b])}">'
    ]
    out += [f"{pad}  {_joint(model, j)}" for j in range(model.njnt) if model.jnt_bodyid[j] == b]
    if model.body_mass[b] > 0:
        out.append(
            f'{pad}  <inertial pos="{_v(model.body_ipos[b])}" quat="{_v(model.body_iquat[b])}" '
            f'mass="{_n(model.body_mass[b])}" diaginertia="{_v(model.body_inertia[b])}"/>'
        )
    out += [f"{pad}  {_geom(model, g)}" for g in range(model.ngeom) if model.geom_bodyid[g] == b]
    for s in range(model.nsite):
        if model.site_bodyid[s] == b:
            out.append(
                f'{pad}  <site name="{model.site(s).name}" pos="{_v(model.site_pos[s])}" '
                f'quat="{_v(model.site_quat[s])}" size="{_v(model.site_size[s])}"/>'
            )
    for child in children.get(b, []):
        out += _body(model, child, children, depth + 1)
    return [*out, f"{pad}</body>"]


def _meshes(model: mujoco.MjModel) -> list[str]:
    out = []
    for m in range(model.nmesh):
        v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
        f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
        out.append(
            f'    <mesh name="coadapt_mesh{m}" vertex="{_v(model.mesh_vert[v0 : v0 + nv])}" '
            f'face="{" ".join(str(int(i)) for i in model.mesh_face[f0 : f0 + nf].ravel())}"/>'
        )
    return out


def mjcf_text(model: mujoco.MjModel, name: str, joints: list[str], torque: np.ndarray) -> str:
    """MJCF of the robot in `model` (bodies under the world, the first the floating base),
    with one motor per joint of `joints` whose control range is +-`torque`."""
    children: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        children.setdefault(int(model.body_parentid[b]), []).append(b)
    out = [
        f'<mujoco model="{name}">',
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
    ]
    meshes = _meshes(model)
    if meshes:
        out += ["  <asset>", *meshes, "  </asset>"]
    out.append("  <worldbody>")
    for root in children.get(0, []):
        out += _body(model, root, children, 2)
    out.append("  </worldbody>")
    excludes = []
    for e in range(model.nexclude):
        signature = int(model.exclude_signature[e])
        first, second = (signature >> 16) & 0xFFFF, signature & 0xFFFF
        excludes.append(
            f'    <exclude body1="{model.body(first).name}" body2="{model.body(second).name}"/>'
        )
    if excludes:
        out += ["  <contact>", *excludes, "  </contact>"]
    if model.neq:  # the spec's loops (`loops`): a connect between two sites each
        out.append("  <equality>")
        out += [
            f'    <connect name="{model.eq(e).name}" site1="{model.site(model.eq_obj1id[e]).name}" '
            f'site2="{model.site(model.eq_obj2id[e]).name}" solref="{_v(model.eq_solref[e])}" '
            f'solimp="{_v(model.eq_solimp[e])}"/>'
            for e in range(model.neq)
        ]
        out.append("  </equality>")
    out.append("  <actuator>")
    out += [
        f'    <motor name="{j}" joint="{j}" gear="1" ctrllimited="true" '
        f'ctrlrange="{_n(-t)} {_n(t)}"/>'
        for j, t in zip(joints, torque, strict=True)
    ]
    return "\n".join([*out, "  </actuator>", "</mujoco>", ""])
