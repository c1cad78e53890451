"""The Kuafu model as text: the MJCF and the URDF of one design's geometry (masses,
inertias, joint frames, limits), written from the same numbers so both describe the same
robot (`generator.py` computes them; `validation.py` checks the two agree)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from coadapt_plugins.robots.kuafu import constants as C
from coadapt_plugins.robots.kuafu.inertia import Part

if TYPE_CHECKING:
    from coadapt_plugins.robots.kuafu.generator import KuafuDesign


def _f(x: float) -> str:
    return f"{float(x):.10g}"


def _v(v: np.ndarray) -> str:
    return " ".join(_f(x) for x in v)


def _mj_inertial(p: Part) -> str:
    i = p.inertia
    full = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
    return f'<inertial pos="{_v(p.com)}" mass="{_f(p.mass)}" fullinertia="{_v(np.array(full))}"/>'


def _urdf_inertial(p: Part) -> str:
    i = p.inertia
    return (
        f'<inertial><origin xyz="{_v(p.com)}" rpy="0 0 0"/><mass value="{_f(p.mass)}"/>'
        f'<inertia ixx="{_f(i[0, 0])}" ixy="{_f(i[0, 1])}" ixz="{_f(i[0, 2])}" '
        f'iyy="{_f(i[1, 1])}" iyz="{_f(i[1, 2])}" izz="{_f(i[2, 2])}"/></inertial>'
    )


@dataclass(frozen=True)
class Geometry:
    """What the text writers need for one design."""

    design: KuafuDesign
    base: Part
    legs: dict[str, Part]
    arm: Part
    lower: np.ndarray
    upper: np.ndarray
    torque_limit: np.ndarray
    speed_limit: np.ndarray
    base_height: float
    head_z: float  # the head's centre above the base origin
    hips: dict[str, np.ndarray]  # side -> hip centre in the base frame
    shoulders: dict[str, np.ndarray]  # side -> shoulder in the base frame


def _sole_box() -> tuple[np.ndarray, np.ndarray]:
    """(centre in the foot frame, full size) of the sole box: the feet's collision shape."""
    centre = np.array(
        [C.FOOT_TOE - 0.5 * C.FOOT_LENGTH, 0.0, -C.ANKLE_HEIGHT + 0.5 * C.FOOT_THICKNESS]
    )
    return centre, np.array([C.FOOT_LENGTH, C.FOOT_WIDTH, C.FOOT_THICKNESS])


