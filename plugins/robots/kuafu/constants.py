"""Fixed facts of the Kuafu humanoid model: paper figures, motor catalog (Table 8), geometry
and mass budget of the parts that do not change with the design. Every number here is an
assumption of ours unless its comment cites the paper; the README explains each one.
"""

from __future__ import annotations

import math
from typing import Any

#: the 3-vectors of the geometry below, by name: numpy arrays made on first use (`__getattr__`),
#: so that importing these facts (the robot's class does, `coadapt plugins` lists it) loads no
#: numpy
_VECTORS: dict[str, tuple[float, ...]] = {}

# -- paper section 4.1.1 ----------------------------------------------------------------
NOMINAL_MASS = 42.0  # kg
NOMINAL_HEIGHT = 1.6  # m, top of the head above the soles at the default standing pose
NOMINAL_LINK_LENGTH = 0.35  # m, thigh (hip pitch -> knee) and shank (knee -> ankle)
SCALE_BOUNDS = (0.5, 1.5)  # xi in [0.5, 1.5]^2, l0 = 0.35 xi0, l1 = 0.35 xi1

# -- actuated joints, the order of every [8] array ----------------------------------------
JOINT_NAMES = [
    "left_hip_roll",
    "left_hip_pitch",
    "left_knee",
    "left_ankle",
    "right_hip_roll",
    "right_hip_pitch",
    "right_knee",
    "right_ankle",
]
SIDES = ("left", "right")
LEG_JOINTS = ("hip_roll", "hip_pitch", "knee", "ankle")  # of each side, hip to foot
SIDE_SIGN = {"left": 1.0, "right": -1.0}  # +y is left
FOOT_BODIES = ["left_foot", "right_foot"]
BASE_BODY = "base"

# -- motors (paper Table 8; gear ratio 17.43 already included) ---------------------------
GEAR_RATIO = 17.43


def rpm_to_rad_s(rpm: float) -> float:
    return rpm * 2.0 * math.pi / 60.0


MOTOR_TYPES: dict[int, dict[str, float]] = {
    1: {"torque_limit": 119.7, "speed_limit_rpm": 99.0, "motor_mass": 0.62},
    2: {"torque_limit": 120.3, "speed_limit_rpm": 340.0, "motor_mass": 0.62},
    3: {"torque_limit": 135.1, "speed_limit_rpm": 310.0, "motor_mass": 0.67},
}
#: Kuafu's own motor; the nominal design uses it at hip and knee
NOMINAL_MOTOR_TYPE = 1
#: the ankle is not a design variable: it is driven by a type-1 motor on every design
ANKLE_MOTOR_TYPE = 1
#: the design's hip motor type drives hip roll AND hip pitch; the knee motor type the knee
#: (assumption, ours: the paper says only "motor types of hip and knee")

# Actuator unit = motor (Table 8 mass) + planetary gearbox, housing and driver board.
GEARBOX_HOUSING_MASS = 0.58  # kg, assumption
ACTUATOR_RADIUS = 0.05  # m, unit modelled as a solid cylinder on the joint axis
ACTUATOR_LENGTH = 0.06  # m
#: rotor inertia, the same for the three motor types (Table 8 does not give it)
ROTOR_INERTIA = 6.0e-5  # kg m^2, assumption
#: reflected rotor inertia at the joint: J_rotor * N^2 (MJCF armature, Pinocchio armature)
ARMATURE = ROTOR_INERTIA * GEAR_RATIO**2  # 0.0182 kg m^2
#: gearbox viscous friction at the joint
JOINT_DAMPING = 0.1  # N m s / rad, assumption

# -- geometry (x forward, y left, z up; base origin at the pelvis centre) ----------------
_VECTORS["HIP_OFFSET"] = (0.0, 0.10, -0.10)  # hip joint centre of the left leg in the base frame
#: hip roll and hip pitch axes intersect at the hip joint centre (a 2-DoF hip)
ANKLE_HEIGHT = 0.07  # m, ankle joint centre above the sole
FOOT_LENGTH = 0.22  # m
FOOT_WIDTH = 0.10  # m
FOOT_THICKNESS = 0.03  # m
FOOT_TOE = 0.13  # m, sole extends from the ankle 0.13 m forward and 0.09 m back
FOOT_HEEL = FOOT_LENGTH - FOOT_TOE
#: default standing pose: ankle centre straight below the hip at 0.94 of the full leg
#: length (knees bent about 40 degrees at the nominal design), sole flat
STANCE_EXTENSION = 0.94

# -- upper body: the trunk (pelvis + torso + head) is one rigid body, `base` -------------
PELVIS_MASS = 4.0  # kg, box 0.16 x 0.30 x 0.12 m around the base origin
_VECTORS["PELVIS_SIZE"] = (0.16, 0.30, 0.12)
_VECTORS["PELVIS_CENTRE"] = (0.0, 0.0, -0.03)
_VECTORS["TORSO_SIZE"] = (0.20, 0.32, 0.40)  # box; battery, computer, wiring inside
_VECTORS["TORSO_CENTRE"] = (0.0, 0.0, 0.28)
HEAD_MASS = 1.5  # kg, sphere
HEAD_RADIUS = 0.11
HIP_ROLL_BRACKET_MASS = 0.5  # kg, the hip clevis carrying the hip-pitch actuator
#: hip-roll actuator housings sit in the pelvis, behind the hip on the roll axis
_VECTORS["HIP_ROLL_ACTUATOR_OFFSET"] = (-0.07, 0.0, 0.0)

# Arms: two shoulder joints, fixed during optimization (paper 4.1.1), modelled as fixed
# joints; each arm a 1.25 kg capsule hanging straight down from the shoulder.
ARM_MASS = 1.25
ARM_LENGTH = 0.50
ARM_RADIUS = 0.04
_VECTORS["SHOULDER_OFFSET"] = (0.0, 0.20, 0.44)  # left shoulder in the base frame

FOOT_MASS = 0.9  # kg, aluminium sole plate + rubber + ankle bearing

# -- joint limits (rad), left leg; the right leg mirrors roll ------------------------------
JOINT_LIMITS_LEFT = {
    "hip_roll": (-0.35, 0.6),
    "hip_pitch": (-1.8, 0.7),
    "knee": (0.0, 2.3),
    "ankle": (-1.0, 0.8),
}

# -- PD gains of the nominal design (scaled for other designs, see generator.pd_gains) ------
# Chosen so every corner of the design space stands under PD alone at 5 ms physics steps
# and rides out 0.2 m/s pushes: standing without a policy needs the legs' series stiffness
# above the gravity stiffness m g h_com (about 330 N m/rad at the nominal design), which puts
# ankle and knee well above the ankle kp 15-40 of policy-balanced humanoids. The light foot
# bounds the ankle from above: the explicit PD loop must stay stable for the swinging foot
# (effective inertia 0.023 kg m^2 with armature) at the largest randomized gains, which keeps
# ankle kd small (validation check control.pd_stability).
NOMINAL_KP = {"hip_roll": 600.0, "hip_pitch": 600.0, "knee": 800.0, "ankle": 500.0}  # N m / rad
NOMINAL_KD = {"hip_roll": 12.0, "hip_pitch": 12.0, "knee": 10.0, "ankle": 2.0}  # N m s / rad

# -- numerical physics options ------------------------------------------------------------
TIMESTEP = 0.005  # s


def __getattr__(name: str) -> Any:
    """A vector of `_VECTORS` as a numpy array (one array per name, made once)."""
    if name not in _VECTORS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import numpy as np

    globals()[name] = value = np.array(_VECTORS[name])
    return value
