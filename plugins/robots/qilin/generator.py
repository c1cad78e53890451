"""Qilin's models from a design: link masses and inertias from a documented solid model
(constants.py), the standing pose, motor limits, and the same robot written as MJCF and URDF
(identical frames, masses and inertias, so Pinocchio and MuJoCo agree to rounding)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType

import numpy as np
from coadapt_plugins.robots.qilin import constants as C

from coadapt_core.robot import RobotModel


@dataclass(frozen=True)
class Part:
    """A rigid link's mass, centre of mass and inertia about it (link frame), kg, m, kg m^2."""

    mass: float
    com: np.ndarray  # [3]
    inertia: np.ndarray  # [3] diagonal: every part is symmetric about the link's axes


@dataclass(frozen=True)
class QilinDesign:
    thigh_scale: float
    calf_scale: float
    hip_motor: int = C.NOMINAL_HIP_MOTOR
    knee_motor: int = C.NOMINAL_KNEE_MOTOR

    @property
    def thigh(self) -> float:
        return C.NOMINAL_THIGH * self.thigh_scale

    @property
    def calf(self) -> float:
        return C.NOMINAL_CALF * self.calf_scale

    @classmethod
    def from_vector(cls, values: np.ndarray) -> QilinDesign:
        motors = (int(round(values[2])), int(round(values[3]))) if len(values) == 4 else ()
        return cls(float(values[0]), float(values[1]), *motors)


def _cylinder_y(mass: float, radius: float, length: float) -> np.ndarray:
    """Diagonal inertia of a solid cylinder whose axis is y, about its centre."""
    across = mass * (3 * radius**2 + length**2) / 12
    return np.array([across, mass * radius**2 / 2, across])


def _rod_z(mass: float, radius: float, length: float) -> np.ndarray:
    """Diagonal inertia of a solid cylinder whose axis is z, about its centre."""
    across = mass * (3 * radius**2 + length**2) / 12
    return np.array([across, across, mass * radius**2 / 2])


def thigh_part(design: QilinDesign) -> Part:
    """The knee motor at the hip-pitch axis plus the structure, a rod along -z."""
    length = design.thigh
    rod = C.THIGH_STRUCTURE_MASS * design.thigh_scale
    mass = C.THIGH_MOTOR_MASS + rod
    com_z = rod * (-length / 2) / mass
    # parallel-axis shifts of both parts to the common centre of mass (along z only)
    shift = C.THIGH_MOTOR_MASS * com_z**2 + rod * (-length / 2 - com_z) ** 2
    inertia = (
        _cylinder_y(C.THIGH_MOTOR_MASS, C.MOTOR_RADIUS, C.MOTOR_LENGTH)
        + _rod_z(rod, 0.015, length)
        + np.array([shift, shift, 0.0])
    )
    return Part(mass, np.array([0.0, 0.0, com_z]), inertia)


def calf_part(design: QilinDesign) -> Part:
    mass = (C.CALF_MASS - C.FOOT_MASS) * design.calf_scale
    return Part(mass, np.array([0.0, 0.0, -design.calf / 2]), _rod_z(mass, 0.01, design.calf))


def foot_part() -> Part:
    """A solid sphere about its centre, the foot body's origin."""
    return Part(C.FOOT_MASS, np.zeros(3), np.full(3, 0.4 * C.FOOT_MASS * C.FOOT_RADIUS**2))


def hip_part() -> Part:
    return Part(C.HIP_MASS, np.zeros(3), np.array(C.HIP_INERTIA))


def base_part() -> Part:
    return Part(C.TRUNK_MASS, np.zeros(3), np.array(C.TRUNK_INERTIA))


def total_mass(design: QilinDesign) -> float:
    return C.TRUNK_MASS + len(C.LEGS) * (
        C.HIP_MASS + thigh_part(design).mass + calf_part(design).mass + C.FOOT_MASS
    )


def stance_depth(design: QilinDesign) -> float:
    """Vertical hip-pitch-to-foot-centre distance at the default pose, m."""
    return C.STANCE_SHARE * (design.thigh + design.calf)


