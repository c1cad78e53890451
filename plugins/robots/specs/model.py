"""A spec's model file, loaded once and scaled per design (`mujoco.MjSpec`).

Loading checks the spec against the model (every body and joint it names exists, each link
is a parent and its child, each foot ends a leg chain) and brings the model to the robot
contract of `coadapt_core.robot`: the floating base first, one `<motor>` per actuated hinge
joint, ground-touching geoms `contype=1 conaffinity=0`, no floor, keyframes, sensors or
actuators of its own. `scaled(design)` returns an edited copy for one design:

- a link (parent, child) scaled by s moves the child along its position vector (pos x s);
  the parent's geoms and sites move along that vector likewise, and those lying along it
  (capsules, cylinders, boxes, ellipsoids whose axis is within 8 deg of it) stretch by s;
- a mesh geom of a scaled body gets a mesh of its own (the compiled vertices, in the geom's
  compiled frame) when the model loads, and a design stretches its vertices along the link
  (x -> x + (s - 1)(x.u)u): a visual mesh (contype = conaffinity = 0) always, a collision
  mesh when one of its principal axes lies within 8 deg of the link; spec `collision: fit`
  replaces every collision mesh of a scaled body by the primitive (box, capsule or cylinder,
  fitted by MuJoCo to its inertia box or its bounding box) closest to it in volume; any
  other collision mesh is refused in one line naming that option (`meshes`);
- mass rule "stretch" (explicit inertial): the body's `stretch_share` of its mass stretches
  with the link (density kept: that mass x s, its distribution scaled by s along the link)
  and the rest is a point mass at the body's origin (a motor at its joint); the centre of
  mass and inertia follow exactly from that (first and second moments about the origin).
  A body without an explicit inertial gets its mass and inertia from its stretched geoms
  when MuJoCo compiles. Rule "fixed": mass, centre of mass and inertia unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.locks import lock_joints
from coadapt_plugins.robots.specs.loops import add_pins, check_loops
from coadapt_plugins.robots.specs.meshes import _MESH, ALONG, _own_meshes, _quat_mat
from coadapt_plugins.robots.specs.orient import add_tips, inertia_from_shape, reorient
from coadapt_plugins.robots.specs.spec import RobotSpec, spec_error

_SCALABLE = {
    mujoco.mjtGeom.mjGEOM_CAPSULE,
    mujoco.mjtGeom.mjGEOM_CYLINDER,
    mujoco.mjtGeom.mjGEOM_BOX,
    mujoco.mjtGeom.mjGEOM_ELLIPSOID,
    mujoco.mjtGeom.mjGEOM_SPHERE,
}


def load_mjspec(
    path,
    *,
    package_paths: tuple = (),
    assets: dict | None = None,
    balanceinertia: bool = False,
    shape_inertia: bool = False,
    shaped: list | None = None,
    urdf_fixes: tuple = (),
) -> mujoco.MjSpec:
    """The model file as an `MjSpec` (MJCF or URDF), read from where it lives: its includes
    and assets as MuJoCo finds them from the file's folder, a URDF's `package://` meshes and
    the files of `assets` (reference -> path) handed over as bytes (`files`);
    `balanceinertia` is MuJoCo's compiler option; `shape_inertia` gives a body of zero
    inertia its collision shape's box's (`orient.inertia_from_shape`; their names appended
    to `shaped`); `urdf_fixes` are made in memory (`urdffix`).
    MuJoCo's own message in one line."""
    from coadapt_plugins.robots.specs.files import loader_assets

    path = Path(path)
    handed = loader_assets(path, tuple(package_paths), assets)
    try:
        if urdf_fixes:
            from coadapt_plugins.robots.specs.urdffix import fixed_xml

            text = fixed_xml(path, tuple(urdf_fixes), tuple(package_paths), assets)
            spec = mujoco.MjSpec.from_string(text)
        else:
            spec = mujoco.MjSpec.from_file(str(path), assets=handed)
        # keep bodies fixed to their parents (a URDF's feet) and a URDF's root link: MuJoCo
        # fuses them into their parents by default when it reads a URDF
        spec.compiler.fusestatic = False
        if balanceinertia:
            spec.compiler.balanceinertia = True
        if shape_inertia:
            names = inertia_from_shape(spec)
            if shaped is not None:
                shaped += names
        spec.compile()
    except (ValueError, mujoco.FatalError, OSError) as exc:
        first = " ".join(str(exc).split())
        raise spec_error("model", f"'{path.name}' does not load in MuJoCo: {first}") from None
    return spec


