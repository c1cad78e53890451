"""Design validation with Pinocchio (from the URDF) and MuJoCo (from the MJCF): kinematics,
mass properties, statics within the motor limits, and agreement of the two descriptions.

Imported only when a design is validated, so Pinocchio loads lazily.
"""

from __future__ import annotations

import numpy as np
from coadapt_plugins.robots.kuafu import constants as C

from coadapt_core.errors import CoadaptError
from coadapt_core.robot import Finding, RobotModel, ValidationReport

GRAVITY = 9.81
LENGTH_TOL = 1e-3  # m, link length from forward kinematics vs 0.35 xi
CONSISTENCY_REL_TOL = 1e-6  # mass, mass matrix (relative)
CONSISTENCY_POS_TOL = 1e-6  # m, CoM and foot positions
RANDOM_CONFIGURATIONS = 5


def _largest_gain_factor() -> float:
    """Largest PD factor x motor strength the default domain randomization (Table 2) draws."""
    from coadapt_core.physics.randomization import RandomizationConfig

    config = RandomizationConfig()
    return float(config.pd_factor[1] * config.motor_strength[1])


def _pinocchio():
    try:
        import pinocchio
    except ImportError as exc:  # pragma: no cover - pin is a core dependency
        raise CoadaptError(f"kuafu validation needs Pinocchio (pip install pin): {exc}") from exc
    return pinocchio


def pinocchio_model(model: RobotModel):
    """The Pinocchio model of the URDF with a free-flyer root and the joints' armature
    (reflected rotor inertia, which URDF cannot carry) set from the model's info."""
    pin = _pinocchio()
    pmodel = pin.buildModelFromXML(model.text("urdf"), pin.JointModelFreeFlyer())
    armature = np.array(pmodel.armature)
    for name, value in zip(model.joint_names, model.info["armature"], strict=True):
        armature[pmodel.joints[pmodel.getJointId(name)].idx_v] = value
    pmodel.armature = armature
    return pmodel


class _Indexer:
    """Maps actuated-joint arrays [8] into Pinocchio q / v vectors."""

    def __init__(self, pmodel, names: list[str]):
        joints = [pmodel.joints[pmodel.getJointId(n)] for n in names]
        self.q_idx = np.array([j.idx_q for j in joints])
        self.v_idx = np.array([j.idx_v for j in joints])
        self.nq, self.nv = pmodel.nq, pmodel.nv

    def q(self, base_pos: np.ndarray, base_quat_wxyz: np.ndarray, joints: np.ndarray) -> np.ndarray:
        q = np.zeros(self.nq)
        q[:3] = base_pos
        w, x, y, z = base_quat_wxyz
        q[3:7] = [x, y, z, w]  # Pinocchio stores (x, y, z, w)
        q[self.q_idx] = joints
        return q


def _standing_q(model: RobotModel, ix: _Indexer) -> np.ndarray:
    return ix.q(
        np.array([0.0, 0.0, model.standing_base_height]),
        np.array([1.0, 0.0, 0.0, 0.0]),
        model.default_joint_pos,
    )


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull of 2-D points [k, 2] (monotone chain)."""
    pts = sorted(map(tuple, points))

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _signed_margin(hull: np.ndarray, point: np.ndarray) -> float:
    """Distance from `point` to the hull's boundary, positive inside."""
    margins = []
    for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True):
        edge = b - a
        normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)  # outward for CCW
        margins.append(-float(normal @ (point - a)))
    return min(margins)


def _sole_points_world(pin, pmodel, pdata, model: RobotModel) -> dict[str, np.ndarray]:
    """{foot body: [4, 3] sole corners in the world} at the configuration last computed."""
    out = {}
    for foot in model.foot_bodies:
        placement = pdata.oMf[pmodel.getFrameId(foot)]
        out[foot] = (placement.rotation @ model.foot_contact_points.T).T + placement.translation
    return out


