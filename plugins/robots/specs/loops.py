"""Closed loops a model file leaves open, closed by the robot (spec `loops`).

A four-bar leg (PyBullet's minitaurs) is written as two open chains hinged on one axis whose
lower legs' ends meet at the toe; PyBullet's own minitaur environment closes it in code. A
spec loop names two bodies whose origins the robot holds together (the two lower legs'
`tips`) and the hinges on their chains that no motor drives (`passive`: the knees).

Per design, at the standing pose's motor angles the passive hinges are solved so that the two
origins come nearest (Gauss-Newton on their distance; what is left is an offset along the
hinges' common axis, kept as it is) and that solution is turned into the model: each passive
hinge's body is turned by its angle about the hinge, so the hinge's zero is the closed
standing pose and every simulator's reset (passive hinges at 0) starts with the loop closed;
a passive hinge is not a policy joint and its reading is not observed. A site on each body at
the meeting point and a MuJoCo `<connect>` between the two sites hold the loop
(`loop_points`: the same points for a simulator that adds its own point-to-point constraint);
the two bodies and the links carrying them do not collide with each other (they meet at the
pin).
"""

from __future__ import annotations

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.fields import spec_error

#: a loop whose two points stay farther apart than this share of the first body's distance
#: from the base once the passive hinges are solved does not close: refused
LOOP_SHARE = 0.1
#: Gauss-Newton steps at most, and the step (rad) below which it stops
ITERATIONS = 100
STEP = 1e-12
#: the sites holding loop k: SITE.format(k=k, side="a" or "b")
SITE = "coadapt_loop{k}_{side}"


#: the body a spec `pins` entry adds: BODY + PIN_SUFFIX, massless as a tip is (TIP_MASS)
PIN_SUFFIX = "_pin"


def add_pins(spec: mujoco.MjSpec, pins: dict) -> None:
    """The spec's `pins`: a body `BODY_pin` at each point, no geom, a tip's mass."""
    from coadapt_plugins.robots.specs.orient import TIP_MASS

    for body, pos in pins.items():
        parent = spec.body(body)
        if parent is None:
            raise spec_error(
                f"pins.{body}",
                f"no body '{body}' in the model; pins takes a body of the model and a point "
                "[x, y, z] in its frame",
            )
        if spec.body(body + PIN_SUFFIX) is not None:
            raise spec_error(f"pins.{body}", f"the model has a body '{body}{PIN_SUFFIX}' already")
        pin = parent.add_body(name=body + PIN_SUFFIX, pos=[float(x) for x in pos])
        pin.mass = TIP_MASS
        pin.inertia = [TIP_MASS * 1e-4] * 3
        pin.explicitinertial = True


def loop_leg(model, base_id: int, feet: list[str], body: str) -> int | None:
    """The leg (index into `feet`) whose chain holds `body` (its foot, or a body hanging from
    a body of its chain), else None."""
    for k, foot in enumerate(feet):
        path, b = set(), model.body(foot).id
        while b not in (base_id, 0):
            path.add(b)
            b = int(model.body_parentid[b])
        if body == foot or int(model.body_parentid[model.body(body).id]) in path:
            return k
    return None


def check_loops(spec: mujoco.MjSpec, loops, hinges: list[str]) -> list[str]:
    """The passive hinges of `loops` (spec `loops`), in model order; one line naming the
    field for a body or joint the model lacks."""
    passive = set()
    for k, (a, b, names) in enumerate(loops):
        for body in (a, b):
            if spec.body(body) is None:
                raise spec_error(f"loops[{k}].bodies", f"no body '{body}' in the model")
        for name in names:
            if name not in hinges:
                raise spec_error(f"loops[{k}].passive", f"'{name}' is not a hinge of the model")
            passive.add(name)
    return [h for h in hinges if h in passive]


def _residual(model, data, loops) -> tuple[np.ndarray, np.ndarray]:
    """([3 K] the loops' gaps, [3 K, nv] their Jacobian) at `data`'s pose."""
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    gaps, rows = [], []
    for a, b, _ in loops:
        ids = [model.body(a).id, model.body(b).id]
        jacs = []
        for body in ids:
            jac = np.zeros((3, model.nv))
            mujoco.mj_jac(model, data, jac, None, data.xpos[body], body)
            jacs.append(jac)
        gaps.append(data.xpos[ids[0]] - data.xpos[ids[1]])
        rows.append(jacs[0] - jacs[1])
    return np.concatenate(gaps), np.concatenate(rows)