def spec_mjspec(rs: RobotSpec) -> mujoco.MjSpec:
    """`rs`'s model file loaded with the spec's fixes for loading (assets, balanceinertia,
    inertia_from_shape, urdf_fixes)."""
    return load_mjspec(
        rs.model_path,
        assets=rs.asset_paths,
        balanceinertia=rs.balanceinertia,
        shape_inertia=rs.inertia_from_shape,
        urdf_fixes=rs.urdf_fixes,
    )


def fix_joints(spec: mujoco.MjSpec, rs: RobotSpec, joints: list[str]) -> None:
    """The spec's `joints` fixes (range, armature, damping) on the hinges they match; a
    pattern that matches none is refused."""
    import re

    for pattern, fix in rs.joints.items():
        hits = [j for j in joints if re.fullmatch(pattern, j)]
        if not hits:
            raise spec_error(
                f"joints.{pattern}",
                f"matches no hinge joint of the model (it has: {', '.join(joints)})",
            )
        for name in hits:
            joint = spec.joint(name)
            if "range" in fix:
                joint.range = list(fix["range"])
                joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            if "armature" in fix:
                joint.armature = fix["armature"]
            if "damping" in fix:
                damping = np.atleast_1d(np.array(joint.damping, dtype=float))
                damping[0] = fix["damping"]  # the linear term (MuJoCo 4 keeps more)
                joint.damping = damping if damping.size > 1 else float(damping[0])


def _root(spec: mujoco.MjSpec, base: str | None) -> mujoco.MjsBody:
    if base is not None:
        body = spec.body(base)
        if body is None:
            raise spec_error("base", f"no body '{base}' in the model")
        return body
    roots = list(spec.worldbody.bodies)
    if len(roots) != 1:
        names = ", ".join(b.name for b in roots)
        raise spec_error("base", f"the model has {len(roots)} root bodies ({names}); name one")
    return roots[0]


def _subtree(body: mujoco.MjsBody) -> list[mujoco.MjsBody]:
    out = [body]
    for child in body.bodies:
        out += _subtree(child)
    return out


@dataclass
class Prepared:
    """The contract-shaped model every design is edited from, and what loading found."""

    spec: mujoco.MjSpec
    base: str
    joints: list[str]  # actuated hinge joints, model order
    standing: np.ndarray  # [J] standing pose
    armature: np.ndarray  # [J]
    damping: np.ndarray  # [J]
    fits: list[str] = field(default_factory=list)  # one line per collision mesh fitted
    passive: list[str] = field(default_factory=list)  # hinges of `loops` no motor drives
    passive_seeds: np.ndarray | None = None  # [P] their standing angles (the loops' seeds)


def _standing_pose(spec: mujoco.MjSpec, rs: RobotSpec, joints: list[str]) -> np.ndarray:
    pose = rs.standing_pose
    if isinstance(pose, str):
        key = next((k for k in spec.keys if k.name == pose), None)
        if key is None:
            names = ", ".join(k.name for k in spec.keys) or "none"
            raise spec_error(
                "standing_pose.keyframe", f"no keyframe '{pose}' (the model has: {names})"
            )
        model = spec.compile()
        qpos = np.array(list(key.qpos), dtype=float)
        if qpos.size != model.nq:
            raise spec_error(
                "standing_pose.keyframe", f"'{pose}' has {qpos.size} values, not {model.nq}"
            )
        adr = [model.jnt_qposadr[model.joint(j).id] for j in joints]
        return qpos[adr]
    unknown = sorted(set(pose) - set(joints))
    if unknown:
        raise spec_error(f"standing_pose.joints.{unknown[0]}", "not a hinge joint of the model")
    return np.array([pose.get(j, 0.0) for j in joints], dtype=float)