def sagittal_ik(thigh: float, calf: float, x: float, depth: float) -> tuple[float, float]:
    """(hip, knee) angles about y putting the foot centre at (x, -depth) from the hip-pitch
    joint in the leg's plane, knee bent backwards (knee < 0, the Go1's). A link at angle a
    from straight down points along (-sin a, -cos a); the foot's direction is the thigh's
    angle plus the calf's direction in the thigh frame."""
    reach = min(max(math.hypot(x, depth), abs(thigh - calf) + 1e-9), (thigh + calf) * (1 - 1e-9))
    knee = -math.acos(max(-1.0, min(1.0, (reach**2 - thigh**2 - calf**2) / (2 * thigh * calf))))
    hip = math.atan2(-x, depth) - math.atan2(calf * math.sin(knee), thigh + calf * math.cos(knee))
    return hip, knee


def default_joint_pos(design: QilinDesign) -> np.ndarray:
    """[12] abduction 0, hip and knee that put each foot below its hip-pitch joint."""
    hip, knee = sagittal_ik(design.thigh, design.calf, 0.0, stance_depth(design))
    return np.array([0.0, hip, knee] * len(C.LEGS))


def pd_gains(design: QilinDesign) -> tuple[float, float]:
    """(kp, kd) of every joint: the nominal gains times the squared ratio of the leg's length
    to the nominal one. The standing load's torque grows with the leg's length and its
    deflection moves the foot by length x angle, so the sag holding the default pose stays
    about the nominal design's."""
    ratio = ((design.thigh + design.calf) / (C.NOMINAL_THIGH + C.NOMINAL_CALF)) ** 2
    return C.KP * ratio, C.KD * ratio


def motor_limits(design: QilinDesign) -> tuple[np.ndarray, np.ndarray]:
    """([12] torque limit N m, [12] speed limit rad/s): type 1 at every abduction joint, the
    design's types at the hips and knees."""
    types = {"abduction": C.ABDUCTION_MOTOR, "hip": design.hip_motor, "knee": design.knee_motor}
    torque = [C.MOTOR_TYPES[types[j]]["torque_limit"] for _ in C.LEGS for j in C.JOINTS]
    speed = [C.MOTOR_TYPES[types[j]]["speed_limit"] for _ in C.LEGS for j in C.JOINTS]
    return np.array(torque), np.array(speed)


# -- text ------------------------------------------------------------------------------------
def _f(x: float) -> str:
    return f"{float(x):.10g}"


def _v(v) -> str:
    return " ".join(_f(x) for x in v)


def _mj_inertial(p: Part) -> str:
    return f'<inertial pos="{_v(p.com)}" mass="{_f(p.mass)}" diaginertia="{_v(p.inertia)}"/>'


def _urdf_inertial(p: Part) -> str:
    i = p.inertia
    return (
        f'<inertial><origin xyz="{_v(p.com)}" rpy="0 0 0"/><mass value="{_f(p.mass)}"/>'
        f'<inertia ixx="{_f(i[0])}" ixy="0" ixz="0" iyy="{_f(i[1])}" iyz="0" '
        f'izz="{_f(i[2])}"/></inertial>'
    )


def _leg_frames(design: QilinDesign, leg: str) -> list[np.ndarray]:
    """Origins of the hip, thigh, calf and foot frames, each in its parent's frame."""
    return [
        C.hip_centre(leg),
        np.array([0.0, C.side(leg) * C.THIGH_OFFSET, 0.0]),
        np.array([0.0, 0.0, -design.thigh]),
        np.array([0.0, 0.0, -design.calf]),
    ]


