"""Reward terms of the locomotion task on hand-made states, and the gait reference."""

from __future__ import annotations

import math

import pytest
import torch

from coadapt_core.task.config import (
    EXTRA_REWARD_WEIGHTS,
    PAPER_REWARD_WEIGHTS,
    GaitConfig,
    RewardConfig,
)
from coadapt_core.task.gait import (
    leg_phases,
    raibert_foot_targets,
    stance_triangle,
    von_mises_height,
)
from coadapt_core.task.rewards import RewardInputs, combine, compute_terms


def inputs(**over) -> RewardInputs:
    n, j = 1, 8
    base = dict(
        command=torch.tensor([[0.5, 0.0, 0.5]]),
        base_lin_vel=torch.tensor([[0.0, 0.0, 0.2]]),
        base_ang_vel=torch.tensor([[0.1, 0.2, 0.0]]),
        projected_gravity=torch.tensor([[0.1, 0.2, -0.97]]),
        joint_pos=torch.full((n, j), 0.1),
        default_joint_pos=torch.zeros(n, j),
        joint_acc=torch.full((n, j), 100.0),
        joint_torque=torch.full((n, j), 10.0),
        action=torch.full((n, j), 0.5),
        last_action=torch.full((n, j), 0.2),
        raibert_targets=torch.full((n, j), 0.3),
        foot_contact=torch.tensor([[True, False]]),
        expected_stance=torch.tensor([[True, True]]),
        first_contact=torch.tensor([[True, False]]),
        air_time=torch.tensor([[0.4, 0.1]]),
        moving_command=torch.tensor([True]),
        terminated=torch.tensor([False]),
    )
    base.update(over)
    return RewardInputs(**base)


def test_every_term_on_a_hand_made_state() -> None:
    terms = compute_terms(inputs(), RewardConfig())
    expected = {
        "tracking_lin_vel": math.exp(-4 * 0.25),  # |(0.5, 0) - (0, 0)|^2 = 0.25
        "tracking_ang_vel": math.exp(-4 * 0.25),  # (0.5 - 0)^2
        "lin_vel_z": 0.04,
        "ang_vel_xy": 0.01 + 0.04,
        "torques": 8 * 100.0,
        "orientation": 0.01 + 0.04,
        "dof_acc": 8 * 1e4,
        "action_rate": 8 * 0.09,
        "default_pos": 8 * 0.01,
        "raibert": 8 * 0.04,
        "contact_match": (1.0 - 0.3) / 2,  # left matches; right is up while the clock wants it down
        "feet_air_time": 0.4 - 0.25,  # touchdown of the left foot after 0.4 s in the air
        "termination": 0.0,
    }
    assert set(terms) == set(expected)
    for name, value in expected.items():
        assert float(terms[name][0]) == pytest.approx(value, rel=1e-5), name


def test_weights_are_the_papers_table_1() -> None:
    assert PAPER_REWARD_WEIGHTS == {
        "tracking_lin_vel": 2.0,
        "tracking_ang_vel": 1.5,
        "lin_vel_z": -1.25,
        "ang_vel_xy": -0.1,
        "torques": -5e-6,
        "orientation": -10.0,
        "dof_acc": -2e-7,
        "action_rate": -0.025,
        "default_pos": -0.2,
        "raibert": -0.75,
    }
    assert set(EXTRA_REWARD_WEIGHTS) == {"contact_match", "feet_air_time", "termination"}
    assert RewardConfig().weights == {**PAPER_REWARD_WEIGHTS, **EXTRA_REWARD_WEIGHTS}


def test_air_time_pays_nothing_under_a_zero_command() -> None:
    terms = compute_terms(inputs(moving_command=torch.tensor([False])), RewardConfig())
    assert float(terms["feet_air_time"][0]) == 0.0