def prepare(rs: RobotSpec) -> Prepared:
    """Load `rs`'s model file and shape it to the robot contract (module docstring)."""
    spec = spec_mjspec(rs)
    if list(spec.tendons) or list(spec.equalities):
        raise spec_error(
            "model",
            "tendons and equality constraints (closed chains) are not supported: a spec robot "
            "is a tree of hinges; write a robot plugin for it (docs/plugins.md)",
        )
    root = _root(spec, rs.base)
    if rs.base_orientation is not None:
        reorient(root, rs.base_orientation)
    add_tips(spec, rs.tips)
    add_pins(spec, rs.pins)
    bodies = _subtree(root)
    lock_joints(spec, rs.locked_joints, rs.locked_at)
    if not any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in root.joints):
        for j in list(root.joints):
            raise spec_error(
                "base", f"the base '{root.name}' has a joint '{j.name}' that is not free"
            )
        root.add_freejoint()
    hinges = []
    for body in bodies:
        for j in body.joints:
            if j.type == mujoco.mjtJoint.mjJNT_HINGE:
                hinges.append(j.name)
            elif j.type != mujoco.mjtJoint.mjJNT_FREE or body is not root:
                raise spec_error(
                    "locked_joints", f"joint '{j.name}' is not a hinge; lock it or model a hinge"
                )
    if any(not name for name in hinges):
        raise spec_error("model", "every hinge joint needs a name")
    passive = check_loops(spec, rs.loops, hinges)  # hinges no motor drives (`loops`)
    joints = [h for h in hinges if h not in passive]
    fix_joints(spec, rs, hinges)
    # keep the robot alone: no floor, no keyframes, sensors or actuators of its own
    for geom in list(spec.worldbody.geoms):
        spec.delete(geom)
    standing = _standing_pose(spec, rs, hinges)
    seeds = standing[[hinges.index(p) for p in passive]]
    standing = standing[[hinges.index(j) for j in joints]]
    for element in [*spec.keys, *spec.sensors, *spec.actuators]:
        spec.delete(element)
    for body in bodies:
        for geom in body.geoms:
            if geom.contype or geom.conaffinity:
                geom.contype, geom.conaffinity = 1, 0
    model = spec.compile()
    fits = _own_meshes(spec, model, rs)
    dofs = [model.jnt_dofadr[model.joint(j).id] for j in joints]
    return Prepared(
        spec,
        root.name,
        joints,
        standing,
        model.dof_armature[dofs].copy(),
        model.dof_damping[dofs].copy(),
        fits,
        passive,
        seeds,
    )


def check_names(rs: RobotSpec, prepared: Prepared) -> None:
    """Every body the spec names exists; each link's child is a child of its parent."""
    spec = prepared.spec
    for k, p in enumerate(rs.parameters):
        for m, (parent, child) in enumerate(p.links):
            where = f"design[{k}].links[{m}]"
            for name in (parent, child):
                if spec.body(name) is None:
                    raise spec_error(where, f"no body '{name}' in the model")
            if spec.body(child).parent.name != parent:
                raise spec_error(
                    where,
                    f"'{child}' is not a child of '{parent}' (a link is a body and its child)",
                )
            if np.linalg.norm(spec.body(child).pos) < 1e-9:
                raise spec_error(
                    where, f"'{child}' sits at '{parent}''s origin: the link has no length"
                )
    for k, leg in enumerate(rs.legs):
        foot = spec.body(leg.foot)
        if foot is None:
            raise spec_error(f"legs[{k}].foot", f"no body '{leg.foot}' in the model")
        if any(True for _ in foot.bodies):
            raise spec_error(
                f"legs[{k}].foot", f"'{leg.foot}' has child bodies: a foot ends a leg chain"
            )
        if leg.hip is not None and spec.body(leg.hip) is None:
            raise spec_error(f"legs[{k}].hip", f"no body '{leg.hip}' in the model")


def _stretch_geoms(
    spec: mujoco.MjSpec, body: mujoco.MjsBody, u: np.ndarray, s: float, where: str
) -> None:
    """Move `body`'s geoms and sites along u by s, stretching those that lie along it and
    the vertices of its meshes (`prepare` gave each its own)."""
    shift = np.eye(3) + (s - 1.0) * np.outer(u, u)
    for geom in body.geoms:
        if geom.type == _MESH and geom.meshname.startswith("coadapt_stretch_"):
            mesh = spec.mesh(geom.meshname)
            w = _quat_mat(geom.quat).T @ u  # the link in the mesh's frame
            vertices = np.array(mesh.uservert, dtype=float).reshape(-1, 3)
            mesh.uservert = (vertices + (s - 1.0) * np.outer(vertices @ w, w)).ravel()
            geom.pos = shift @ np.array(geom.pos, dtype=float)
            continue
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
            raise spec_error(
                where,
                f"body '{body.name}' holds the mesh geom '{geom.name or '(unnamed)'}': coadapt "
                "scales capsules, cylinders, boxes, spheres and ellipsoids; give the link "
                "primitive geoms or leave it unscaled",
            )
        if geom.type not in _SCALABLE and geom.type != mujoco.mjtGeom.mjGEOM_PLANE:
            raise spec_error(where, f"geom '{geom.name}' of body '{body.name}' cannot be scaled")
        fromto = np.array(geom.fromto, dtype=float)
        if not np.isnan(fromto[0]):
            geom.fromto = np.concatenate([shift @ fromto[:3], shift @ fromto[3:]])
            continue
        geom.pos = shift @ np.array(geom.pos, dtype=float)
        axes = _quat_mat(geom.quat)  # columns: the geom's axes in the body frame
        size = np.array(geom.size, dtype=float)
        if geom.type in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
            if abs(axes[:, 2] @ u) >= ALONG:
                size[1] *= s
        elif geom.type in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
            for i in range(3):
                if abs(axes[:, i] @ u) >= ALONG:
                    size[i] *= s
        geom.size = size
    for site in body.sites:
        site.pos = shift @ np.array(site.pos, dtype=float)


