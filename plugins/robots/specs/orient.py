"""Model fixes for frames and inertias a model file gives in its own way (`model`, `new`):

- `base_orientation` [w, x, y, z]: the rotation from the model's base frame to the robot's
  (x forward, z up); a y-up model (pybullet_data's laikago.urdf) gets its base's contents
  (child bodies, geoms, sites, cameras, lights, inertial) turned by it, so the base frame of
  the robot is upright at the identity orientation. `up_rotation` finds it from the model:
  up is the axis opposite the feet, forward the other axis the feet spread along most (its
  sign from the legs' front and rear names), left completes a right-handed frame; None for a
  z-up model, which is left as it is.
- `tips` {BODY: [x, y, z]}: a foot point the model has no body for (its leg's last body turns
  about its own origin, so its origin is a knee, not a foot): a body `BODY_tip` there, in
  BODY's frame, holding a collision sphere of TIP_RADIUS and TIP_MASS, which ends the leg
  (`add_tips`). `find_tips` puts the sphere's far side at the point of the body's collision
  geoms farthest from its origin, for a leg of three hinges or more whose last body holds one
  hinge at its origin and reaches TIP_SHARE of the leg's longest link beyond it (a shank; a
  biped's sole is shorter, and its origin is the ankle the IK places).
- `inertia_from_shape`: a body the model gives a mass but a zero inertia (MuJoCo refuses it:
  "mass and inertia of moving bodies must be larger than mjMINVAL"; PyBullet by default
  computes it from the collision shape) gets the inertia of a solid box of its mass filling
  the box that bounds its collision geoms in its frame (as Bullet approximates a mesh's);
  its centre of mass stays the model's.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

from coadapt_core.errors import UserError

#: the model is left as it is when its feet all hang below its base along z (z-up), or when
#: along no axis do they all lie UPRIGHT of their mean distance to one side of it
UPRIGHT = 0.25
#: a foot point is added where a leg's last body turns about its own origin and its geoms
#: reach at least this share of the chain's longest link beyond it, a shank not a sole (`tips`)
TIP_SHARE = 0.75
TIP_SUFFIX = "_tip"
#: the collision sphere a tip body holds: its radius (m; its surface reaches the tip point)
#: and its mass (kg: as the URDF writer's intermediate links, far below anything the dynamics
#: notice, above MuJoCo's and Bullet's zero)
TIP_RADIUS = 0.01
TIP_MASS = 1e-6
_FRONT = re.compile(r"^(f|fl|fr|lf|rf|front|fore)$")
_REAR = re.compile(r"^(rl|rr|hl|hr|lh|rh|rear|back|hind|h)$")


def _mat(quat) -> np.ndarray:
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=float))
    return out.reshape(3, 3)


def _turn(element, quat: np.ndarray, where: str) -> None:
    """`element`'s pos and quat (in the base frame) turned by `quat`."""
    if element.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        raise UserError(
            f"robot spec field 'base_orientation': '{element.name or where}' in the base gives "
            "its orientation other than as a quaternion; turn the model's base in the file "
            "instead",
            field="base_orientation",
        )
    element.pos = _mat(quat) @ np.array(element.pos, dtype=float)
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, quat, np.array(element.quat, dtype=float))
    element.quat = out


def reorient(root: mujoco.MjsBody, quat) -> None:
    """Turn the contents of the base body `root` by `quat` (module docstring)."""
    quat = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    rot = _mat(quat)
    for child in [*root.bodies, *root.sites, *root.cameras, *root.frames]:
        _turn(child, quat, "a child of the base")
    for light in root.lights:
        light.pos = rot @ np.array(light.pos, dtype=float)
        light.dir = rot @ np.array(light.dir, dtype=float)
    for geom in root.geoms:
        fromto = np.array(geom.fromto, dtype=float)
        if not np.isnan(fromto[0]):
            geom.fromto = np.concatenate([rot @ fromto[:3], rot @ fromto[3:]])
        else:
            _turn(geom, quat, "a geom of the base")
    if root.explicitinertial:
        root.ipos = rot @ np.array(root.ipos, dtype=float)
        full = np.array(root.fullinertia, dtype=float)
        if np.isnan(full[0]):
            out = np.zeros(4)
            mujoco.mju_mulQuat(out, quat, np.array(root.iquat, dtype=float))
            root.iquat = out
        else:
            xx, yy, zz, xy, xz, yz = full
            t = rot @ np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) @ rot.T
            root.fullinertia = [t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]]


