"""What a PyBullet engine needs to know about one design, as a small picklable record.

The main process builds it from the robot's `RobotModel` (URDF plus actuator facts) and
ships it to worker processes, so workers never import the robot plugin. Joint damping,
armature and friction loss are read from the compiled MJCF — the model MuJoCo simulates —
so both backends see the same joint dynamics even where the URDF cannot say it (armature).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coadapt_core.robot import RobotModel


@dataclass
class EnvSpec:
    """One design as a PyBullet engine loads it; arrays over actuated joints [J]."""

    design: np.ndarray  # [design_dim]
    urdf: str
    base_body: str
    joint_names: list[str]
    foot_bodies: list[str]
    default_joint_pos: np.ndarray  # [J]
    kp: np.ndarray  # [J]
    kd: np.ndarray  # [J]
    torque_limit: np.ndarray  # [J]
    speed_limit: np.ndarray  # [J]
    standing_base_height: float
    foot_radius: float  # m, horizontal reach of a foot's contact points around its origin
    # from the compiled MJCF; None when it does not compile (the URDF's <dynamics> stand)
    joint_damping: np.ndarray | None  # [J] N m s / rad
    joint_armature: np.ndarray | None  # [J] kg m^2
    joint_frictionloss: np.ndarray | None  # [J] N m

    @classmethod
    def from_model(cls, model: RobotModel) -> EnvSpec:
        dynamics = mjcf_joint_dynamics(model.text("mjcf"), model.joint_names)
        damping, armature, frictionloss = dynamics if dynamics is not None else (None, None, None)
        return cls(
            design=np.asarray(model.design, dtype=float).copy(),
            urdf=model.text("urdf"),
            base_body=model.base_body,
            joint_names=list(model.joint_names),
            foot_bodies=list(model.foot_bodies),
            default_joint_pos=np.asarray(model.default_joint_pos, dtype=float),
            kp=np.asarray(model.kp, dtype=float),
            kd=np.asarray(model.kd, dtype=float),
            torque_limit=np.asarray(model.torque_limit, dtype=float),
            speed_limit=np.asarray(model.speed_limit, dtype=float),
            standing_base_height=float(model.standing_base_height),
            foot_radius=_foot_radius(model.foot_contact_points),
            joint_damping=damping,
            joint_armature=armature,
            joint_frictionloss=frictionloss,
        )


def _foot_radius(points: np.ndarray) -> float:
    """The same reach the MuJoCo backend uses to find the ground under a spawning foot."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return float(np.max(np.linalg.norm(pts[:, :2], axis=1))) if len(pts) else 0.15


def mjcf_joint_dynamics(
    mjcf: str, joint_names: list[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(damping, armature, frictionloss) [J] of the named joints in the compiled MJCF.

    Compiling (rather than parsing the XML) resolves MJCF default classes the same way
    MuJoCo does. None when there is no MJCF or it does not compile.
    """
    n = len(joint_names)
    if not mjcf:
        return None
    import mujoco

    try:
        mj = mujoco.MjModel.from_xml_string(mjcf)
    except Exception:
        return None
    damping, armature, frictionloss = (np.zeros(n) for _ in range(3))
    for j, name in enumerate(joint_names):
        jid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            continue
        dof = mj.jnt_dofadr[jid]
        damping[j] = mj.dof_damping[dof]
        armature[j] = mj.dof_armature[dof]
        frictionloss[j] = mj.dof_frictionloss[dof]
    return damping, armature, frictionloss