def inertia_tensor(body: mujoco.MjsBody) -> np.ndarray:
    """[3, 3] the explicit inertial's tensor about its centre of mass, body frame."""
    full = np.array(body.fullinertia, dtype=float)
    if not np.isnan(full[0]):
        xx, yy, zz, xy, xz, yz = full
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    rot = _quat_mat(body.iquat)
    return rot @ np.diag(np.array(body.inertia, dtype=float)) @ rot.T


def set_inertia(body: mujoco.MjsBody, mass: float, com: np.ndarray, tensor: np.ndarray) -> None:
    body.mass = float(mass)
    body.ipos = com
    body.iquat = [1.0, 0.0, 0.0, 0.0]
    body.inertia = [0.0, 0.0, 0.0]  # "not given": the full tensor holds it
    body.fullinertia = [
        tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2],
    ]  # fmt: skip


def combine(
    parts: list[tuple[float, np.ndarray, np.ndarray]],
) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia about it) of rigid parts given as (mass, com, inertia
    about its own com), all in one frame."""
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass
    tensor = np.zeros((3, 3))
    for m, c, inertia in parts:
        d = c - com
        tensor += inertia + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, tensor


def stretch_inertial(body: mujoco.MjsBody, u: np.ndarray, s: float, share: float) -> None:
    """The "stretch" mass rule (module docstring) applied to `body`'s explicit inertial: the
    body is a point mass (1 - share) x m at its origin (a motor at its joint) and the rest,
    which carries all of its first and second moments about the origin, stretches by s along
    u with its density kept."""
    mass, com = float(body.mass), np.array(body.ipos, dtype=float)
    inertia = inertia_tensor(body)
    second = 0.5 * np.trace(inertia) * np.eye(3) - inertia + mass * np.outer(com, com)  # origin
    shift = np.eye(3) + (s - 1.0) * np.outer(u, u)
    new_mass = (1.0 - share) * mass + s * share * mass
    new_com = s * (shift @ com) * mass / new_mass
    new_second = s * shift @ second @ shift.T - new_mass * np.outer(new_com, new_com)
    set_inertia(body, new_mass, new_com, np.trace(new_second) * np.eye(3) - new_second)


def scale_link(spec: mujoco.MjSpec, parent: str, child: str, s: float, param, where: str) -> None:
    """Scale the link (parent, child) by `s` with `param`'s mass rule."""
    if abs(s - 1.0) < 1e-15:
        return
    body, kid = spec.body(parent), spec.body(child)
    vector = np.array(kid.pos, dtype=float)
    u = vector / np.linalg.norm(vector)
    kid.pos = vector * s
    _stretch_geoms(spec, body, u, s, where)
    if body.explicitinertial and param.mass == "stretch":
        stretch_inertial(body, u, s, param.stretch_share)


def add_point_mass(spec: mujoco.MjSpec, joint: str, delta: float) -> None:
    """A motor type's extra mass `delta` (kg), at `joint`'s anchor in its body."""
    j = spec.joint(joint)
    body = j.parent
    anchor = np.array(j.pos, dtype=float)
    if body.explicitinertial:
        parts = [(float(body.mass), np.array(body.ipos, dtype=float), inertia_tensor(body))]
        mass, com, tensor = combine([*parts, (delta, anchor, np.zeros((3, 3)))])
        if mass <= 0:
            raise spec_error("motors.types", f"the motor makes body '{body.name}' massless")
        set_inertia(body, mass, com, tensor)
    elif delta > 0:
        body.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0, 0], pos=anchor, mass=delta,
            contype=0, conaffinity=0, group=4,
        )  # fmt: skip
    else:
        raise spec_error(
            "motors.types",
            f"a lighter motor at '{joint}' needs an explicit inertial on body '{body.name}'",
        )