def mjcf_text(g: Geometry) -> str:
    l0, l1 = g.design.thigh_length, g.design.shank_length
    head_z = g.head_z
    sole_centre, sole_size = _sole_box()
    out = [
        '<mujoco model="kuafu">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_f(C.TIMESTEP)}"/>',
        "  <default>",
        f'    <joint type="hinge" damping="{_f(C.JOINT_DAMPING)}" armature="{_f(C.ARMATURE)}" '
        'limited="true"/>',
        '    <geom contype="1" conaffinity="0" condim="3" rgba="0.7 0.7 0.75 1"/>',
        '    <motor ctrllimited="true" gear="1"/>',
        '    <default class="visual"><geom contype="0" conaffinity="0" group="1" rgba="0.25 0.35 '
        '0.6 1"/></default>',
        "  </default>",
        "  <worldbody>",
        f'    <body name="base" pos="0 0 {_f(g.base_height)}">',
        '      <freejoint name="root"/>',
        f"      {_mj_inertial(g.base)}",
        f'      <geom name="pelvis" type="box" pos="{_v(C.PELVIS_CENTRE)}" '
        f'size="{_v(0.5 * C.PELVIS_SIZE)}"/>',
        f'      <geom name="torso" type="box" pos="{_v(C.TORSO_CENTRE)}" '
        f'size="{_v(0.5 * C.TORSO_SIZE)}"/>',
        f'      <geom name="head" type="sphere" pos="0 0 {_f(head_z)}" '
        f'size="{_f(C.HEAD_RADIUS)}"/>',
        '      <geom name="neck" class="visual" type="cylinder" fromto="0 0 '
        f'{_f(C.TORSO_CENTRE[2] + 0.5 * C.TORSO_SIZE[2])} 0 0 {_f(head_z)}" size="0.04"/>',
    ]
    joint_index = 0
    for side in C.SIDES:
        hip = g.hips[side]
        names = [f"{side}_{j}" for j in C.LEG_JOINTS]
        rng = [(g.lower[joint_index + k], g.upper[joint_index + k]) for k in range(4)]
        joint_index += 4
        out += [
            f'      <body name="{side}_hip_roll_link" pos="{_v(hip)}">',
            f'        <joint name="{names[0]}" axis="1 0 0" range="{_f(rng[0][0])} '
            f'{_f(rng[0][1])}"/>',
            f"        {_mj_inertial(g.legs['hip_roll_link'])}",
            f'        <geom name="{side}_hip" type="sphere" size="0.06"/>',
            f'        <body name="{side}_thigh">',
            f'          <joint name="{names[1]}" axis="0 1 0" range="{_f(rng[1][0])} '
            f'{_f(rng[1][1])}"/>',
            f"          {_mj_inertial(g.legs['thigh'])}",
            f'          <geom name="{side}_thigh" type="capsule" fromto="0 0 0 0 0 {_f(-l0)}" '
            'size="0.05"/>',
            f'          <body name="{side}_shank" pos="0 0 {_f(-l0)}">',
            f'            <joint name="{names[2]}" axis="0 1 0" range="{_f(rng[2][0])} '
            f'{_f(rng[2][1])}"/>',
            f"            {_mj_inertial(g.legs['shank'])}",
            f'            <geom name="{side}_shank" type="capsule" fromto="0 0 0 0 0 {_f(-l1)}" '
            'size="0.04"/>',
            f'            <body name="{side}_foot" pos="0 0 {_f(-l1)}">',
            f'              <joint name="{names[3]}" axis="0 1 0" range="{_f(rng[3][0])} '
            f'{_f(rng[3][1])}"/>',
            f"              {_mj_inertial(g.legs['foot'])}",
            f'              <geom name="{side}_sole" type="box" pos="{_v(sole_centre)}" '
            f'size="{_v(0.5 * sole_size)}" rgba="0.2 0.2 0.2 1"/>',
            "            </body>",
            "          </body>",
            "        </body>",
            "      </body>",
        ]
    for side in C.SIDES:
        out += [
            f'      <body name="{side}_arm" pos="{_v(g.shoulders[side])}">',
            f"        {_mj_inertial(g.arm)}",
            f'        <geom name="{side}_arm" type="capsule" fromto="0 0 0 0 0 '
            f'{_f(-C.ARM_LENGTH)}" size="{_f(C.ARM_RADIUS)}"/>',
            "      </body>",
        ]
    out += ["    </body>", "  </worldbody>", "  <actuator>"]
    for k, name in enumerate(C.JOINT_NAMES):
        t = g.torque_limit[k]
        out.append(f'    <motor name="{name}" joint="{name}" ctrlrange="{_f(-t)} {_f(t)}"/>')
    out += ["  </actuator>", "</mujoco>", ""]
    return "\n".join(out)


def _urdf_link(name: str, part: Part, shapes: list[str]) -> str:
    geometry = "".join(shapes)
    return f'  <link name="{name}">{_urdf_inertial(part)}{geometry}</link>'


def _shape(kind: str, geometry: str, xyz: np.ndarray) -> str:
    return f'<{kind}><origin xyz="{_v(xyz)}" rpy="0 0 0"/><geometry>{geometry}</geometry></{kind}>'


def _both(geometry: str, xyz: np.ndarray) -> list[str]:
    return [_shape("visual", geometry, xyz), _shape("collision", geometry, xyz)]


