"""The design-aware gait reference (`task.gait.design_aware`, coadapt_core/task/gait.py): each
design's reference in units of its leg length, the clock by Froude scaling; off by default,
where the reference is the same for every design."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from coadapt_core.task.config import GaitConfig, TaskConfig
from coadapt_core.task.gait import clock_frequency, gait_scales, raibert_foot_targets


def _reference(scale=None, command=0.8):
    n = 2
    feet = torch.zeros(n, 2, 3)
    feet[..., 2] = -0.6
    phase = torch.tensor([[0.0, 0.5], [0.75, 0.25]])  # touchdown / lift-off; mid-swing / mid-stance
    cmd = torch.tensor([[command, 0.0, 0.0]] * n)
    return raibert_foot_targets(feet, phase, cmd, cmd.clone(), GaitConfig(), scale)


def test_scale_one_is_the_plain_reference_and_scales_stride_clip_swing_and_stance_time():
    plain = _reference()
    assert torch.allclose(_reference(torch.ones(2)), plain, atol=1e-7)
    # touchdown offset v T_st / 2 = 0.8 x (0.5 / 1.5) / 2 = 0.1333 m, inside the 0.15 m clip
    assert plain[0, 0, 0].item() == pytest.approx(0.8 * (0.5 / 1.5) / 2, abs=1e-6)
    long = _reference(torch.tensor([1.3, 1.3]))
    # a leg 1.3 x nominal: stance time x sqrt(1.3), offset 0.152 m, clip 0.195 m
    assert long[0, 0, 0].item() == pytest.approx(0.8 * (0.5 * math.sqrt(1.3) / 1.5) / 2, abs=1e-6)
    # the swing apex (mid-swing, full command gate) x 1.3: 0.08 -> 0.104 m above the stance foot
    assert (long[1, 0, 2] - long[1, 1, 2]).item() == pytest.approx(
        1.3 * (plain[1, 0, 2] - plain[1, 1, 2]).item(), rel=1e-5
    )
    # a fast command saturates the clip, which grows with the leg
    assert _reference(command=2.0)[0, 0, 0].item() == pytest.approx(0.15, abs=1e-6)
    assert _reference(torch.tensor([1.3, 1.3]), command=2.0)[0, 0, 0].item() == pytest.approx(
        0.195, abs=1e-6
    )
    assert _reference(torch.tensor([0.8, 0.8]), command=2.0)[0, 0, 0].item() == pytest.approx(
        0.12, abs=1e-6
    )


def test_froude_clock_and_the_setting_off_by_default():
    cfg = GaitConfig()
    assert not cfg.design_aware
    legs = torch.tensor([0.5, 0.658, 0.9])
    assert torch.equal(gait_scales(cfg, legs, 0.658), torch.ones(3))
    cfg.design_aware = True
    scale = gait_scales(cfg, legs, 0.658)
    assert scale.tolist() == pytest.approx([0.5 / 0.658, 1.0, 0.9 / 0.658], rel=1e-6)
    assert clock_frequency(cfg, scale).tolist() == pytest.approx(
        [1.5 * math.sqrt(0.658 / x) for x in (0.5, 0.658, 0.9)], rel=1e-6
    )


@pytest.mark.slow
def test_env_scales_each_design_by_its_hip_height_in_mujoco():
    from coadapt_plugins.robots.kuafu.robot import Kuafu
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    from coadapt_core.task.env import LocomotionEnv

    robot = Kuafu()
    designs = np.array([[0.6, 1.15], [1.0, 1.0], [1.4, 1.15]])
    heights = robot.hip_height(torch.tensor(designs, dtype=torch.float32)).numpy()
    for aware in (False, True):
        cfg = TaskConfig()
        cfg.gait.design_aware = aware
        cfg.commands.curriculum = False
        with MujocoSimulator(robot, designs, seed=0) as sim:
            env = LocomotionEnv(sim, robot, cfg)
            expected = heights / heights[1] if aware else np.ones(3)
            assert env.gait.scale.numpy() == pytest.approx(expected, rel=1e-5)
            if aware:  # thigh 0.6 and 1.4 at shank 1.15: legs 0.875 and 1.275 x nominal
                assert env.gait.scale.numpy() == pytest.approx([0.875, 1.0, 1.275], abs=0.01)
            env.set_commands(torch.tensor([[0.8, 0.0, 0.0]] * 3))
            env.reset()
            before = env.phase.clone()
            env.step(torch.zeros(3, env.num_actions))
            advance = torch.remainder(env.phase - before, 1.0).numpy()
            assert advance == pytest.approx(env.dt * 1.5 / np.sqrt(expected), rel=1e-4)
