"""The standing pose solved per design keeps every joint inside its range and the soles
level (`plugins/robots/specs/level.py`): pybullet_data's MJCF humanoid, taken by `coadapt
robot new` with no edit, at its long-thigh short-shank corner (thigh 1.3, shank 0.7), where
its feet 0.75 of the leg's length under the hips put each `ankle_y` 23 deg past its -50 deg
limit (clipped: the foot toe-down, and the robot tipped over backward)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import torch
from coadapt_plugins.robots.specs.level import MARGIN, TILT
from coadapt_plugins.robots.specs.new import write_robot
from coadapt_plugins.robots.specs.robot import spec_robot_class

pytest.importorskip("pybullet_data")
import pybullet_data

CORNER = np.array([1.3, 0.7])


@pytest.fixture(scope="module")
def humanoid(tmp_path_factory):
    source = f"{pybullet_data.getDataPath()}/mjcf/humanoid.xml"
    folder, _, _ = write_robot("humanoid", source, tmp_path_factory.mktemp("robots"))
    return spec_robot_class(folder)()


def _foot_tilts(model, pose: np.ndarray) -> list[float]:
    """Each foot body's turn (rad) from its orientation in the file (every joint at 0), the
    base upright, in MuJoCo."""
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = mujoco.MjData(compiled)
    feet = [compiled.body(f).id for f in model.foot_bodies]
    mujoco.mj_kinematics(compiled, data)
    flat = data.xmat[feet].reshape(-1, 3, 3).copy()
    for name, angle in zip(model.joint_names, pose, strict=True):
        data.qpos[compiled.jnt_qposadr[compiled.joint(name).id]] = angle
    mujoco.mj_kinematics(compiled, data)
    turned = data.xmat[feet].reshape(-1, 3, 3)
    cos = [0.5 * (np.trace(a.T @ b) - 1.0) for a, b in zip(flat, turned, strict=True)]
    return [float(np.arccos(np.clip(c, -1.0, 1.0))) for c in cos]


@pytest.mark.slow
def test_the_long_thigh_corner_keeps_its_joints_in_range_and_its_soles_level(humanoid):
    model = humanoid.build(CORNER)
    built, kin = humanoid._built, humanoid._built.kinematics
    lower, upper = model.joint_lower, model.joint_upper
    design = torch.as_tensor(CORNER[None])
    ankles = [model.joint_names.index(f"{side}_ankle_y") for side in ("left", "right")]
    # the old solve: the IK's answer at 0.75 of the leg's length, clipped at the limits
    old = kin.inverse(design, built.stand_targets(design, level=False))[0].numpy()
    assert np.all(old[ankles] < lower[ankles] - 0.3)  # -72.6 deg against a -50 deg limit
    clipped = np.clip(old, lower, upper)
    assert min(_foot_tilts(model, clipped)) > 0.3  # toe-down by 22.6 deg
    # the solve: the IK's answer, every joint inside its range, the legs' MARGIN inside
    targets = built.stand_targets(design)
    pose = model.default_joint_pos
    np.testing.assert_array_equal(pose, kin.inverse(design, targets)[0].numpy())
    legs = kin.chain.joint_index[kin.chain.joint_index >= 0].numpy()
    assert np.all((pose > lower) & (pose < upper))
    assert np.all(pose[legs] >= lower[legs] + MARGIN) and np.all(pose[legs] <= upper[legs] - MARGIN)
    assert max(_foot_tilts(model, pose)) <= TILT
    # the feet still under their hips, higher: 0.88 of the leg's length
    foot, _, hip, _, _ = kin.forward(kin.scales(design), kin.leg_angles(torch.tensor(pose[None])))
    np.testing.assert_allclose((foot - hip).numpy(), targets.numpy(), atol=1e-6)
    assert torch.all(targets[..., 0] == 0.0)
    share = 0.75 * targets[0, :, 2] / built.stand_targets(design, level=False)[0, :, 2]
    assert torch.allclose(share, torch.tensor(0.88, dtype=torch.float64))
    # the gait's default feet are the same targets (the pose the policy is trained around)
    assert torch.equal(humanoid.default_foot_positions(design), targets)


#: a biped as a user might write it: each hip three stacked hinges (yaw, roll, pitch) in the
#: thigh body, a knee, an ankle in the foot body, no keyframe. Every joint at 0 is a straight
#: leg, the leg IK's singular point: bending the last hinge (the ankle) does not leave it.
STRAIGHT_BIPED = """<mujoco model="straight_biped">
  <compiler angle="radian" autolimits="true"/>
  <default><joint damping="0.5" armature="0.02"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="pelvis" pos="0 0 0.6">
      <freejoint/>
      <inertial pos="0 0 0" mass="9" diaginertia="0.08 0.06 0.07"/>
      <geom type="box" size="0.08 0.12 0.05"/>
      {legs}
    </body>
  </worldbody>
  <actuator>{motors}</actuator>