def urdf_text(g: Geometry) -> str:
    l0, l1 = g.design.thigh_length, g.design.shank_length
    head_z = g.head_z
    sole_centre, sole_size = _sole_box()
    out = [
        '<?xml version="1.0"?>',
        "<!-- Kuafu humanoid generated by coadapt; floating base implied (root link base).",
        f"     Every revolute joint has a reflected rotor inertia (armature) of {_f(C.ARMATURE)} "
        "kg m^2",
        "     (rotor inertia x gear ratio^2, see the transmissions); URDF has no element for it. "
        "-->",
        '<robot name="kuafu">',
        _urdf_link(
            "base",
            g.base,
            _both(f'<box size="{_v(C.PELVIS_SIZE)}"/>', C.PELVIS_CENTRE)
            + _both(f'<box size="{_v(C.TORSO_SIZE)}"/>', C.TORSO_CENTRE)
            + _both(f'<sphere radius="{_f(C.HEAD_RADIUS)}"/>', np.array([0.0, 0.0, head_z])),
        ),
    ]
    joint_index = 0
    for side in C.SIDES:
        links = [f"{side}_hip_roll_link", f"{side}_thigh", f"{side}_shank", f"{side}_foot"]
        parents = ["base", *links[:3]]
        origins = [
            g.hips[side],
            np.zeros(3),
            np.array([0.0, 0.0, -l0]),
            np.array([0.0, 0.0, -l1]),
        ]
        axes = ["1 0 0", "0 1 0", "0 1 0", "0 1 0"]
        shapes = [
            _both('<sphere radius="0.06"/>', np.zeros(3)),
            _both(f'<cylinder radius="0.05" length="{_f(l0)}"/>', np.array([0.0, 0.0, -0.5 * l0])),
            _both(f'<cylinder radius="0.04" length="{_f(l1)}"/>', np.array([0.0, 0.0, -0.5 * l1])),
            _both(f'<box size="{_v(sole_size)}"/>', sole_centre),
        ]
        for k, j in enumerate(C.LEG_JOINTS):
            out.append(_urdf_link(links[k], g.legs[links[k].removeprefix(f"{side}_")], shapes[k]))
            i = joint_index + k
            out.append(
                f'  <joint name="{side}_{j}" type="revolute"><parent link="{parents[k]}"/><child '
                f'link="{links[k]}"/>'
                f'<origin xyz="{_v(origins[k])}" rpy="0 0 0"/><axis xyz="{axes[k]}"/>'
                f'<limit lower="{_f(g.lower[i])}" upper="{_f(g.upper[i])}" '
                f'effort="{_f(g.torque_limit[i])}" velocity="{_f(g.speed_limit[i])}"/>'
                f'<dynamics damping="{_f(C.JOINT_DAMPING)}" friction="0"/></joint>'
            )
        joint_index += 4
    for side in C.SIDES:
        out.append(
            _urdf_link(
                f"{side}_arm",
                g.arm,
                _both(
                    f'<cylinder radius="{_f(C.ARM_RADIUS)}" length="{_f(C.ARM_LENGTH)}"/>',
                    np.array([0.0, 0.0, -0.5 * C.ARM_LENGTH]),
                ),
            )
        )
        out.append(
            f'  <joint name="{side}_shoulder" type="fixed"><parent link="base"/><child '
            f'link="{side}_arm"/>'
            f'<origin xyz="{_v(g.shoulders[side])}" rpy="0 0 0"/></joint>'
        )
    for name in C.JOINT_NAMES:
        out.append(
            f'  <transmission name="{name}_transmission">'
            "<type>transmission_interface/SimpleTransmission</type>"
            f'<joint name="{name}">'
            "<hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>"
            "</joint>"
            f'<actuator name="{name}_motor">'
            f"<mechanicalReduction>{_f(C.GEAR_RATIO)}</mechanicalReduction>"
            "</actuator></transmission>"
        )
    out += ["</robot>", ""]
    return "\n".join(out)