def test_combine_scales_by_dt_clips_at_zero_then_adds_termination() -> None:
    config = RewardConfig(
        weights={"tracking_lin_vel": 2.0, "orientation": -10.0, "termination": -200.0}
    )
    x = inputs(terminated=torch.tensor([True]), projected_gravity=torch.tensor([[0.5, 0.0, -0.8]]))
    terms = compute_terms(x, config)
    total, weighted = combine(terms, config, dt=0.02)
    assert float(weighted["tracking_lin_vel"][0]) == pytest.approx(0.02 * 2.0 * math.exp(-1.0))
    assert float(weighted["orientation"][0]) == pytest.approx(0.02 * -10.0 * 0.25)
    # 0.0294 - 0.05 < 0 is clipped to 0, then the fall costs 0.02 x 200
    assert float(total[0]) == pytest.approx(-4.0)
    config.clip_at_zero = False
    total, _ = combine(terms, config, dt=0.02)
    assert float(total[0]) == pytest.approx(0.02 * (2.0 * math.exp(-1.0) - 2.5) - 4.0, rel=1e-5)


def test_unknown_reward_term_is_a_one_line_user_error() -> None:
    from coadapt_core.errors import UserError

    with pytest.raises(UserError, match="unknown term"):
        RewardConfig(weights={"speed_bonus": 1.0})


def test_gait_profile_triangle_and_von_mises_apex() -> None:
    phase = torch.tensor([0.0, 0.25, 0.5, 0.75])
    assert stance_triangle(phase).tolist() == pytest.approx([1.0, 0.0, -1.0, 0.0])
    heights = von_mises_height(phase, apex=0.08, kappa=4.0)
    assert float(heights[3]) == pytest.approx(0.08)  # apex at mid-swing
    assert float(heights[1]) == pytest.approx(0.08 * math.exp(-8.0))  # ~0 at mid-stance
    legs = leg_phases(torch.tensor([0.1]), 2)
    assert legs[0].tolist() == pytest.approx([0.1, 0.6])


def test_raibert_placement_moves_the_stance_foot_back_at_the_commanded_speed() -> None:
    gait = GaitConfig()
    feet = torch.tensor([[[0.0, 0.0, -0.65], [0.0, 0.0, -0.65]]])
    command = torch.tensor([[0.5, 0.0, 0.0]])
    t_stance = 0.5 / gait.frequency
    touchdown = raibert_foot_targets(feet, torch.tensor([[0.0, 0.5]]), command, command, gait)
    # left touches down ahead by v T_st / 2; right lifts off behind by the same
    assert float(touchdown[0, 0, 0]) == pytest.approx(0.5 * t_stance / 2)
    assert float(touchdown[0, 1, 0]) == pytest.approx(-0.5 * t_stance / 2)
    mid_swing = raibert_foot_targets(feet, torch.tensor([[0.25, 0.75]]), command, command, gait)
    assert float(mid_swing[0, 1, 2]) == pytest.approx(-0.65 + gait.swing_height)
    assert float(mid_swing[0, 0, 2]) == pytest.approx(-0.65, abs=1e-3)


def test_raibert_targets_equal_the_default_pose_at_zero_command(fake_robot) -> None:
    designs = torch.tensor([[1.0, 1.0], [0.6, 1.4]])
    feet = fake_robot.default_foot_positions(designs)
    for phase in (0.1, 0.6, 0.9):
        targets = raibert_foot_targets(
            feet,
            leg_phases(torch.full((2,), phase), 2),
            torch.zeros(2, 3),
            torch.zeros(2, 3),
            GaitConfig(),
        )
        assert torch.allclose(targets, feet)
    q_star = fake_robot.leg_inverse_kinematics(designs, feet)
    assert torch.allclose(q_star, torch.tensor([[0.0, -0.4, 0.8, -0.4] * 2] * 2), atol=1e-5)


def test_kuafu_raibert_targets_at_zero_command_are_its_standing_pose() -> None:
    import numpy as np

    from coadapt_core.plugins import get_registry

    registry = get_registry()
    robot = registry.get("robot", "kuafu")()
    for design in (np.array([1.0, 1.0]), np.array([0.6, 1.3])):
        designs = torch.tensor(design[None, :], dtype=torch.float32)
        feet = robot.default_foot_positions(designs)
        targets = raibert_foot_targets(
            feet,
            leg_phases(torch.tensor([0.3]), 2),
            torch.zeros(1, 3),
            torch.zeros(1, 3),
            GaitConfig(),
        )
        q_star = robot.leg_inverse_kinematics(designs, targets)[0].numpy()
        assert np.allclose(q_star, robot.build(design).default_joint_pos, atol=1e-4)
