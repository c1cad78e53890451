"""Design validation with Pinocchio (from the URDF) and MuJoCo (from the MJCF): link lengths,
mass, the standing pose (joint ranges, ground clearance, centre of mass over the feet),
statics within the motor limits, and agreement of the two descriptions.

Imported only when a design is validated, so Pinocchio loads lazily.
"""

from __future__ import annotations

import numpy as np
from coadapt_plugins.robots.qilin import constants as C

from coadapt_core.errors import CoadaptError
from coadapt_core.robot import Finding, RobotModel, ValidationReport

GRAVITY = 9.81
LENGTH_TOL = 1e-6  # m, link length from forward kinematics against the design's
CONSISTENCY_TOL = 1e-6  # m and relative: Pinocchio against MuJoCo
#: standing may use at most this share of a joint's torque limit (the rest is for walking)
STANDING_TORQUE_SHARE = 0.5
#: the trunk's underside must stand this high above flat ground, m
MIN_CLEARANCE = 0.05
RANDOM_CONFIGURATIONS = 4


def _pinocchio():
    try:
        import pinocchio
    except ImportError as exc:  # pragma: no cover - pin is a core dependency
        raise CoadaptError(f"qilin validation needs Pinocchio (pip install pin): {exc}") from exc
    return pinocchio


