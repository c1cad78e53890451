"""`trotter`: a small quadruped (about 6 kg, 8 joints) generated as MJCF and URDF from a
design vector: thigh and shank scale, and (mixed space) a motor type.

Each leg is a hip-pitch joint and a knee joint, both about the body's y axis, so every leg
moves in its own x-z plane; the foot is a sphere at the shank's end. Legs in order: front
left, front right, rear left, rear right. The gait clock trots: diagonal pairs (FL + RR,
FR + RL) are half a cycle apart.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import DesignError
from coadapt_core.robot import Finding, Leg, Robot, RobotModel, ValidationReport

THIGH, SHANK = 0.16, 0.16  # nominal segment lengths, m
FOOT_RADIUS = 0.02
BASE_SIZE = (0.40, 0.20, 0.08)  # full box size, m
BASE_MASS = 4.0
HIPS = {"fl": (0.17, 0.10), "fr": (0.17, -0.10), "rl": (-0.17, 0.10), "rr": (-0.17, -0.10)}
LEGS = tuple(HIPS)
TROT = {"fl": 0.0, "fr": 0.5, "rl": 0.5, "rr": 0.0}
STANCE = 0.8  # standing hip-to-foot distance as a fraction of the leg's full length
#: motor types: (peak torque N m, no-load speed rad/s, motor mass kg at the hip)
MOTORS = {1.0: (8.0, 25.0, 0.10), 2.0: (12.0, 18.0, 0.16)}
KP, KD = 30.0, 0.6


def segment_masses(thigh: float, shank: float) -> tuple[float, float, float]:
    """(thigh, shank, foot) masses in kg: aluminium-like tubes scale with length."""
    return 0.30 * thigh, 0.15 * shank, 0.05


def two_link_ik(x, z, lt, ls):
    """Hip and knee angles (torch or numpy, broadcast) that put the foot at (x, z) relative
    to the hip in the leg's plane; the knee bends backwards (negative angle)."""
    import torch

    x, z, lt, ls = (torch.as_tensor(v, dtype=torch.float64) for v in (x, z, lt, ls))
    r = torch.sqrt(x**2 + z**2).clamp(min=(lt - ls).abs() + 1e-6, max=lt + ls - 1e-6)
    cos_knee = ((r**2 - lt**2 - ls**2) / (2 * lt * ls)).clamp(-1.0, 1.0)
    knee = -torch.acos(cos_knee)
    # rotation about y adds its angle to atan2(x, z) of a vector in the x-z plane
    alpha_foot = torch.atan2(x, z)
    alpha_leg = torch.atan2(-ls * torch.sin(knee), -lt - ls * torch.cos(knee))
    hip = torch.remainder(alpha_foot - alpha_leg + math.pi, 2 * math.pi) - math.pi
    return hip, knee


