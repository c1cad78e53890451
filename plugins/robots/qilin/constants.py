"""Qilin's figures: a 12-joint quadruped modelled on the Unitree Go1's published description.

Source of every figure marked "Go1": the MJCF `unitree_go1/go1.xml` of MuJoCo Menagerie
(google-deepmind/mujoco_menagerie, BSD-3-Clause), itself derived from Unitree's public URDF
(unitreerobotics/unitree_ros, `robots/go1_description`). The motor speed limits are not in
that MJCF; they are the `<limit velocity>` Unitree's Go2 description declares for the same
torque ratings (23.7 N m at 30.1 rad/s, 35.55 N m at 20.06 rad/s). Everything else is an
assumption of ours and says so (README.md lists them all).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np


# -- body ----------------------------------------------------------------------------------
#: Go1 trunk mass, kg
TRUNK_MASS = 5.204
#: Go1 trunk principal moments, kg m^2 (0.0168, 0.0630, 0.0717), assigned to x, y, z by size:
#: the trunk is longest along x (assumption: principal axes along the base axes, CoM at the
#: base origin; the Go1's lies 2.2 cm ahead of it)
TRUNK_INERTIA = (0.0168101, 0.0630105, 0.0716565)
#: Go1 collision box of the trunk (half sizes 0.125, 0.04, 0.057 m) widened to its two side
#: cylinders' 0.058 m radius: full size of our one box, m
TRUNK_SIZE = (0.25, 0.196, 0.114)
#: Go1 abduction-joint centres relative to the base origin, m (x forward, y left)
HIP_X, HIP_Y = 0.1881, 0.04675
#: Go1 lateral offset of the hip-pitch joint from the abduction joint, m (outward)
THIGH_OFFSET = 0.08

# -- legs ----------------------------------------------------------------------------------
#: Go1 thigh and calf length (hip pitch to knee, knee to foot centre), m
NOMINAL_THIGH = 0.213
NOMINAL_CALF = 0.213
#: design bounds of both leg scales (ours: at 0.7 the standing base is 0.22 m high, at 1.3
#: the leg still folds under the trunk within the Go1's joint ranges)
SCALE_BOUNDS = (0.7, 1.3)
#: Go1 hip (abduction) link mass, kg: both of its motors' housings; fixed
HIP_MASS = 0.68
HIP_INERTIA = (0.000734064, 0.000468438, 0.000398719)
#: Go1 thigh link mass 1.009 kg. Assumption: 0.60 kg is the knee motor in its housing at the
#: hip-pitch axis (a solid cylinder of the Go1 hip geom's 0.046 m radius, 0.04 m long, about y)
#: and 0.409 kg the structure, a uniform rod along the thigh whose mass scales with length
THIGH_MOTOR_MASS = 0.60
THIGH_STRUCTURE_MASS = 1.009 - THIGH_MOTOR_MASS
MOTOR_RADIUS, MOTOR_LENGTH = 0.046, 0.04
#: Go1 calf link mass, kg, foot included. Assumption: a 0.02 kg solid rubber foot sphere
#: (fixed) and the rest a uniform rod along the calf, scaling with length (the Go1's calf
#: drive is a linkage rod inside it). A foot with mass keeps PyBullet from giving a URDF link
#: without inertial 1 kg
CALF_MASS = 0.195862
FOOT_MASS = 0.02
#: Go1 foot sphere radius, m (the foot body is the sphere's centre)
FOOT_RADIUS = 0.023
#: Go1 home pose: thigh 0.9 rad, knee -1.8 rad, which puts the foot below the hip at
#: cos(0.9) = 0.6216 of the leg's full length; every design stands at that share
STANCE_SHARE = math.cos(0.9)

LEGS = ("FL", "FR", "RL", "RR")
#: trot: diagonal pairs (FL + RR, FR + RL) half a gait cycle apart
TROT = {"FL": 0.0, "FR": 0.5, "RL": 0.5, "RR": 0.0}
JOINTS = ("abduction", "hip", "knee")
JOINT_NAMES = tuple(f"{leg}_{j}" for leg in LEGS for j in JOINTS)
FOOT_BODIES = tuple(f"{leg}_foot" for leg in LEGS)
BASE_BODY = "base"
#: Go1 joint ranges, rad: abduction +-0.863, hip -0.686..4.501, knee -2.818..-0.888
JOINT_RANGES = {"abduction": (-0.863, 0.863), "hip": (-0.686, 4.501), "knee": (-2.818, -0.888)}


def side(leg: str) -> float:
    """+1 for a left leg, -1 for a right one."""
    return 1.0 if leg[1] == "L" else -1.0


def hip_centre(leg: str) -> np.ndarray:
    """The abduction joint's centre in the base frame, m."""
    import numpy as np

    return np.array([HIP_X if leg[0] == "F" else -HIP_X, side(leg) * HIP_Y, 0.0])


# -- motors ----------------------------------------------------------------------------------
#: type 1: the Go1 joint motor (23.7 N m, 30.1 rad/s); type 2: the same motor behind the Go1
#: knee's further 1.5 reduction (35.55 N m, 20.06 rad/s). Assumption: the extra stage weighs
#: nothing and adds no reflected inertia (the Go1 MJCF gives every joint armature 0.01)
MOTOR_TYPES = {
    1: {"torque_limit": 23.7, "speed_limit": 30.1},
    2: {"torque_limit": 35.55, "speed_limit": 20.06},
}
#: the Go1's own: type 1 at the abduction and hip joints, type 2 at the knee
NOMINAL_HIP_MOTOR, NOMINAL_KNEE_MOTOR = 1, 2
#: the abduction joint always carries a type-1 motor (not a design variable)
ABDUCTION_MOTOR = 1
#: Go1 MJCF: armature 0.01 kg m^2 and damping 2 N m s/rad (abduction 1) per joint; we keep
#: the armature and a light damping (the PD's kd does the damping)
ARMATURE = 0.01
JOINT_DAMPING = 0.1
#: PD gains of every joint at the nominal design, N m/rad and N m s/rad (ours; `generator.pd_gains`
#: scales them with the squared leg length). legged_gym's (Rudin et al. 2022) settings for the
#: Go1-sized Unitree A1, stiffness 20 and damping 0.5, let the nominal design sag 8.1 cm in 1 s
#: holding its default pose and a long-calf corner 12.8 cm (the simulator conformance suite
#: allows 10 cm); 50 and 1.2 (legged_gym's damping-to-stiffness ratio) keep the nominal design
#: and the four corners within 2.0-3.1 cm
KP, KD = 50.0, 1.2