def _sign(names: list[list[str]], coords: np.ndarray) -> float:
    """-1 when the legs named front lie behind those named rear along `coords`, else 1."""
    front = [c for n, c in zip(names, coords, strict=True) if any(_FRONT.match(t) for t in n)]
    rear = [c for n, c in zip(names, coords, strict=True) if any(_REAR.match(t) for t in n)]
    if front and rear and np.mean(front) < np.mean(rear):
        return -1.0
    return 1.0


def up_rotation(model: mujoco.MjModel, data: mujoco.MjData, base: int) -> np.ndarray | None:
    """[w, x, y, z] turning the base's frame upright (module docstring), or None when the
    feet already hang along its -z. `data` holds the model's pose, kinematics done."""
    from coadapt_plugins.robots.specs.legs import _chain, _hinges, _tokens

    feet = []
    for b in range(1, model.nbody):
        if any(model.body_parentid[c] == b for c in range(1, model.nbody)):
            continue
        chain = _chain(model, base, b)
        if len(chain) >= 2 and _hinges(model, chain) >= 2:
            feet.append((b, chain))
    if not feet:
        return None
    frame = data.xmat[base].reshape(3, 3)
    rel = np.array([frame.T @ (data.xpos[b] - data.xpos[base]) for b, _ in feet])
    reach = float(np.mean(np.linalg.norm(rel, axis=1)))
    # how far every foot lies on one side of the base, along each axis and way
    side = np.stack([(-rel).min(axis=0), rel.min(axis=0)])  # [below, above] per axis
    way, k = np.unravel_index(int(np.argmax(side)), side.shape)
    if (k == 2 and way == 0) or side[way, k] < UPRIGHT * reach:
        return None  # z-up, or feet spread around the base (an ant at rest): left as it is
    up = np.zeros(3)
    up[k] = 1.0 if way == 0 else -1.0
    others = [i for i in range(3) if i != k]
    along = others[int(np.argmax([np.ptp(rel[:, i]) for i in others]))]
    names = [
        [t.lower() for b in chain for t in _tokens(model.body(int(b)).name)] for _, chain in feet
    ]
    forward = np.zeros(3)
    forward[along] = _sign(names, rel[:, along])
    rows = np.stack([forward, np.cross(up, forward), up])  # the robot's axes, model frame
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rows.ravel())
    return quat


def zero_inertia_bodies(spec: mujoco.MjSpec) -> list[mujoco.MjsBody]:
    """The bodies with an explicit inertial, a mass and a zero inertia."""
    out = []
    for body in spec.bodies:
        if body.name == "world" or not body.explicitinertial or body.mass <= 0:
            continue
        full = np.array(body.fullinertia, dtype=float)
        values = np.array(body.inertia, dtype=float) if np.isnan(full[0]) else full[:3]
        if np.all(np.abs(values) <= mujoco.mjMINVAL):
            out.append(body)
    return out