class Trotter(Robot):
    """A small trotting quadruped: thigh/shank scale in [0.7, 1.3], motor type 1-2."""

    name: ClassVar[str] = "trotter"
    description: ClassVar[str] = (
        "example quadruped (6 kg, 8 joints): thigh/shank scale in [0.7, 1.3], motor type 1-2"
    )

    def design_space(self, mixed: bool = False) -> DesignSpace:
        variables = [Continuous("thigh_scale", 0.7, 1.3), Continuous("shank_scale", 0.7, 1.3)]
        if mixed:
            variables.append(Discrete("motor", (1.0, 2.0)))
        return DesignSpace(variables)

    def nominal_design(self, mixed: bool = False) -> np.ndarray:
        return np.array([1.0, 1.0, 1.0] if mixed else [1.0, 1.0])

    def legs(self) -> list[Leg]:
        return [Leg(name, TROT[name]) for name in LEGS]

    # -- kinematics ------------------------------------------------------------------------
    def _lengths(self, designs):
        import torch

        designs = torch.as_tensor(designs, dtype=torch.float64)
        return THIGH * designs[..., 0], SHANK * designs[..., 1]

    def default_foot_positions(self, designs):
        import torch

        lt, ls = self._lengths(designs)
        height = STANCE * (lt + ls)  # [n]
        feet = torch.zeros(*height.shape, len(LEGS), 3, dtype=torch.float64)
        feet[..., 2] = -height[..., None]
        return feet

    def leg_inverse_kinematics(self, designs, foot_pos):
        import torch

        lt, ls = self._lengths(designs)
        hip, knee = two_link_ik(
            foot_pos[..., 0], foot_pos[..., 2], lt[..., None], ls[..., None]
        )  # [n, L]
        return torch.stack([hip, knee], dim=-1).reshape(*hip.shape[:-1], 2 * len(LEGS))  # [n, 8]

    # -- models ------------------------------------------------------------------------------
    def build(self, design: np.ndarray) -> RobotModel:
        design = np.atleast_1d(np.asarray(design, dtype=float))
        space = self.design_space(design.shape[0] == 3)
        if design.ndim != 1 or design.shape[0] not in (2, 3):
            raise DesignError(
                f"trotter design needs 2 or 3 values, got {design.size}", field="design"
            )
        space.validate(design)
        thigh, shank = float(design[0]), float(design[1])
        motor = float(design[2]) if design.shape[0] == 3 else 1.0
        peak, speed, motor_mass = MOTORS[motor]
        lt, ls = THIGH * thigh, SHANK * shank
        m_thigh, m_shank, m_foot = segment_masses(thigh, shank)
        height = STANCE * (lt + ls)
        hip, knee = (float(v) for v in two_link_ik(0.0, -height, lt, ls))
        joint_names = [f"{leg}_{j}" for leg in LEGS for j in ("hip", "knee")]
        default = np.array([hip, knee] * len(LEGS))
        total = BASE_MASS + len(LEGS) * (motor_mass + m_thigh + m_shank + m_foot)
        standing = height + FOOT_RADIUS
        return RobotModel(
            design=design.copy(),
            formats={
                "mjcf": self._mjcf(lt, ls, m_thigh, m_shank, m_foot, motor_mass, peak, standing),
                "urdf": self._urdf(lt, ls, m_thigh, m_shank, m_foot, motor_mass),
            },
            base_body="base",
            joint_names=joint_names,
            foot_bodies=[f"{leg}_foot" for leg in LEGS],
            default_joint_pos=default,
            kp=np.full(8, KP),
            kd=np.full(8, KD),
            torque_limit=np.full(8, peak),
            speed_limit=np.full(8, speed),
            joint_lower=np.tile([-1.6, -2.7], 4),
            joint_upper=np.tile([1.6, -0.05], 4),
            standing_base_height=standing,
            total_mass=total,
            foot_contact_points=np.zeros((1, 3)),
            info={"thigh_length": lt, "shank_length": ls, "motor": motor},
        )

    def _mjcf(self, lt, ls, m_thigh, m_shank, m_foot, motor_mass, peak, standing) -> str:
        bx, by, bz = (s / 2 for s in BASE_SIZE)
        legs, motors = [], []
        for leg, (x, y) in HIPS.items():
            legs.append(f"""
      <body name="{leg}_thigh" pos="{x} {y} 0">
        <joint name="{leg}_hip" axis="0 1 0" range="-1.6 1.6" armature="0.005" damping="0.01"/>
        <geom type="sphere" size="0.025" mass="{motor_mass}" contype="0" conaffinity="0"/>
        <geom type="capsule" fromto="0 0 0 0 0 {-lt}" size="0.012" mass="{m_thigh}"
              contype="0" conaffinity="0"/>
        <body name="{leg}_shank" pos="0 0 {-lt}">
          <joint name="{leg}_knee" axis="0 1 0" range="-2.7 -0.05" armature="0.005" damping="0.01"/>
          <geom type="capsule" fromto="0 0 0 0 0 {-ls}" size="0.01" mass="{m_shank}"
                contype="0" conaffinity="0"/>
          <body name="{leg}_foot" pos="0 0 {-ls}">
            <geom type="sphere" size="{FOOT_RADIUS}" mass="{m_foot}" contype="1" conaffinity="0"
                  condim="3" friction="1.0 0.005 0.0001"/>
          </body>
        </body>
      </body>""")
            for j in ("hip", "knee"):
                motors.append(
                    f'    <motor name="{leg}_{j}" joint="{leg}_{j}" gear="1" ctrlrange="{-peak} '
                    f'{peak}"/>'
                )
        return f"""<mujoco model="trotter">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 {standing}">
      <freejoint name="root"/>
      <geom type="box" size="{bx} {by} {bz}" mass="{BASE_MASS}" contype="1" conaffinity="0"/>
      {"".join(legs)}
    </body>
  </worldbody>
  <actuator>
{chr(10).join(motors)}
  </actuator>
</mujoco>
"""

    def _urdf(self, lt, ls, m_thigh, m_shank, m_foot, motor_mass) -> str:
        def inertial(mass, z):
            i = max(mass * 1e-4, 1e-6)
            return (
                f'<inertial><origin xyz="0 0 {z}"/><mass value="{mass}"/>'
                f'<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial>'
            )

        bx, by, bz = BASE_SIZE
        parts = [
            f'<robot name="trotter"><link name="base">{inertial(BASE_MASS, 0)}'
            f'<collision><geometry><box size="{bx} {by} {bz}"/></geometry></collision></link>'
        ]
        for leg, (x, y) in HIPS.items():
            thigh_com = -lt / 2 * m_thigh / (motor_mass + m_thigh)
            parts.append(
                f'<link name="{leg}_thigh">{inertial(motor_mass + m_thigh, thigh_com)}</link>'
                f'<joint name="{leg}_hip" type="revolute"><parent link="base"/><child '
                f'link="{leg}_thigh"/>'
                f'<origin xyz="{x} {y} 0"/><axis xyz="0 1 0"/><limit lower="-1.6" upper="1.6" '
                'effort="12" velocity="25"/></joint>'
                f'<link name="{leg}_shank">{inertial(m_shank, -ls / 2)}</link>'
                f'<joint name="{leg}_knee" type="revolute"><parent link="{leg}_thigh"/><child '
                f'link="{leg}_shank"/>'
                f'<origin xyz="0 0 {-lt}"/><axis xyz="0 1 0"/><limit lower="-2.7" upper="-0.05" '
                'effort="12" velocity="25"/></joint>'
                f'<link name="{leg}_foot">{inertial(m_foot, 0)}'
                "<collision><geometry><sphere "
                f'radius="{FOOT_RADIUS}"/></geometry></collision></link>'
                f'<joint name="{leg}_foot_fixed" type="fixed"><parent link="{leg}_shank"/><child '
                f'link="{leg}_foot"/>'
                f'<origin xyz="0 0 {-ls}"/></joint>'
            )
        parts.append("</robot>")
        return "".join(parts)

    # -- validation ----------------------------------------------------------------------------
    def validate(self, design: np.ndarray) -> ValidationReport:
        design = np.atleast_1d(np.asarray(design, dtype=float))
        model = self.build(design)
        lt = model.info["thigh_length"]
        # static knee torque with the weight shared by two stance feet (a trot), foot under hip
        weight_per_foot = model.total_mass * 9.81 / 2
        knee_arm = lt * math.sin(abs(model.default_joint_pos[0]))
        knee_torque = weight_per_foot * knee_arm
        clearance = model.standing_base_height - BASE_SIZE[2] / 2
        findings = [
            Finding(
                "kinematics.reach",
                bool(STANCE < 1.0),
                f"stance height is {STANCE:.2f} of the leg's length (< 1)",
                float(STANCE),
                1.0,
            ),
            Finding(
                "statics.knee_torque",
                bool(knee_torque < 0.8 * float(model.torque_limit[1])),
                f"static knee torque {knee_torque:.2f} N m < 80 % of the motor's "
                f"{model.torque_limit[1]:.1f} N m",
                float(knee_torque),
                float(0.8 * model.torque_limit[1]),
            ),
            Finding(
                "geometry.belly_clearance",
                bool(clearance > 0.1),
                f"belly {clearance:.3f} m above flat ground (> 0.1 m)",
                float(clearance),
                0.1,
            ),
        ]
        return ValidationReport(design, findings)
