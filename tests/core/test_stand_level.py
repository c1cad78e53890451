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
