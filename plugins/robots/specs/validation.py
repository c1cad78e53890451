"""Validation of any spec robot's design: physical masses and inertias, the standing pose
(joint ranges, every foot on the ground, no self-contact), standing torques within the
motors' peaks, MuJoCo against Pinocchio (mass, centre of mass, foot positions), and the stand
test: joint PD with the spec's gains (torques within the motors' peaks) holds the standing
pose on flat ground for STAND_SECONDS, the base staying above STAND_HEIGHT_SHARE of its
standing height and tilting less than STAND_TILT; at the nominal design it is run at every
corner of the design box too. A robot with three feet or more must pass it; a biped's result
is reported (its policy balances it, not joint PD).

Pinocchio reads the robot's URDF when it writes one, else its MJCF.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.loops import loop_forces

from coadapt_core.robot import Finding, RobotModel, ValidationReport

GRAVITY = 9.81
#: a foot more than this above flat ground at the standing pose is not standing on it, m
FOOT_GROUND_TOL = 0.01
#: robot geoms of bodies that are not parent and child may overlap at most this much, m
SELF_CONTACT_TOL = 1e-3
#: MuJoCo against Pinocchio: m and relative mass
CONSISTENCY_TOL = 1e-6
#: the stand test: seconds held, the physics step (s, the simulators' default), the lowest
#: base height as a share of the standing height, the largest tilt of the base (rad)
STAND_SECONDS = 3.0
STAND_DT = 0.005
STAND_HEIGHT_SHARE = 0.75
STAND_TILT = 0.35


@dataclass(frozen=True)
class Stand:
    """What the stand test saw for one design."""

    design: tuple[float, ...]
    lowest: float  # the base's lowest height over the test, as a share of its standing height
    tilt: float  # the largest angle between the base's z axis and the vertical, rad
    saturated: str  # the joint whose torque sat at its peak the longest ("" if none did)
    saturated_share: float  # the share of the test it sat there

    @property
    def ok(self) -> bool:
        return self.lowest >= STAND_HEIGHT_SHARE and self.tilt <= STAND_TILT

    def text(self) -> str:
        where = ",".join(f"{x:g}" for x in self.design)
        tilt = np.degrees(self.tilt)
        line = f"design ({where}): lowest {self.lowest:.0%} of its height, tilt {tilt:.1f} deg"
        if self.saturated:
            line += f", '{self.saturated}' at its peak {self.saturated_share:.0%} of the time"
        return line


def stand_test(rm: RobotModel, seconds: float = STAND_SECONDS) -> Stand:
    """Joint PD toward the standing pose with `rm`'s gains and peaks, on flat ground, from
    the standing pose at the standing height, for `seconds`."""
    spec = mujoco.MjSpec.from_string(rm.text("mjcf"))
    spec.option.timestep = STAND_DT
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=0, conaffinity=1
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:7] = [0.0, 0.0, rm.standing_base_height, 1.0, 0.0, 0.0, 0.0]
    qadr = np.array([model.jnt_qposadr[model.joint(j).id] for j in rm.joint_names])
    vadr = np.array([model.jnt_dofadr[model.joint(j).id] for j in rm.joint_names])
    act = np.array([model.actuator(j).id for j in rm.joint_names])
    data.qpos[qadr] = rm.default_joint_pos
    target, kp, kd, peak = (np.asarray(a, dtype=float) for a in (
        rm.default_joint_pos, rm.kp, rm.kd, rm.torque_limit))  # fmt: skip
    base = model.body(rm.base_body).id
    height = max(rm.standing_base_height, 1e-6)
    lowest, tilt = np.inf, 0.0
    at_peak = np.zeros(len(rm.joint_names))
    steps = int(round(seconds / STAND_DT))
    for _ in range(steps):
        raw = kp * (target - data.qpos[qadr]) - kd * data.qvel[vadr]
        torque = np.clip(raw, -peak, peak)
        at_peak += np.abs(raw) >= peak
        data.ctrl[act] = torque
        mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qpos)):
            lowest, tilt = -np.inf, np.pi
            break
        lowest = min(lowest, float(data.xpos[base, 2]) / height)
        up = float(np.clip(data.xmat[base, 8], -1.0, 1.0))
        tilt = max(tilt, float(np.arccos(up)))
    worst = int(np.argmax(at_peak))
    share = float(at_peak[worst] / steps)
    return Stand(
        tuple(float(x) for x in rm.design),
        float(lowest),
        float(tilt),
        rm.joint_names[worst] if share > 0 else "",
        share,
    )


def stand_finding(stands: list[Stand], required: bool = True) -> Finding:
    """One finding for the stand tests of a design (and the corners); not `required` (a
    biped, balanced by its policy rather than by joint PD), it is reported and passes."""
    failed = [s for s in stands if not s.ok]
    limits = (
        f"limits: base above {STAND_HEIGHT_SHARE:.0%} of its standing height, tilt below "
        f"{np.degrees(STAND_TILT):.0f} deg, {STAND_SECONDS:g} s under joint PD"
    )
    worst_low = min(s.lowest for s in stands)
    worst_tilt = max(s.tilt for s in stands)
    what = "the design" if len(stands) == 1 else f"the nominal design and {len(stands) - 1} corners"
    if failed:
        message = f"falls: {failed[0].text()} ({limits})"
    else:
        message = (
            f"{what} stand{'s' if len(stands) == 1 else ''}: lowest {worst_low:.0%} of the "
            f"standing height, tilt {np.degrees(worst_tilt):.1f} deg ({limits})"
        )
    if failed and not required:
        message = "reported, not required (a biped is balanced by its policy): " + message
    return Finding(
        "stand.hold", not failed or not required, message, float(worst_low), STAND_HEIGHT_SHARE
    )


def _standing_data(rm: RobotModel) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(rm.text("mjcf"))
    data = mujoco.MjData(model)
    data.qpos[:7] = [0.0, 0.0, rm.standing_base_height, 1.0, 0.0, 0.0, 0.0]
    for name, angle in zip(rm.joint_names, rm.default_joint_pos, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    mujoco.mj_forward(model, data)
    return model, data


def _inertias(model: mujoco.MjModel) -> list[Finding]:
    worst, where = 0.0, ""
    bad = []
    for b in range(1, model.nbody):
        i = np.sort(model.body_inertia[b])
        if model.body_mass[b] <= 0 or i[0] <= 0:
            bad.append(model.body(b).name)
        slack = (i[0] + i[1] - i[2]) / max(i[2], 1e-12)
        if slack < worst:
            worst, where = slack, model.body(b).name
    return [
        Finding(
            "mass.positive",
            not bad,
            "every body has a positive mass and inertia"
            if not bad
            else f"non-positive mass or inertia: {', '.join(bad)}",
        ),
        Finding(
            "mass.triangle_inequality",
            worst >= -1e-9,
            "every body's principal moments satisfy I1 + I2 >= I3"
            if worst >= -1e-9
            else f"body '{where}' breaks I1 + I2 >= I3 by {-worst:.2%} of I3",
            float(worst),
            0.0,
        ),
    ]


def _pose(rm: RobotModel, model: mujoco.MjModel, data: mujoco.MjData) -> list[Finding]:
    inside = bool(
        np.all(rm.default_joint_pos >= rm.joint_lower - 1e-12)
        and np.all(rm.default_joint_pos <= rm.joint_upper + 1e-12)
    )
    from coadapt_plugins.robots.specs.build import lowest_points

    frames = (data.geom_xpos, data.geom_xmat.reshape(-1, 3, 3))
    lows = [
        float(lowest_points(model, model.body(foot).id, *frames)[:, 2].min())
        for foot in rm.foot_bodies
    ]
    highest = max(lows)
    return [
        Finding(
            "pose.joint_ranges",
            inside,
            "the standing pose is inside every joint's range"
            if inside
            else "the standing pose leaves a joint's range",
        ),
        Finding(
            "pose.feet_on_ground",
            highest <= FOOT_GROUND_TOL,
            f"highest foot {highest * 1000:.1f} mm above the ground at the standing height "
            f"(limit {FOOT_GROUND_TOL * 1000:.0f} mm)",
            float(highest),
            FOOT_GROUND_TOL,
        ),
    ]


def _self_contact(rm: RobotModel) -> Finding:
    """Contacts between the robot's own collision geoms at the standing pose (parent and
    child bodies excluded, as MuJoCo does)."""
    spec = mujoco.MjSpec.from_string(rm.text("mjcf"))
    for geom in spec.geoms:
        if geom.contype or geom.conaffinity:
            geom.contype, geom.conaffinity = 1, 1
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:7] = [0.0, 0.0, rm.standing_base_height, 1.0, 0.0, 0.0, 0.0]
    for name, angle in zip(rm.joint_names, rm.default_joint_pos, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    mujoco.mj_forward(model, data)
    deepest, pair = 0.0, ""
    for c in data.contact[: data.ncon]:
        if -c.dist > deepest:
            b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
            deepest, pair = -float(c.dist), f"{model.body(b1).name} / {model.body(b2).name}"
    ok = deepest <= SELF_CONTACT_TOL
    return Finding(
        "pose.self_contact",
        ok,
        "no self-contact at the standing pose"
        if ok
        else f"{pair} overlap by {deepest * 1000:.1f} mm at the standing pose",
        deepest,
        SELF_CONTACT_TOL,
    )


def _statics(rm: RobotModel, model: mujoco.MjModel, data: mujoco.MjData) -> Finding:
    """Joint torques holding the standing pose with the weight shared equally by the feet:
    gravity on every body (`qfrc_bias` at rest) less each foot's reaction through its
    Jacobian (and, with `loops`, the pins' forces that leave the passive hinges free); the
    largest share of a motor's peak torque."""
    support = np.array([0.0, 0.0, rm.total_mass * GRAVITY / len(rm.foot_bodies)])
    torque = data.qfrc_bias.copy()
    jac = np.zeros((3, model.nv))
    for foot in rm.foot_bodies:
        mujoco.mj_jacBody(model, data, jac, None, model.body(foot).id)
        torque -= jac.T @ support
    torque = loop_forces(model, data, torque)  # a four-bar's pins carry their share
    dofs = [model.jnt_dofadr[model.joint(j).id] for j in rm.joint_names]
    share = np.abs(torque[dofs]) / rm.torque_limit
    worst = int(np.argmax(share))
    ok = bool(share[worst] <= 1.0)
    return Finding(
        "statics.standing_torque",
        ok,
        f"largest standing torque {share[worst]:.0%} of the peak at '{rm.joint_names[worst]}'",
        float(share[worst]),
        1.0,
    )


def _coordinate(pin, pmodel, model: mujoco.MjModel, name: str) -> int:
    """The index in Pinocchio's configuration of MuJoCo's hinge `name`. Pinocchio merges the
    hinges of one MJCF body into one composite joint (nq > 1, named after none of them but
    the first): its coordinates follow the body's hinges in MuJoCo's order."""
    j = pmodel.getJointId(name)
    if j < pmodel.njoints and pmodel.joints[j].nq == 1:
        return int(pmodel.joints[j].idx_q)
    jid = model.joint(name).id
    body = int(model.jnt_bodyid[jid])
    hinges = [h for h in range(model.njnt) if model.jnt_bodyid[h] == body]
    frame = pmodel.frames[pmodel.getFrameId(model.body(body).name)]
    joint = pmodel.joints[frame.parentJoint]
    if joint.nq != len(hinges):
        raise ValueError(
            f"Pinocchio's joint of body '{model.body(body).name}' has {joint.nq} coordinates, "
            f"MuJoCo's {len(hinges)} hinges"
        )
    return int(joint.idx_q) + hinges.index(jid)


def _pinocchio(rm: RobotModel, model: mujoco.MjModel, data: mujoco.MjData) -> list[Finding]:
    import pinocchio as pin

    if "urdf" in rm.formats:
        # kinematics and inertials only: urdfdom does not parse a capsule (PyBullet does)
        text = re.sub(r"<(visual|collision)>.*?</\1>", "", rm.text("urdf"), flags=re.S)
        pmodel = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
        source = "URDF"
    else:
        import os
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "robot.xml")
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(rm.text("mjcf"))
            pmodel = pin.buildModelFromMJCF(path)
        source = "MJCF"
    pdata = pmodel.createData()
    q = pin.neutral(pmodel)
    q[:3] = [0.0, 0.0, rm.standing_base_height]
    try:
        for name, angle in zip(rm.joint_names, rm.default_joint_pos, strict=True):
            q[_coordinate(pin, pmodel, model, name)] = angle
    except ValueError as exc:
        return [Finding("consistency.pinocchio", False, f"Pinocchio ({source}): {exc}")]
    pin.forwardKinematics(pmodel, pdata, q)
    pin.updateFramePlacements(pmodel, pdata)
    mass = float(sum(pmodel.inertias[i].mass for i in range(pmodel.njoints)))
    com = pin.centerOfMass(pmodel, pdata, q)
    extra = ""
    if source == "URDF":  # leave out the tiny intermediate links the URDF adds for Bullet
        from coadapt_plugins.robots.specs.urdf import TINY_MASS, intermediate_links

        tiny = intermediate_links(rm.text("urdf"))
        if tiny:
            where = sum(pdata.oMf[pmodel.getFrameId(n)].translation for n in tiny)
            com = (mass * com - TINY_MASS * where) / (mass - TINY_MASS * len(tiny))
            mass -= TINY_MASS * len(tiny)
            extra = f" ({len(tiny)} intermediate links of {TINY_MASS:g} kg left out)"
    mj_com = data.subtree_com[model.body(rm.base_body).id]
    feet = max(
        float(
            np.linalg.norm(
                pdata.oMf[pmodel.getFrameId(foot)].translation - data.xpos[model.body(foot).id]
            )
        )
        for foot in rm.foot_bodies
    )
    gap = max(abs(mass - rm.total_mass) / rm.total_mass, float(np.abs(com - mj_com).max()), feet)
    return [
        Finding(
            "consistency.pinocchio",
            gap <= CONSISTENCY_TOL,
            f"Pinocchio ({source}) against MuJoCo: mass, centre of mass and feet agree within "
            f"{gap:.1e}{extra}",
            gap,
            CONSISTENCY_TOL,
        )
    ]


