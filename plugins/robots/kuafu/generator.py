"""Kuafu model generator: one design -> mass properties of every body, default pose, PD
gains, motor limits, and the MJCF and URDF texts that describe the same robot.

Body tree (frames x forward, y left, z up; each body's origin at its parent joint):

    base (freejoint "root"; pelvis + torso + head, one rigid body)
    ├── {side}_hip_roll_link   joint {side}_hip_roll  (about x) at the hip centre
    │   └── {side}_thigh       joint {side}_hip_pitch (about y) at the same centre
    │       └── {side}_shank   joint {side}_knee      (about y) at (0, 0, -l0)
    │           └── {side}_foot joint {side}_ankle    (about y) at (0, 0, -l1)
    └── {side}_arm             fixed shoulder joint {side}_shoulder (no MJCF joint)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache, lru_cache
from types import MappingProxyType

import numpy as np
from coadapt_plugins.robots.kuafu import constants as C
from coadapt_plugins.robots.kuafu.inertia import (
    Part,
    box,
    combine,
    cylinder,
    inertia_about_axis,
    rotation_y,
    sphere,
)
from coadapt_plugins.robots.kuafu.mass_model import load_mass_models
from coadapt_plugins.robots.kuafu.model_text import Geometry, mjcf_text, urdf_text

from coadapt_core.robot import RobotModel


@dataclass(frozen=True)
class KuafuDesign:
    """A design resolved into physical terms."""

    thigh_scale: float
    shank_scale: float
    hip_motor: int = C.NOMINAL_MOTOR_TYPE
    knee_motor: int = C.NOMINAL_MOTOR_TYPE

    @property
    def thigh_length(self) -> float:  # l0 = 0.35 xi0 (paper 4.1.1)
        return C.NOMINAL_LINK_LENGTH * self.thigh_scale

    @property
    def shank_length(self) -> float:  # l1 = 0.35 xi1
        return C.NOMINAL_LINK_LENGTH * self.shank_scale

    def motor_of(self, joint: str) -> int:
        """Motor type driving a leg joint: the hip type drives hip roll and hip pitch."""
        if joint in ("hip_roll", "hip_pitch"):
            return self.hip_motor
        if joint == "knee":
            return self.knee_motor
        return C.ANKLE_MOTOR_TYPE

    @classmethod
    def from_vector(cls, design: np.ndarray) -> KuafuDesign:
        d = [float(x) for x in design]
        if len(d) == 2:
            return cls(d[0], d[1])
        return cls(d[0], d[1], int(round(d[2])), int(round(d[3])))


# -- parts ---------------------------------------------------------------------------------
def actuator(motor_type: int, centre: np.ndarray, axis: str) -> Part:
    """Actuator unit (motor + gearbox + housing) as a solid cylinder on the joint axis."""
    mass = C.MOTOR_TYPES[motor_type]["motor_mass"] + C.GEARBOX_HOUSING_MASS
    return cylinder(mass, C.ACTUATOR_RADIUS, C.ACTUATOR_LENGTH, centre, axis=axis)


def _hip_centre(side: str) -> np.ndarray:
    return C.HIP_OFFSET * np.array([1.0, C.SIDE_SIGN[side], 1.0])


def _shoulder(side: str) -> np.ndarray:
    return C.SHOULDER_OFFSET * np.array([1.0, C.SIDE_SIGN[side], 1.0])


@cache
def head_top_above_base() -> float:
    """Height of the top of the head above the base origin, chosen so the nominal design
    stands NOMINAL_HEIGHT tall (head top above the soles at the default pose)."""
    return C.NOMINAL_HEIGHT - standing_base_height(KuafuDesign(1.0, 1.0))


def _upper_body_parts(design: KuafuDesign, torso_mass: float) -> list[Part]:
    head_centre = np.array([0.0, 0.0, head_top_above_base() - C.HEAD_RADIUS])
    parts = [
        box(C.PELVIS_MASS, C.PELVIS_SIZE, C.PELVIS_CENTRE),
        box(torso_mass, C.TORSO_SIZE, C.TORSO_CENTRE),
        sphere(C.HEAD_MASS, C.HEAD_RADIUS, head_centre),
    ]
    for side in C.SIDES:
        parts.append(
            actuator(design.hip_motor, _hip_centre(side) + C.HIP_ROLL_ACTUATOR_OFFSET, "x")
        )
    return parts


@lru_cache(maxsize=8192)
def leg_parts(design: KuafuDesign) -> dict[str, Part]:
    """Mass properties of the four leg bodies (the same for both legs), each in its frame."""
    models = load_mass_models()
    l0, l1 = design.thigh_length, design.shank_length
    bracket = box(C.HIP_ROLL_BRACKET_MASS, (0.08, 0.08, 0.08), np.zeros(3))
    foot_centre = np.array(
        [C.FOOT_TOE - 0.5 * C.FOOT_LENGTH, 0.0, -C.ANKLE_HEIGHT + 0.5 * C.FOOT_THICKNESS]
    )
    return {
        "hip_roll_link": combine([bracket, actuator(design.hip_motor, np.zeros(3), "y")]),
        # the knee actuator housing is carried by the thigh at the knee
        "thigh": combine(
            [models["thigh"].part(l0), actuator(design.knee_motor, np.array([0.0, 0.0, -l0]), "y")]
        ),
        # the ankle actuator sits high in the shank and drives the ankle by a push rod
        "shank": combine(
            [
                models["shank"].part(l1),
                actuator(C.ANKLE_MOTOR_TYPE, np.array([0.0, 0.0, -0.07]), "y"),
            ]
        ),
        "foot": box(C.FOOT_MASS, (C.FOOT_LENGTH, C.FOOT_WIDTH, C.FOOT_THICKNESS), foot_centre),
    }


def arm_part() -> Part:
    return cylinder(
        C.ARM_MASS, C.ARM_RADIUS, C.ARM_LENGTH, np.array([0.0, 0.0, -0.5 * C.ARM_LENGTH]), axis="z"
    )


@cache
def torso_mass() -> float:
    """The torso (battery, computer, structure) is the balancing term of the mass budget: the
    nominal design weighs NOMINAL_MASS (paper 4.1.1)."""
    nominal = KuafuDesign(1.0, 1.0)
    others = sum(p.mass for p in _upper_body_parts(nominal, 0.0))
    others += 2.0 * sum(p.mass for p in leg_parts(nominal).values())
    others += 2.0 * arm_part().mass
    return C.NOMINAL_MASS - others


def base_part(design: KuafuDesign) -> Part:
    return _base_part(design.hip_motor)


@lru_cache(maxsize=8)
def _base_part(hip_motor: int) -> Part:
    """The trunk depends on the design only through the hip-roll actuators it carries."""
    return combine(_upper_body_parts(KuafuDesign(1.0, 1.0, hip_motor=hip_motor), torso_mass()))


# -- default pose and leg kinematics -------------------------------------------------------
def stance_hip_to_ankle(design: KuafuDesign) -> float:
    """Vertical hip-centre to ankle-centre distance at the default pose."""
    return C.STANCE_EXTENSION * (design.thigh_length + design.shank_length)


def standing_base_height(design: KuafuDesign) -> float:
    return C.ANKLE_HEIGHT + stance_hip_to_ankle(design) - C.HIP_OFFSET[2]


def sagittal_ik(l0: float, l1: float, x: float, depth: float) -> tuple[float, float, float]:
    """(hip pitch, knee, ankle) putting the ankle centre at (x, -depth) from the hip in the
    leg plane, knee bent forward (knee >= 0), sole parallel to the ground. Positive pitch
    rotates about +y, moving the foot backwards."""
    reach = min(max(math.hypot(x, depth), abs(l0 - l1) + 1e-9), (l0 + l1) * (1 - 1e-9))
    cos_knee = (reach * reach - l0 * l0 - l1 * l1) / (2.0 * l0 * l1)
    knee = math.acos(min(1.0, max(-1.0, cos_knee)))
    pitch = math.atan2(-x, depth) - math.atan2(l1 * math.sin(knee), l0 + l1 * math.cos(knee))
    return pitch, knee, -(pitch + knee)


def default_joint_pos(design: KuafuDesign) -> np.ndarray:
    """[8] standing pose: ankles straight below the hips, soles flat, no hip roll."""
    pitch, knee, ankle = sagittal_ik(
        design.thigh_length, design.shank_length, 0.0, stance_hip_to_ankle(design)
    )
    leg = [0.0, pitch, knee, ankle]
    return np.array(leg + leg)


def _upper_body_in_hip_frame(design: KuafuDesign) -> list[Part]:
    """Base and both arms, placed in the left hip frame (base upright at the default pose)."""
    hip = _hip_centre("left")
    parts = [base_part(design).shifted(-hip)]
    for side in C.SIDES:
        parts.append(arm_part().shifted(_shoulder(side) - hip))
    return parts


def leg_joint_inertias(design: KuafuDesign) -> dict[str, dict[str, float]]:
    """Inertias of each leg joint about its axis at the default pose (left leg; the right
    one mirrors it; armature not included):

    - "load": what the joint carries with the foot on the ground and swings with it in the
      air: the whole leg plus the upper body (base and arms; the other leg left out);
    - "swing": the chain distal to the joint only (the foot alone at the ankle).
    """
    parts = leg_parts(design)
    _, pitch, knee, ankle = default_joint_pos(design)[:4]
    l0, l1 = design.thigh_length, design.shank_length
    r_thigh = rotation_y(pitch)
    r_shank = rotation_y(pitch + knee)
    p_knee = r_thigh @ np.array([0.0, 0.0, -l0])
    p_ankle = p_knee + r_shank @ np.array([0.0, 0.0, -l1])
    placed = {  # body: (rotation, position) in the hip frame
        "hip_roll_link": (np.eye(3), np.zeros(3)),
        "thigh": (r_thigh, np.zeros(3)),
        "shank": (r_shank, p_knee),
        "foot": (rotation_y(pitch + knee + ankle), p_ankle),
    }
    upper = _upper_body_in_hip_frame(design)
    x_axis, y_axis = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    joints = {  # joint: (point on the axis, axis, distal bodies)
        "hip_roll": (np.zeros(3), x_axis, ("hip_roll_link", "thigh", "shank", "foot")),
        "hip_pitch": (np.zeros(3), y_axis, ("thigh", "shank", "foot")),
        "knee": (p_knee, y_axis, ("shank", "foot")),
        "ankle": (p_ankle, y_axis, ("foot",)),
    }
    out: dict[str, dict[str, float]] = {"load": {}, "swing": {}}
    for name, (point, axis, distal) in joints.items():
        leg = {b: inertia_about_axis(parts[b], *placed[b], point, axis) for b in placed}
        above = sum(inertia_about_axis(p, np.eye(3), np.zeros(3), point, axis) for p in upper)
        out["load"][name] = sum(leg.values()) + above
        out["swing"][name] = sum(leg[b] for b in distal)
    return out


@cache
def _nominal_inertias() -> dict[str, dict[str, float]]:
    return leg_joint_inertias(KuafuDesign(1.0, 1.0))


def pd_gains(design: KuafuDesign) -> tuple[np.ndarray, np.ndarray, dict[str, dict[str, float]]]:
    """The PD scaling rule (README, "PD gains"):

        kp_j = kp_j(nominal) * L_j / L_j(nominal)
        kd_j = kd_j(nominal) * sqrt(kp_j / kp_j(nominal) * S_j / S_j(nominal))

    with L_j the load inertia and S_j = swing inertia + armature. Stiffness grows with the
    mass the joint moves (and with it the gravity load m g h it must out-stiffen to stand);
    damping keeps the swing mode's damping ratio kd / (2 sqrt(kp S)) at the nominal robot's,
    so the explicit PD stays as far from its 5 ms stability bound as the nominal design's
    for a given natural frequency."""
    inertias = leg_joint_inertias(design)
    nominal = _nominal_inertias()
    kp, kd = [], []
    for j in C.LEG_JOINTS:
        kp_ratio = inertias["load"][j] / nominal["load"][j]
        swing_ratio = (inertias["swing"][j] + C.ARMATURE) / (nominal["swing"][j] + C.ARMATURE)
        kp.append(C.NOMINAL_KP[j] * kp_ratio)
        kd.append(C.NOMINAL_KD[j] * math.sqrt(kp_ratio * swing_ratio))
    return np.array(kp + kp), np.array(kd + kd), inertias


def joint_limits() -> tuple[np.ndarray, np.ndarray]:
    lower, upper = [], []
    for side in C.SIDES:
        for j in C.LEG_JOINTS:
            lo, hi = C.JOINT_LIMITS_LEFT[j]
            if j == "hip_roll" and side == "right":  # mirror: abduction is -x rotation
                lo, hi = -hi, -lo
            lower.append(lo)
            upper.append(hi)
    return np.array(lower), np.array(upper)


def foot_contact_points() -> np.ndarray:
    """[4, 3] sole corners in the foot frame (origin at the ankle centre)."""
    z = -C.ANKLE_HEIGHT
    w = 0.5 * C.FOOT_WIDTH
    return np.array(
        [[C.FOOT_TOE, w, z], [C.FOOT_TOE, -w, z], [-C.FOOT_HEEL, w, z], [-C.FOOT_HEEL, -w, z]]
    )


# -- the model -------------------------------------------------------------------------------
#: the unit of each entry of a model's info, for `coadapt robot show` (RobotModel.info's
#: convention)
INFO_UNITS = {
    "thigh_length": "m",
    "shank_length": "m",
    "standing_height": "m",
    "hip_to_ankle": "m",
    "segment_masses": "kg",
    "joint_load_inertia": "kg m^2",
    "joint_swing_inertia": "kg m^2",
    "armature": "kg m^2",
    "joint_damping": "N m s/rad",
    "hip_offset": "m",
    "hip_motor": "type",
    "knee_motor": "type",
    "ankle_motor": "type",
}


def motor_limits(design: KuafuDesign) -> tuple[np.ndarray, np.ndarray]:
    """([8] torque limit N m, [8] speed limit rad/s) from Table 8 per joint's motor type."""
    torque, speed = [], []
    for _side in C.SIDES:
        for j in C.LEG_JOINTS:
            motor = C.MOTOR_TYPES[design.motor_of(j)]
            torque.append(motor["torque_limit"])
            speed.append(C.rpm_to_rad_s(motor["speed_limit_rpm"]))
    return np.array(torque), np.array(speed)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@lru_cache(maxsize=4096)
