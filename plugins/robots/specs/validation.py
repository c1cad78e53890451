"""Validation of any spec robot's design: physical masses and inertias, the standing pose
(joint ranges, every foot on the ground, no self-contact), standing torques within the
motors' peaks, and MuJoCo against Pinocchio (mass, centre of mass, foot positions).

Pinocchio reads the robot's URDF when it writes one, else its MJCF.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

from coadapt_core.robot import Finding, RobotModel, ValidationReport

GRAVITY = 9.81
#: a foot more than this above flat ground at the standing pose is not standing on it, m
FOOT_GROUND_TOL = 0.01
#: robot geoms of bodies that are not parent and child may overlap at most this much, m
SELF_CONTACT_TOL = 1e-3
#: MuJoCo against Pinocchio: m and relative mass
CONSISTENCY_TOL = 1e-6


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
    Jacobian; the largest share of a motor's peak torque."""
    support = np.array([0.0, 0.0, rm.total_mass * GRAVITY / len(rm.foot_bodies)])
    torque = data.qfrc_bias.copy()
    jac = np.zeros((3, model.nv))
    for foot in rm.foot_bodies:
        mujoco.mj_jacBody(model, data, jac, None, model.body(foot).id)
        torque -= jac.T @ support
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
    return ValidationReport(np.array(rm.design, dtype=float), findings)