def _kinematics(pin, pmodel, pdata, model: RobotModel, q: np.ndarray) -> list[Finding]:
    pin.forwardKinematics(pmodel, pdata, q)
    pin.updateFramePlacements(pmodel, pdata)
    findings = []
    for link, (proximal, distal), expected in (
        ("thigh", ("hip_pitch", "knee"), model.info["thigh_length"]),
        ("shank", ("knee", "ankle"), model.info["shank_length"]),
    ):
        errors = []
        for side in C.SIDES:
            a = pdata.oMi[pmodel.getJointId(f"{side}_{proximal}")].translation
            b = pdata.oMi[pmodel.getJointId(f"{side}_{distal}")].translation
            errors.append(float(np.linalg.norm(b - a)) - expected)
        worst = max(errors, key=abs)
        findings.append(
            Finding(
                f"kinematics.{link}_length",
                abs(worst) <= LENGTH_TOL,
                f"{link} {expected + worst:.4f} m from Pinocchio forward kinematics vs 0.35 x "
                f"scale = {expected:.4f} m (tolerance 1 mm)",
                value=expected + worst,
                limit=expected,
            )
        )
    inside = (model.joint_lower < model.default_joint_pos) & (
        model.default_joint_pos < model.joint_upper
    )
    bad = [n for n, ok in zip(model.joint_names, inside, strict=True) if not ok]
    findings.append(
        Finding(
            "kinematics.joint_limits",
            not bad,
            "lower < default < upper for all 8 joints"
            if not bad
            else f"default pose outside the limits of {', '.join(bad)}",
        )
    )
    base_z = float(q[2])
    feet_z = [float(pdata.oMf[pmodel.getFrameId(f)].translation[2]) for f in model.foot_bodies]
    below = max(feet_z) - base_z
    findings.append(
        Finding(
            "kinematics.feet_below_pelvis",
            below < 0,
            f"highest foot {-below:.3f} m below the pelvis at the default pose",
            value=-below,
            limit=0.0,
        )
    )
    return findings


def _mass(pin, pmodel, pdata, model: RobotModel, q: np.ndarray) -> list[Finding]:
    total = float(pin.computeTotalMass(pmodel))
    com = pin.centerOfMass(pmodel, pdata, q)
    pin.updateFramePlacements(pmodel, pdata)
    soles = _sole_points_world(pin, pmodel, pdata, model)
    hull = _convex_hull(np.concatenate([s[:, :2] for s in soles.values()]))
    margin = _signed_margin(hull, com[:2])
    return [
        Finding(
            "mass.total",
            abs(total - model.total_mass) <= CONSISTENCY_REL_TOL * model.total_mass,
            f"{total:.3f} kg (Pinocchio) vs {model.total_mass:.3f} kg (generator); nominal design "
            f"{C.NOMINAL_MASS:.1f} kg",
            value=total,
            limit=model.total_mass,
        ),
        Finding(
            "mass.com_over_support",
            margin > 0,
            f"CoM {'inside' if margin > 0 else 'outside'} the support polygon of both soles by "
            f"{abs(margin) * 100:.1f} cm",
            value=margin,
            limit=0.0,
        ),
    ]


def _stance_torques(
    pin, pmodel, pdata, model: RobotModel, ix: _Indexer, q: np.ndarray, loads: dict[str, float]
) -> np.ndarray:
    """[8] joint torques holding the default pose statically with `loads` {foot: fraction
    of the weight}: tau = g(q) - sum_c J_c^T f_c, each foot's share a vertical force at its
    centre of pressure, the sole point closest to below the CoM."""
    zero = np.zeros(pmodel.nv)
    tau = pin.rnea(pmodel, pdata, q, zero, zero).copy()  # gravity torques g(q)
    com = pin.centerOfMass(pmodel, pdata, q)
    pin.computeJointJacobians(pmodel, pdata, q)
    pin.updateFramePlacements(pmodel, pdata)
    weight = float(pin.computeTotalMass(pmodel)) * GRAVITY
    soles = _sole_points_world(pin, pmodel, pdata, model)
    for foot, share in loads.items():
        corners = soles[foot]
        lo, hi = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)  # soles are flat here
        cop = np.array([*np.clip(com[:2], lo, hi), corners[:, 2].mean()])
        frame = pmodel.getFrameId(foot)
        placement = pdata.oMf[frame]
        jac = pin.getFrameJacobian(
            pmodel, pdata, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )  # [6, nv] at the frame origin
        # linear velocity of the CoP point: v_origin + w x r
        r = cop - placement.translation
        skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
        jac_point = jac[:3] - skew @ jac[3:]
        tau -= jac_point.T @ np.array([0.0, 0.0, share * weight])
    return tau[ix.v_idx]