def _mjcf(design: QilinDesign, torque: np.ndarray, height: float) -> str:
    lo, hi = C.JOINT_RANGES["abduction"], C.JOINT_RANGES["hip"]
    knee = C.JOINT_RANGES["knee"]
    out = [
        '<mujoco model="qilin">',
        # every body carries its inertial: none is guessed from geoms
        '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
        "  <default>",
        f'    <joint type="hinge" damping="{_f(C.JOINT_DAMPING)}" armature="{_f(C.ARMATURE)}" '
        'limited="true"/>',
        '    <geom contype="1" conaffinity="0" condim="3" rgba="0.75 0.6 0.3 1"/>',
        '    <motor ctrllimited="true" gear="1"/>',
        "  </default>",
        "  <worldbody>",
        f'    <body name="{C.BASE_BODY}" pos="0 0 {_f(height)}">',
        '      <freejoint name="root"/>',
        f"      {_mj_inertial(base_part())}",
        f'      <geom name="trunk" type="box" size="{_v(0.5 * np.array(C.TRUNK_SIZE))}"/>',
    ]
    thigh, calf = thigh_part(design), calf_part(design)
    for leg in C.LEGS:
        f = _leg_frames(design, leg)
        out += [
            f'      <body name="{leg}_hip" pos="{_v(f[0])}">',
            f'        <joint name="{leg}_abduction" axis="1 0 0" range="{_f(lo[0])} {_f(lo[1])}"/>',
            f"        {_mj_inertial(hip_part())}",
            f'        <geom name="{leg}_hip" type="cylinder" quat="1 1 0 0" '
            f'size="{_f(C.MOTOR_RADIUS)} 0.02"/>',
            f'        <body name="{leg}_thigh" pos="{_v(f[1])}">',
            f'          <joint name="{leg}_hip" axis="0 1 0" range="{_f(hi[0])} {_f(hi[1])}"/>',
            f"          {_mj_inertial(thigh)}",
            f'          <geom name="{leg}_thigh" type="capsule" fromto="0 0 0 0 0 '
            f'{_f(-design.thigh)}" size="0.015"/>',
            f'          <body name="{leg}_calf" pos="{_v(f[2])}">',
            f'            <joint name="{leg}_knee" axis="0 1 0" range="{_f(knee[0])} '
            f'{_f(knee[1])}"/>',
            f"            {_mj_inertial(calf)}",
            f'            <geom name="{leg}_calf" type="capsule" fromto="0 0 0 0 0 '
            f'{_f(-design.calf)}" size="0.01"/>',
            f'            <body name="{leg}_foot" pos="{_v(f[3])}">',
            f"              {_mj_inertial(foot_part())}",
            f'              <geom name="{leg}_foot" type="sphere" size="{_f(C.FOOT_RADIUS)}" '
            'rgba="0.2 0.2 0.2 1"/>',
            "            </body>",
            "          </body>",
            "        </body>",
            "      </body>",
        ]
    out += ["    </body>", "  </worldbody>", "  <actuator>"]
    out += [
        f'    <motor name="{n}" joint="{n}" ctrlrange="{_f(-t)} {_f(t)}"/>'
        for n, t in zip(C.JOINT_NAMES, torque, strict=True)
    ]
    return "\n".join([*out, "  </actuator>", "</mujoco>", ""])


def _link(name: str, part: Part, geometry: str, xyz) -> str:
    shape = f'<origin xyz="{_v(xyz)}" rpy="0 0 0"/><geometry>{geometry}</geometry>'
    return (
        f'  <link name="{name}">{_urdf_inertial(part)}'
        f"<visual>{shape}</visual><collision>{shape}</collision></link>"
    )