def _q(pmodel, model: RobotModel, base_z: float, joints: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration: base at (0, 0, base_z), upright, the actuated joints."""
    q = np.zeros(pmodel.nq)
    q[2], q[6] = base_z, 1.0  # quaternion (x, y, z, w)
    for name, value in zip(model.joint_names, joints, strict=True):
        q[pmodel.joints[pmodel.getJointId(name)].idx_q] = value
    return q


def _lengths(pin, pmodel, pdata, model: RobotModel) -> list[Finding]:
    """Hip pitch to knee and knee to foot centre, by forward kinematics at the zero pose."""
    pin.framesForwardKinematics(pmodel, pdata, _q(pmodel, model, 0.0, np.zeros(model.num_joints)))
    findings = []
    for key, a, b, want in (
        ("thigh_length", "hip", "knee", model.info["thigh_length"]),
        ("calf_length", "knee", "foot", model.info["calf_length"]),
    ):
        worst = 0.0
        for leg in C.LEGS:
            ends = [
                pdata.oMi[pmodel.getJointId(f"{leg}_{a}")].translation if a != "foot" else None,
                pdata.oMi[pmodel.getJointId(f"{leg}_{b}")].translation
                if b != "foot"
                else pdata.oMf[pmodel.getFrameId(f"{leg}_foot")].translation,
            ]
            worst = max(worst, abs(float(np.linalg.norm(ends[1] - ends[0])) - want))
        findings.append(
            Finding(
                f"kinematics.{key}",
                worst <= LENGTH_TOL,
                f"largest deviation from {want:.4f} m: {worst:.2e} m",
                worst,
                LENGTH_TOL,
            )
        )
    return findings


def _standing(pin, pmodel, pdata, model: RobotModel) -> list[Finding]:
    """The default pose on flat ground: in the joint ranges, the trunk clear of the ground,
    the centre of mass over the feet, and the joint torques holding it (an equal share of
    the weight on each foot) within `STANDING_TORQUE_SHARE` of the motors' limits."""
    q = _q(pmodel, model, model.standing_base_height, model.default_joint_pos)
    inside = bool(
        np.all(model.default_joint_pos >= model.joint_lower)
        and np.all(model.default_joint_pos <= model.joint_upper)
    )
    clearance = model.standing_base_height - 0.5 * C.TRUNK_SIZE[2]
    pin.framesForwardKinematics(pmodel, pdata, q)
    feet = np.array(
        [pdata.oMf[pmodel.getFrameId(f)].translation for f in model.foot_bodies]
    )  # [4, 3]
    com = pin.centerOfMass(pmodel, pdata, q)
    margin = float(
        min(
            com[0] - feet[:, 0].min(),
            feet[:, 0].max() - com[0],
            com[1] - feet[:, 1].min(),
            feet[:, 1].max() - com[1],
        )
    )
    # joint torques: gravity's, less what the ground's push on each foot takes
    gravity = pin.computeGeneralizedGravity(pmodel, pdata, q)
    pin.computeJointJacobians(pmodel, pdata, q)
    push = np.array([0.0, 0.0, model.total_mass * GRAVITY / len(model.foot_bodies)])
    for foot in model.foot_bodies:
        jac = pin.getFrameJacobian(
            pmodel, pdata, pmodel.getFrameId(foot), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        gravity = gravity - jac[:3].T @ push
    v_idx = [pmodel.joints[pmodel.getJointId(n)].idx_v for n in model.joint_names]
    share = float(np.max(np.abs(gravity[v_idx]) / model.torque_limit))
    return [
        Finding(
            "pose.default_in_range",
            inside,
            "default joint angles inside the joint ranges"
            if inside
            else "a default joint angle leaves its range",
        ),
        Finding(
            "pose.trunk_clearance",
            clearance >= MIN_CLEARANCE,
            f"trunk underside {clearance:.3f} m above ground (>= {MIN_CLEARANCE} m)",
            float(clearance),
            MIN_CLEARANCE,
        ),
        Finding(
            "statics.com_over_feet",
            margin > 0,
            f"centre of mass {margin:.3f} m inside the feet's rectangle",
            margin,
            0.0,
        ),
        Finding(
            "statics.standing_torque",
            share <= STANDING_TORQUE_SHARE,
            f"standing needs {share:.2f} of a joint's "
            f"torque limit at most (<= {STANDING_TORQUE_SHARE})",
            share,
            STANDING_TORQUE_SHARE,
        ),
    ]


def _mujoco_agrees(pin, pmodel, pdata, model: RobotModel) -> list[Finding]:
    """The MJCF and the URDF describe one robot: total mass, and feet and centre of mass at
    the default pose and at random joint angles."""
    import mujoco

    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    md = mujoco.MjData(mj)
    qadr = [
        mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)]
        for n in model.joint_names
    ]
    feet = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, f) for f in model.foot_bodies]
    rng = np.random.default_rng(0)
    poses = [model.default_joint_pos] + [
        rng.uniform(model.joint_lower, model.joint_upper) for _ in range(RANDOM_CONFIGURATIONS)
    ]
    worst = 0.0
    for joints in poses:
        md.qpos[:] = 0.0
        md.qpos[3] = 1.0
        md.qpos[qadr] = joints
        mujoco.mj_kinematics(mj, md)
        mujoco.mj_comPos(mj, md)
        q = _q(pmodel, model, 0.0, joints)
        pin.framesForwardKinematics(pmodel, pdata, q)
        pin_feet = np.array(
            [pdata.oMf[pmodel.getFrameId(f)].translation for f in model.foot_bodies]
        )
        worst = max(
            worst,
            float(np.abs(pin_feet - md.xpos[feet]).max()),
            float(np.abs(pin.centerOfMass(pmodel, pdata, q) - md.subtree_com[1]).max()),
        )
    masses = [float(sum(i.mass for i in pmodel.inertias)), float(mj.body_mass.sum())]
    mass_error = max(abs(m - model.total_mass) for m in masses) / model.total_mass
    return [
        Finding(
            "mass.total",
            mass_error <= CONSISTENCY_TOL,
            f"Pinocchio {masses[0]:.4f} kg, MuJoCo {masses[1]:.4f} kg, "
            f"model {model.total_mass:.4f} kg",
            mass_error,
            CONSISTENCY_TOL,
        ),
        Finding(
            "consistency.feet_and_com",
            worst <= CONSISTENCY_TOL,
            f"feet and centre of mass agree to {worst:.1e} m over {len(poses)} poses",
            worst,
            CONSISTENCY_TOL,
        ),
    ]


def validate_model(model: RobotModel) -> ValidationReport:
    pin = _pinocchio()
    pmodel = pin.buildModelFromXML(model.text("urdf"), pin.JointModelFreeFlyer())
    pdata = pmodel.createData()
    findings = [
        *_lengths(pin, pmodel, pdata, model),
        *_standing(pin, pmodel, pdata, model),
        *_mujoco_agrees(pin, pmodel, pdata, model),
    ]
    return ValidationReport(design=np.asarray(model.design, dtype=float).copy(), findings=findings)