def inertia_from_shape(spec: mujoco.MjSpec) -> list[str]:
    """Give each zero-inertia body (`zero_inertia_bodies`) the inertia of a solid box of its
    mass filling the box that bounds its collision geoms, body axes (Bullet's approximation
    of a mesh's inertia); returns their names."""
    bodies = zero_inertia_bodies(spec)
    if not bodies:
        return []
    scratch = spec.copy()
    scratch.compiler.boundmass = 1e-9
    scratch.compiler.boundinertia = 1e-12
    model = scratch.compile()
    done = []
    for body in bodies:
        b = model.body(body.name).id
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == b]
        colliding = [g for g in geoms if model.geom_contype[g] or model.geom_conaffinity[g]]
        points = [_geom_points(model, g) for g in colliding or geoms]
        points = np.concatenate(points) if points else np.zeros((0, 3))
        if len(points) < 2:  # no shape to take an inertia from
            continue
        dx, dy, dz = np.ptp(points, axis=0)
        m = float(body.mass)
        body.inertia = [
            m * (dy**2 + dz**2) / 12,
            m * (dx**2 + dz**2) / 12,
            m * (dx**2 + dy**2) / 12,
        ]
        body.iquat = [1.0, 0.0, 0.0, 0.0]
        body.fullinertia = [np.nan, 0.0, 0.0, 0.0, 0.0, 0.0]
        done.append(body.name)
    return done


def add_tips(spec: mujoco.MjSpec, tips: dict) -> None:
    """The spec's `tips`: a massless body `BODY_tip` at each point (module docstring)."""
    for body, pos in tips.items():
        parent = spec.body(body)
        if parent is None:
            raise UserError(
                f"robot spec field 'tips.{body}': no body '{body}' in the model", field="tips"
            )
        if spec.body(body + TIP_SUFFIX) is not None:
            raise UserError(
                f"robot spec field 'tips.{body}': the model has a body '{body}{TIP_SUFFIX}' "
                "already",
                field="tips",
            )
        tip = parent.add_body(name=body + TIP_SUFFIX, pos=[float(x) for x in pos])
        tip.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[TIP_RADIUS, 0, 0], mass=TIP_MASS,
            contype=1, conaffinity=1,
        )  # fmt: skip


def _geom_points(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Points of geom `g`'s surface (a mesh's vertices, a primitive's extremes), body frame."""
    pos, rot = model.geom_pos[g], _mat(model.geom_quat[g])
    size, kind = model.geom_size[g], int(model.geom_type[g])  # an int: `in` needs one
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        m = int(model.geom_dataid[g])
        v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
        local = model.mesh_vert[v0 : v0 + nv]
    elif kind in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
        end = size[1] + (size[0] if kind == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0)
        local = np.array([[0, 0, end], [0, 0, -end]])
    elif kind in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        local = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * size
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        local = np.eye(3) * size[0]
        local = np.concatenate([local, -local])
    else:
        return np.zeros((0, 3))
    return pos + np.asarray(local, dtype=float) @ rot.T


def find_tips(model: mujoco.MjModel, legs: list[dict]) -> dict[str, list[float]]:
    """{foot body: its tip point} for the legs (`legs._legs`) that need one (module
    docstring)."""
    from coadapt_plugins.robots.specs.legs import _hinges

    out = {}
    for leg in legs:
        b = int(leg["foot"])
        own = [
            j
            for j in range(model.njnt)
            if model.jnt_bodyid[j] == b and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
        ]
        if _hinges(model, leg["chain"]) < 3 or len(own) != 1:
            continue
        if np.linalg.norm(model.jnt_pos[own[0]]) > 1e-6:
            continue
        geoms = [
            g
            for g in range(model.ngeom)
            if model.geom_bodyid[g] == b and (model.geom_contype[g] or model.geom_conaffinity[g])
        ]
        points = np.concatenate([np.zeros((1, 3)), *(_geom_points(model, g) for g in geoms)])
        far = points[int(np.argmax(np.linalg.norm(points, axis=1)))]
        longest = max(float(np.linalg.norm(model.body_pos[c])) for c in leg["chain"][1:])
        if np.linalg.norm(far) >= max(TIP_SHARE * longest, 2 * TIP_RADIUS):
            centre = far * (1.0 - TIP_RADIUS / np.linalg.norm(far))
            out[model.body(b).name] = [round(float(x), 6) + 0.0 for x in centre]
    return out