def _urdf(design: QilinDesign, torque: np.ndarray, speed: np.ndarray) -> str:
    out = [
        '<?xml version="1.0"?>',
        "<!-- Qilin quadruped generated by coadapt; floating base implied (root link base). Every "
        "revolute",
        f"     joint has a reflected rotor inertia (armature) of {_f(C.ARMATURE)} kg m^2, which "
        "URDF cannot carry. -->",
        '<robot name="qilin">',
        _link(C.BASE_BODY, base_part(), f'<box size="{_v(C.TRUNK_SIZE)}"/>', np.zeros(3)),
    ]
    parts = [hip_part(), thigh_part(design), calf_part(design), foot_part()]
    for i, leg in enumerate(C.LEGS):
        frames = _leg_frames(design, leg)
        links = [f"{leg}_hip", f"{leg}_thigh", f"{leg}_calf", f"{leg}_foot"]
        shapes = [
            (f'<cylinder radius="{_f(C.MOTOR_RADIUS)}" length="0.04"/>', np.zeros(3)),
            (f'<cylinder radius="0.015" length="{_f(design.thigh)}"/>', [0, 0, -design.thigh / 2]),
            (f'<cylinder radius="0.01" length="{_f(design.calf)}"/>', [0, 0, -design.calf / 2]),
            (f'<sphere radius="{_f(C.FOOT_RADIUS)}"/>', np.zeros(3)),
        ]
        for k, link in enumerate(links):
            out.append(_link(link, parts[k], *shapes[k]))
            parent = C.BASE_BODY if k == 0 else links[k - 1]
            origin = f'<origin xyz="{_v(frames[k])}" rpy="0 0 0"/>'
            if k == 3:
                out.append(
                    f'  <joint name="{leg}_foot_fixed" type="fixed"><parent link="{parent}"/>'
                    f'<child link="{link}"/>{origin}</joint>'
                )
                continue
            j, n = C.JOINTS[k], 3 * i + k
            lo, hi = C.JOINT_RANGES[j]
            out.append(
                f'  <joint name="{leg}_{j}" type="revolute"><parent link="{parent}"/><child '
                f'link="{link}"/>'
                f'{origin}<axis xyz="{"1 0 0" if k == 0 else "0 1 0"}"/><limit lower="{_f(lo)}" '
                f'upper="{_f(hi)}" '
                f'effort="{_f(torque[n])}" velocity="{_f(speed[n])}"/>'
                f'<dynamics damping="{_f(C.JOINT_DAMPING)}" friction="0"/></joint>'
            )
    return "\n".join([*out, "</robot>", ""])


def _readonly(a) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@lru_cache(maxsize=4096)
def build_cached(key: tuple[float, ...]) -> RobotModel:
    """The model of a design given as a rounded tuple (the cache key); its arrays are
    read-only because callers share it."""
    design = QilinDesign.from_vector(np.array(key))
    torque, speed = motor_limits(design)
    height = stance_depth(design) + C.FOOT_RADIUS
    kp, kd = pd_gains(design)
    n = len(C.JOINT_NAMES)
    lower = [C.JOINT_RANGES[j][0] for _ in C.LEGS for j in C.JOINTS]
    upper = [C.JOINT_RANGES[j][1] for _ in C.LEGS for j in C.JOINTS]
    info = {
        "thigh_length": design.thigh,
        "calf_length": design.calf,
        "hip_motor": design.hip_motor,
        "knee_motor": design.knee_motor,
        "segment_masses": {
            "base": C.TRUNK_MASS,
            "hip": C.HIP_MASS,
            "thigh": thigh_part(design).mass,
            "calf": calf_part(design).mass,
            "foot": C.FOOT_MASS,
        },
        "armature": _readonly(np.full(n, C.ARMATURE)),
        "joint_damping": _readonly(np.full(n, C.JOINT_DAMPING)),
        "units": {
            "thigh_length": "m",
            "calf_length": "m",
            "segment_masses": "kg",
            "armature": "kg m^2",
            "joint_damping": "N m s/rad",
            "hip_motor": "type",
            "knee_motor": "type",
        },
    }
    return RobotModel(
        design=_readonly(np.array(key)),
        formats=MappingProxyType(
            {"mjcf": _mjcf(design, torque, height), "urdf": _urdf(design, torque, speed)}
        ),
        base_body=C.BASE_BODY,
        joint_names=list(C.JOINT_NAMES),
        foot_bodies=list(C.FOOT_BODIES),
        default_joint_pos=_readonly(default_joint_pos(design)),
        kp=_readonly(np.full(n, kp)),
        kd=_readonly(np.full(n, kd)),
        torque_limit=_readonly(torque),
        speed_limit=_readonly(speed),
        joint_lower=_readonly(lower),
        joint_upper=_readonly(upper),
        standing_base_height=height,
        total_mass=total_mass(design),
        foot_contact_points=_readonly([[0.0, 0.0, -C.FOOT_RADIUS]]),
        info=info,
    )