</mujoco>
"""
LEG = """<body name="{s}_thigh" pos="0 {y} -0.05">
        <joint name="{s}_hip_yaw" axis="0 0 1" range="-0.5 0.5"/>
        <joint name="{s}_hip_roll" axis="1 0 0" range="-0.5 0.5"/>
        <joint name="{s}_hip_pitch" axis="0 1 0" range="-1.5 1.0"/>
        <inertial pos="0 0 -0.12" mass="1.5" diaginertia="0.008 0.008 0.001"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.24" size="0.03"/>
        <body name="{s}_shin" pos="0 0 -0.24">
          <joint name="{s}_knee" axis="0 1 0" range="-2.5 2.5"/>
          <inertial pos="0 0 -0.12" mass="0.8" diaginertia="0.004 0.004 0.0005"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.24" size="0.025"/>
          <body name="{s}_foot" pos="0 0 -0.24">
            <joint name="{s}_ankle" axis="0 1 0" range="-0.8 0.8"/>
            <inertial pos="0.02 0 -0.02" mass="0.3" diaginertia="0.0005 0.0005 0.0002"/>
            <geom type="box" pos="0.02 0 -0.02" size="0.08 0.04 0.015"/>
          </body>
        </body>
      </body>"""


def test_straight_legs_whose_last_hinge_is_an_ankle_get_a_bent_knee_and_level_soles(tmp_path):
    """robot new's standing solve bends the knee of a leg the first starts left straight (it
    used to leave both feet at 0, the knees locked straight); the soles stay as the file has
    them, and the robot stands under joint PD at the nominal design and the corners."""
    hinges = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle")
    text = STRAIGHT_BIPED.format(
        legs="\n      ".join(LEG.format(s=s, y=y) for s, y in (("left", 0.09), ("right", -0.09))),
        motors="".join(
            f'<motor joint="{s}_{j}" ctrlrange="-60 60"/>'
            for s in ("left", "right")
            for j in hinges
        ),
    )
    source = tmp_path / "biped.xml"
    source.write_text(text)
    folder, notes, _ = write_robot("straight", source, tmp_path / "robots")
    assert any("solved with 2 of 2 feet" in n for n in notes), notes
    assert any("stand 3 s under joint PD" in n for n in notes), notes
    robot = spec_robot_class(folder)()
    model = robot.build(robot.nominal_design())
    pose = dict(zip(model.joint_names, model.default_joint_pos, strict=True))
    for side in ("left", "right"):
        assert pose[f"{side}_knee"] > 1.0  # bent (1.45 rad), the knee in front
        # the sole level: the pitch hinges' angles cancel
        assert abs(pose[f"{side}_hip_pitch"] + pose[f"{side}_knee"] + pose[f"{side}_ankle"]) < TILT
    assert max(_foot_tilts(model, model.default_joint_pos)) <= TILT
    # the feet 0.75 of the leg's length (0.48 m) under the hips
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = mujoco.MjData(compiled)
    for name, angle in pose.items():
        data.qpos[compiled.jnt_qposadr[compiled.joint(name).id]] = angle
    mujoco.mj_kinematics(compiled, data)
    for side in ("left", "right"):
        drop = (
            data.xpos[compiled.body(f"{side}_thigh").id]
            - data.xpos[compiled.body(f"{side}_foot").id]
        )
        assert drop[2] == pytest.approx(0.75 * 0.48, abs=0.01)
