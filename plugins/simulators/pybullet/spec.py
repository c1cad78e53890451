"""What a PyBullet engine needs to know about one design, as a small picklable record.

The main process builds it from the robot's `RobotModel` (URDF plus actuator facts) and
ships it to worker processes, so workers never import the robot plugin. Joint damping,
armature and friction loss are read from the compiled MJCF — the model MuJoCo simulates —
so both backends see the same joint dynamics even where the URDF cannot say it (armature).
"""

from __future__ import annotations

from dataclasses import dataclass, field

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
    # [J] kg m^2, the inertia each joint turns at the standing pose (its subtree about its
    # axis: the joint's diagonal of MuJoCo's mass matrix less its armature)
    joint_inertia: np.ndarray | None = None
    # MuJoCo's integrator takes the joints' damping implicitly (Euler, unless its eulerdamp
    # flag is off, implicit, implicitfast; not RK4): its velocity update then solves with
    # M + h D, h the time step, as if each joint carried h times its damping as armature
    implicit_damping: bool = False
    # file name -> text of the files the URDF names (a collision mesh's OBJ): the model's
    # "urdf:<file>" formats, written beside the URDF before it loads
    urdf_files: dict[str, str] = field(default_factory=dict)
    # (link A, point in A, link B, point in B) per closed loop of the MJCF (`loops`)
    loops: list = field(default_factory=list)

    @classmethod
    def from_model(cls, model: RobotModel) -> EnvSpec:
        dynamics = compiled_dynamics(
            model.text("mjcf"), model.joint_names, np.asarray(model.default_joint_pos, dtype=float)
        )
        damping, armature, frictionloss, inertia, implicit = (
            dynamics if dynamics is not None else (None, None, None, None, False)
        )
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
            joint_inertia=inertia,
            implicit_damping=implicit,
            urdf_files={
                k.split(":", 1)[1]: v for k, v in model.formats.items() if k.startswith("urdf:")
            },
            loops=_loops(model.text("mjcf")),
        )


def _loops(mjcf: str) -> list:
    """The closed loops of the robot's MJCF (`loops.mjcf_loops`); none without a connect."""
    if "<connect" not in mjcf:
        return []
    import mujoco
    from coadapt_plugins.simulators.pybullet.loops import mjcf_loops

    return mjcf_loops(mujoco.MjModel.from_xml_string(mjcf))


def _foot_radius(points: np.ndarray) -> float:
    """The same reach the MuJoCo backend uses to find the ground under a spawning foot."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return float(np.max(np.linalg.norm(pts[:, :2], axis=1))) if len(pts) else 0.15


def mjcf_joint_dynamics(
    mjcf: str, joint_names: list[str], pose: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(damping, armature, frictionloss, turned inertia) [J] of the named joints in the
    compiled MJCF; the turned inertia is the joint's diagonal entry of the joint-space mass
    matrix less its armature, with the joints at `pose` [J] (default: the model's zero).

    Compiling (rather than parsing the XML) resolves MJCF default classes the same way
    MuJoCo does. None when there is no MJCF or it does not compile.
    """
    dynamics = compiled_dynamics(mjcf, joint_names, pose)
    return None if dynamics is None else dynamics[:4]


def compiled_dynamics(
    mjcf: str, joint_names: list[str], pose: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool] | None:
    """`mjcf_joint_dynamics` and whether MuJoCo integrates the joints' damping implicitly
    (`damps_implicitly`), from one compile."""
    n = len(joint_names)
    if not mjcf:
        return None
    import mujoco

    try:
        mj = mujoco.MjModel.from_xml_string(mjcf)
    except Exception:
        return None
    damping, armature, frictionloss, inertia = (np.zeros(n) for _ in range(4))
    data = mujoco.MjData(mj)
    dofs = np.full(n, -1)
    for j, name in enumerate(joint_names):
        jid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            continue
        dofs[j] = dof = mj.jnt_dofadr[jid]
        damping[j] = mj.dof_damping[dof]
        armature[j] = mj.dof_armature[dof]
        frictionloss[j] = mj.dof_frictionloss[dof]
        if pose is not None:
            data.qpos[mj.jnt_qposadr[jid]] = pose[j]
    mujoco.mj_forward(mj, data)
    full = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, full)
    found = dofs >= 0
    inertia[found] = full[dofs[found], dofs[found]] - armature[found]
    return damping, armature, frictionloss, inertia, damps_implicitly(mj)


def damps_implicitly(mj) -> bool:
    """Whether MuJoCo's integrator takes joint damping into its velocity update implicitly,
    solving (M + h D) dv = h f: Euler (unless the model disables `eulerdamp`), implicit and
    implicitfast do; RK4 does not."""
    import mujoco

    integrator = mujoco.mjtIntegrator(mj.opt.integrator)
    if integrator == mujoco.mjtIntegrator.mjINT_EULER:
        return not mj.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    return integrator != mujoco.mjtIntegrator.mjINT_RK4