def _statics(pin, pmodel, pdata, model: RobotModel, ix: _Indexer, q: np.ndarray) -> list[Finding]:
    left, right = model.foot_bodies
    findings = []
    for check, loads in (
        ("statics.double_support", {left: 0.5, right: 0.5}),
        ("statics.single_support", {left: 1.0}),
    ):
        tau = _stance_torques(pin, pmodel, pdata, model, ix, q, loads)
        ratio = np.abs(tau) / model.torque_limit
        worst = int(np.argmax(ratio))
        name = model.joint_names[worst]
        findings.append(
            Finding(
                check,
                bool(ratio[worst] <= 1.0),
                f"largest gravity torque {abs(tau[worst]):.1f} N m at {name} vs limit "
                f"{model.torque_limit[worst]:.1f} N m ({100 * ratio[worst]:.0f} %)",
                value=float(abs(tau[worst])),
                limit=float(model.torque_limit[worst]),
            )
        )
    return findings


def _pd_stability(
    pin, pmodel, pdata, model: RobotModel, ix: _Indexer, q: np.ndarray
) -> list[Finding]:
    """The PD law is explicit in the physics step (torques written to ctrl), so a light
    chain with stiff gains can ring or diverge. Per joint, with the base held (a swinging
    leg) and I = 1 / (M^-1)_jj its effective inertia (armature included), the discrete
    semi-implicit Euler loop is stable when a = dt f kd / I < 2 and 2 a + dt^2 f kp / I < 4,
    f the largest randomized PD factor x motor strength. Value: worst (2a + b) / 4."""
    legs = pin.crba(pmodel, pdata, q)
    legs = np.triu(legs) + np.triu(legs, 1).T
    legs = legs[np.ix_(ix.v_idx, ix.v_idx)]
    effective = 1.0 / np.diag(np.linalg.inv(legs))  # [8]
    factor = _largest_gain_factor()
    dt = C.TIMESTEP
    a = dt * factor * model.kd / effective
    b = dt * dt * factor * model.kp / effective
    index = (2.0 * a + b) / 4.0
    worst = int(np.argmax(index))
    ok = bool(index[worst] < 1.0 and np.all(a < 2.0))
    return [
        Finding(
            "control.pd_stability",
            ok,
            f"explicit PD at dt {dt * 1000:g} ms, gains x{factor:.2f}: "
            f"worst {model.joint_names[worst]} at {100 * index[worst]:.0f} % of the stability "
            f"bound (effective inertia {effective[worst]:.4f} kg m^2)",
            value=float(index[worst]),
            limit=1.0,
        )
    ]