def build_cached(key: tuple[float, ...]) -> RobotModel:
    """The model of a design given as a rounded tuple (the cache key). Arrays are read-only
    because the model is shared between callers."""
    design = KuafuDesign.from_vector(np.array(key))
    legs = leg_parts(design)
    base = base_part(design)
    arm = arm_part()
    lower, upper = joint_limits()
    torque, speed = motor_limits(design)
    kp, kd, inertias = pd_gains(design)
    height = standing_base_height(design)
    geometry = Geometry(
        design,
        base,
        legs,
        arm,
        lower,
        upper,
        torque,
        speed,
        height,
        head_z=head_top_above_base() - C.HEAD_RADIUS,
        hips={side: _hip_centre(side) for side in C.SIDES},
        shoulders={side: _shoulder(side) for side in C.SIDES},
    )
    total = base.mass + 2.0 * sum(p.mass for p in legs.values()) + 2.0 * arm.mass
    info = {
        "thigh_length": design.thigh_length,
        "shank_length": design.shank_length,
        "hip_motor": design.hip_motor,
        "knee_motor": design.knee_motor,
        "ankle_motor": C.ANKLE_MOTOR_TYPE,
        "motor_types": [design.motor_of(j) for _ in C.SIDES for j in C.LEG_JOINTS],
        "standing_height": height + head_top_above_base(),
        "hip_to_ankle": stance_hip_to_ankle(design),
        "segment_masses": {
            "base": base.mass,
            "torso": torso_mass(),
            **{name: part.mass for name, part in legs.items()},
            "arm": arm.mass,
        },
        "armature": _readonly(np.full(len(C.JOINT_NAMES), C.ARMATURE)),
        "joint_damping": _readonly(np.full(len(C.JOINT_NAMES), C.JOINT_DAMPING)),
        "joint_load_inertia": dict(inertias["load"]),
        "joint_swing_inertia": dict(inertias["swing"]),
        "hip_offset": _readonly(C.HIP_OFFSET),
        "gear_ratio": C.GEAR_RATIO,
        "units": dict(INFO_UNITS),
    }
    return RobotModel(
        design=_readonly(np.array(key)),
        formats=MappingProxyType({"mjcf": mjcf_text(geometry), "urdf": urdf_text(geometry)}),
        base_body=C.BASE_BODY,
        joint_names=list(C.JOINT_NAMES),
        foot_bodies=list(C.FOOT_BODIES),
        default_joint_pos=_readonly(default_joint_pos(design)),
        kp=_readonly(kp),
        kd=_readonly(kd),
        torque_limit=_readonly(torque),
        speed_limit=_readonly(speed),
        joint_lower=_readonly(lower),
        joint_upper=_readonly(upper),
        standing_base_height=height,
        total_mass=total,
        foot_contact_points=_readonly(foot_contact_points()),
        info=info,
    )