def solve_passive(model, loops, joints, pose, passive, seeds) -> tuple[np.ndarray, np.ndarray]:
    """([P] the passive hinges' angles that close `loops` with the hinges `joints` at `pose`,
    starting from `seeds`; [K] each loop's gap left, m)."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    for name, angle in zip(joints, pose, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    q_adr = [int(model.jnt_qposadr[model.joint(n).id]) for n in passive]
    v_adr = [int(model.jnt_dofadr[model.joint(n).id]) for n in passive]
    data.qpos[q_adr] = seeds
    for _ in range(ITERATIONS):
        gap, jac = _residual(model, data, loops)
        step = np.linalg.lstsq(jac[:, v_adr], -gap, rcond=1e-10)[0]
        data.qpos[q_adr] += np.clip(step, -0.5, 0.5)
        if np.max(np.abs(step), initial=0.0) < STEP:
            break
    gap, _ = _residual(model, data, loops)
    return data.qpos[q_adr].copy(), np.linalg.norm(gap.reshape(-1, 3), axis=1)


def _turn(spec: mujoco.MjSpec, model: mujoco.MjModel, name: str, angle: float) -> None:
    """Turn hinge `name`'s body by `angle` about the hinge, so that its zero is there."""
    j = model.joint(name).id
    b = int(model.jnt_bodyid[j])
    turn = np.zeros(4)
    mujoco.mju_axisAngle2Quat(turn, model.jnt_axis[j], angle)
    rot, frame = np.zeros(9), np.zeros(9)
    mujoco.mju_quat2Mat(rot, turn)
    mujoco.mju_quat2Mat(frame, model.body_quat[b])
    anchor = model.jnt_pos[j]
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, model.body_quat[b], turn)
    body = spec.body(model.body(b).name)
    body.pos = model.body_pos[b] + frame.reshape(3, 3) @ (anchor - rot.reshape(3, 3) @ anchor)
    body.quat = quat
    joint = spec.joint(name)
    if model.jnt_limited[j]:
        shift = np.degrees(angle) if spec.compiler.degree else angle
        joint.range = [float(joint.range[0]) - shift, float(joint.range[1]) - shift]


def close_loops(spec, model, rs, joints, pose, passive, seeds) -> mujoco.MjModel:
    """`spec` (one design, compiled as `model`) with its loops closed at the standing `pose`
    of `joints` (module docstring), compiled again; one line when a loop does not close."""
    angles, gaps = solve_passive(model, rs.loops, joints, pose, passive, seeds)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    for k, (a, b, _) in enumerate(rs.loops):
        reach = np.linalg.norm(data.xpos[model.body(a).id] - data.xpos[model.body(a).rootid])
        if gaps[k] > LOOP_SHARE * reach:
            raise spec_error(
                f"loops[{k}]",
                f"'{a}' and '{b}' stay {gaps[k]:.3g} m apart at the standing pose whatever "
                f"the passive hinges ({', '.join(rs.loops[k][2]) or 'none'}): the loop does "
                "not close",
            )
    for name, angle in zip(passive, angles, strict=True):
        _turn(spec, model, name, float(angle))
    closed = spec.compile()
    data = mujoco.MjData(closed)
    data.qpos[:] = closed.qpos0
    for name, angle in zip(joints, pose, strict=True):
        data.qpos[closed.jnt_qposadr[closed.joint(name).id]] = angle
    mujoco.mj_kinematics(closed, data)
    for k, (a, b, _) in enumerate(rs.loops):
        ia, ib = closed.body(a).id, closed.body(b).id
        at_b = data.xmat[ib].reshape(3, 3).T @ (data.xpos[ia] - data.xpos[ib])
        spec.body(a).add_site(name=SITE.format(k=k, side="a"), size=[0.005, 0, 0])
        spec.body(b).add_site(name=SITE.format(k=k, side="b"), pos=at_b, size=[0.005, 0, 0])
        spec.add_equality(
            name=f"coadapt_loop{k}",
            type=mujoco.mjtEq.mjEQ_CONNECT,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            name1=SITE.format(k=k, side="a"),
            name2=SITE.format(k=k, side="b"),
        )
        # the two bodies pinned together and the links carrying them meet at the pin
        sides = [(a, spec.body(a).parent.name), (b, spec.body(b).parent.name)]
        pairs = {(x, y) for x in sides[0] for y in sides[1] if x != y}
        for first, second in sorted(pairs):
            spec.add_exclude(bodyname1=first, bodyname2=second)
    return spec.compile()


def loop_forces(model: mujoco.MjModel, data: mujoco.MjData, force: np.ndarray) -> np.ndarray:
    """[nv] the generalized force `force` [nv] less what the loops' pins carry: the pin
    forces that leave no torque on a hinge without a motor (least squares), at `data`'s pose
    (kinematics done); `force` itself for a model without loops."""
    sites = [(int(model.eq_obj1id[e]), int(model.eq_obj2id[e])) for e in range(model.neq)]
    if not sites:
        return force
    rows = []
    for sa, sb in sites:
        ja, jb = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, ja, None, sa)
        mujoco.mj_jacSite(model, data, jb, None, sb)
        rows.append(ja - jb)
    jac = np.concatenate(rows)  # [3 K, nv]
    actuated = {int(model.jnt_dofadr[model.actuator_trnid[a, 0]]) for a in range(model.nu)}
    passive = [
        int(model.jnt_dofadr[j])
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
        and int(model.jnt_dofadr[j]) not in actuated
    ]
    pins = np.linalg.lstsq(jac[:, passive].T, force[passive], rcond=None)[0]
    return force - jac.T @ pins