def _random_configurations(
    model: RobotModel, count: int, seed: int = 0
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        joints = rng.uniform(model.joint_lower, model.joint_upper)
        out.append((rng.uniform(-1.0, 1.0, size=3), quat, joints))
    return out


def _quat_to_matrix(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def consistency(
    model: RobotModel, pmodel=None, count: int = RANDOM_CONFIGURATIONS, seed: int = 0
) -> dict[str, float]:
    """Worst disagreement between MuJoCo (MJCF) and Pinocchio (URDF) over `count` random
    configurations: total mass (relative), CoM and foot positions (m), joint-space mass
    matrix (max abs difference / max abs entry). MuJoCo's free joint takes the linear
    velocity in the world frame, Pinocchio's in the base frame, so M_mujoco = T^T M_pin T
    with T = diag(R^T, I, I)."""
    import mujoco

    pin = _pinocchio()
    pmodel = pmodel if pmodel is not None else pinocchio_model(model)
    pdata = pmodel.createData()
    ix = _Indexer(pmodel, model.joint_names)
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    md = mujoco.MjData(mj)
    qadr = np.array(
        [
            mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)]
            for n in model.joint_names
        ]
    )
    vadr = np.array(
        [
            mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)]
            for n in model.joint_names
        ]
    )
    base_id = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, model.base_body)
    foot_ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, f) for f in model.foot_bodies]
    worst = {
        "mass": abs(float(mj.body_subtreemass[0]) - float(pin.computeTotalMass(pmodel)))
        / float(mj.body_subtreemass[0]),
        "com": 0.0,
        "feet": 0.0,
        "mass_matrix": 0.0,
    }
    full = np.zeros((mj.nv, mj.nv))
    for base_pos, quat, joints in _random_configurations(model, count, seed):
        md.qpos[:3], md.qpos[3:7], md.qpos[qadr] = base_pos, quat, joints
        mujoco.mj_forward(mj, md)
        q = ix.q(base_pos, quat, joints)
        com = pin.centerOfMass(pmodel, pdata, q)
        pin.framesForwardKinematics(pmodel, pdata, q)
        worst["com"] = max(worst["com"], float(np.abs(md.subtree_com[base_id] - com).max()))
        for foot, fid in zip(model.foot_bodies, foot_ids, strict=True):
            diff = md.xpos[fid] - pdata.oMf[pmodel.getFrameId(foot)].translation
            worst["feet"] = max(worst["feet"], float(np.abs(diff).max()))
        mujoco.mj_fullM(mj, md, full)
        m_pin = pin.crba(pmodel, pdata, q)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T  # crba fills the upper triangle
        # reorder Pinocchio's velocity vector to MuJoCo's: base 6, then the joints by name
        order = np.concatenate([np.arange(6), ix.v_idx])
        m_pin = m_pin[np.ix_(order, order)]
        t = np.eye(mj.nv)
        t[:3, :3] = _quat_to_matrix(quat).T
        m_expected = t.T @ m_pin @ t
        mj_order = np.concatenate([np.arange(6), vadr])
        m_mj = full[np.ix_(mj_order, mj_order)]
        worst["mass_matrix"] = max(
            worst["mass_matrix"], float(np.abs(m_mj - m_expected).max() / np.abs(m_mj).max())
        )
    return worst


def _consistency_findings(model: RobotModel, pmodel) -> list[Finding]:
    worst = consistency(model, pmodel)
    return [
        Finding(
            "consistency.total_mass",
            worst["mass"] <= CONSISTENCY_REL_TOL,
            f"MuJoCo vs Pinocchio total mass differ by {worst['mass']:.1e} (relative; tolerance "
            "1e-6)",
            value=worst["mass"],
            limit=CONSISTENCY_REL_TOL,
        ),
        Finding(
            "consistency.com",
            worst["com"] <= CONSISTENCY_POS_TOL,
            f"CoM differs by at most {worst['com']:.1e} m over {RANDOM_CONFIGURATIONS} random "
            "configurations (tolerance 1e-6 m)",
            value=worst["com"],
            limit=CONSISTENCY_POS_TOL,
        ),
        Finding(
            "consistency.foot_positions",
            worst["feet"] <= CONSISTENCY_POS_TOL,
            f"foot positions differ by at most {worst['feet']:.1e} m over {RANDOM_CONFIGURATIONS} "
            "random configurations (tolerance 1e-6 m)",
            value=worst["feet"],
            limit=CONSISTENCY_POS_TOL,
        ),
        Finding(
            "consistency.mass_matrix",
            worst["mass_matrix"] <= CONSISTENCY_REL_TOL,
            f"joint-space mass matrices differ by at most {worst['mass_matrix']:.1e} (relative to "
            "the largest entry; tolerance 1e-6)",
            value=worst["mass_matrix"],
            limit=CONSISTENCY_REL_TOL,
        ),
    ]


def validate_model(model: RobotModel) -> ValidationReport:
    """All checks on one built model; see the README for what each one measures."""
    pin = _pinocchio()
    pmodel = pinocchio_model(model)
    pdata = pmodel.createData()
    ix = _Indexer(pmodel, model.joint_names)
    q = _standing_q(model, ix)
    findings = _kinematics(pin, pmodel, pdata, model, q)
    findings += _mass(pin, pmodel, pdata, model, q)
    findings += _statics(pin, pmodel, pdata, model, ix, q)
    findings += _pd_stability(pin, pmodel, pdata, model, ix, q)
    findings += _consistency_findings(model, pmodel)
    return ValidationReport(design=np.array(model.design, dtype=float), findings=findings)
