"""Leg inverse kinematics (batched torch) against MuJoCo forward kinematics, and link
lengths of random designs through Pinocchio."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import torch
from coadapt_plugins.robots.kuafu import constants as C
from coadapt_plugins.robots.kuafu.validation import pinocchio_model


def ankle_relative_to_hip(model, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[2, 3] ankle centres relative to the hip centres and [2, 3, 3] foot orientations,
    base at the origin, upright (MuJoCo forward kinematics)."""
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = mujoco.MjData(mj)
    data.qpos[3] = 1.0
    data.qpos[7:15] = joints
    mujoco.mj_kinematics(mj, data)
    rel, rot = [], []
    for side in C.SIDES:
        rel.append(
            data.xpos[mj.body(f"{side}_foot").id] - data.xpos[mj.body(f"{side}_hip_roll_link").id]
        )
        rot.append(data.xmat[mj.body(f"{side}_foot").id].reshape(3, 3))
    return np.array(rel), np.array(rot)


def test_ik_places_the_ankle_where_asked(kuafu):
    rng = np.random.default_rng(7)
    designs = kuafu.design_space(mixed=True).sample(6, rng=rng)
    l_sum = 0.35 * (designs[:, 0] + designs[:, 1])
    feet = np.zeros((6, 2, 3))
    feet[..., 0] = rng.uniform(-0.12, 0.12, size=(6, 2))
    feet[..., 1] = rng.uniform(-0.06, 0.06, size=(6, 2))
    feet[..., 2] = -rng.uniform(0.8, 0.95, size=(6, 2)) * l_sum[:, None]
    q = kuafu.leg_inverse_kinematics(torch.as_tensor(designs), torch.as_tensor(feet))
    assert q.shape == (6, 8) and q.dtype == torch.float64
    for i in range(6):
        model = kuafu.build(designs[i])
        rel, rot = ankle_relative_to_hip(model, q[i].numpy())
        np.testing.assert_allclose(rel, feet[i], atol=1e-9)
        # the ankle cancels the sagittal pitch: the sole's x axis stays horizontal
        np.testing.assert_allclose(rot[:, 2, 0], 0.0, atol=1e-9)
        assert np.all(q[i, [2, 6]].numpy() >= 0)  # knee bends forward


def test_default_foot_positions_match_the_default_pose(kuafu):
    designs = np.array([[0.5, 0.5], [1.0, 1.0], [1.5, 0.7], [0.6, 1.4]])
    feet = kuafu.default_foot_positions(torch.as_tensor(designs))
    np.testing.assert_allclose(
        kuafu.hip_height(torch.as_tensor(designs)).numpy(), 0.94 * 0.35 * designs.sum(axis=1)
    )
    for i, design in enumerate(designs):
        model = kuafu.build(design)
        rel, _ = ankle_relative_to_hip(model, model.default_joint_pos)
        np.testing.assert_allclose(rel, feet[i].numpy(), atol=1e-12)
        # standing base height = sole depth + hip-to-ankle + hip drop below the base
        assert model.standing_base_height == pytest.approx(
            C.ANKLE_HEIGHT - feet[i, 0, 2].item() - C.HIP_OFFSET[2]
        )


def test_hip_roll_follows_the_lateral_offset(kuafu):
    designs = torch.tensor([[1.0, 1.0], [1.0, 1.0]], dtype=torch.float64)
    feet = kuafu.default_foot_positions(designs).clone()
    feet[0, 0, 1] = 0.05  # left foot outwards (+y)
    feet[1, 1, 1] = -0.05  # right foot outwards (-y)
    q = kuafu.leg_inverse_kinematics(designs, feet)
    assert q[0, 0] > 0.05 and q[1, 4] < -0.05  # abduction: +x rotation left, -x right
    assert q[0, 4] == 0.0 and q[1, 0] == 0.0


def test_unreachable_targets_are_clamped_not_nan(kuafu):
    designs = torch.tensor([[1.0, 1.0], [1.5, 0.5]], dtype=torch.float64)
    feet = torch.zeros(2, 2, 3, dtype=torch.float64)
    feet[0, :, 2] = -2.0  # beyond full extension
    feet[1, :, 2] = -0.01  # inside the inner radius |l0 - l1|
    q = kuafu.leg_inverse_kinematics(designs, feet)
    assert torch.isfinite(q).all()
    assert q[0, 2].item() == pytest.approx(0.0, abs=1e-3)  # straight knee
    assert q[1, 2].item() == pytest.approx(np.pi, abs=1e-3)  # fully folded


def test_random_designs_have_link_lengths_0_35_xi_in_pinocchio(kuafu):
    designs = np.vstack(
        [kuafu.design_space().sample(6, rng=3), kuafu.design_space(True).sample(4, rng=4)[:, :2]]
    )
    for design in designs:
        model = kuafu.build(design)
        pmodel = pinocchio_model(model)
        pdata = pmodel.createData()
        q = pin.neutral(pmodel)
        pin.forwardKinematics(pmodel, pdata, q)
        for side in C.SIDES:
            pos = {
                j: pdata.oMi[pmodel.getJointId(f"{side}_{j}")].translation
                for j in ("hip_pitch", "knee", "ankle")
            }
            assert np.linalg.norm(pos["knee"] - pos["hip_pitch"]) == pytest.approx(
                0.35 * design[0], abs=1e-3
            )
            assert np.linalg.norm(pos["ankle"] - pos["knee"]) == pytest.approx(
                0.35 * design[1], abs=1e-3
            )