def corners(robot) -> list[np.ndarray]:
    """The corners of a spec robot's continuous design box (motor types nominal)."""
    import itertools

    space = robot.design_space(False)
    lows, highs = space.lower.astype(float), space.upper.astype(float)
    return [
        np.where(np.array(bits, dtype=bool), highs, lows)
        for bits in itertools.product((0, 1), repeat=lows.size)
    ]


def stands_of(robot, rm: RobotModel) -> list[Stand]:
    """The stand test of `rm`'s design, and of every corner when it is the nominal design."""
    stands = [stand_test(rm)]
    nominal = robot.nominal_design(mixed=rm.design.size != len(robot.spec.parameters))
    if np.allclose(rm.design, nominal):
        stands += [stand_test(robot.build(c)) for c in corners(robot)]
    return stands


def validate_spec_model(robot, rm: RobotModel) -> ValidationReport:
    """The findings above for one built design of a spec robot."""
    model, data = _standing_data(rm)
    findings = [
        *_inertias(model),
        *_pose(rm, model, data),
        _self_contact(rm),
        _statics(rm, model, data),
    ]
    findings += _pinocchio(rm, model, data)
    findings.append(stand_finding(stands_of(robot, rm), required=len(rm.foot_bodies) >= 3))
    return ValidationReport(np.array(rm.design, dtype=float), findings)
