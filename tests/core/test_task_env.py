"""LocomotionEnv on the fake simulator: observation layout, noise, design input, commands,
termination, timeouts and objective metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from coadapt_core.objective import Objective, StepBatch
from coadapt_core.task.commands import CommandSampler
from coadapt_core.task.config import CommandConfig, NoiseConfig, TaskConfig
from coadapt_core.task.env import LocomotionEnv


class SquaredTorque(Objective):
    name = "sq_torque"
    display_name = "squared torque"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return (step.joint_torque**2).sum(-1)


class SpeedError(Objective):
    name = "speed_error"
    display_name = "speed error"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return step.linear_tracking_error


def quiet_task(**over) -> TaskConfig:
    task = TaskConfig(noise=NoiseConfig(enabled=False))
    for key, value in over.items():
        setattr(task, key, value)
    return task


def test_observation_has_70_values_in_the_documented_order(fake_robot, fake_sim_factory) -> None:
    env = LocomotionEnv(fake_sim_factory(4), fake_robot, quiet_task())
    obs, critic, _ = env.reset()
    assert obs.shape == (4, 70) and env.num_obs == 70
    expected = [
        ("base_lin_vel", 0, 3),
        ("base_ang_vel", 3, 6),
        ("projected_gravity", 6, 9),
        ("command", 9, 12),
        ("joint_pos", 12, 20),
        ("joint_vel", 20, 28),
        ("action_history", 28, 68),
        ("clock", 68, 70),
    ]
    assert [(k, s.start, s.stop) for k, s in env.obs_slices.items()] == expected
    actions = torch.full((4, 8), 0.4)
    obs, critic, *_ = env.step(actions)
    s = env.obs_slices
    assert torch.allclose(obs[:, s["command"]], env.command)
    assert torch.allclose(
        obs[:, s["projected_gravity"]], torch.tensor([0.0, 0.0, -1.0]).expand(4, 3)
    )
    # joints move halfway to target (fake sim): 0.25 x 0.4 x 0.5 = 0.05 rad from the default
    assert torch.allclose(obs[:, s["joint_pos"]], torch.full((4, 8), 0.05), atol=1e-6)
    assert torch.allclose(obs[:, 28:36], actions)  # newest action first
    assert torch.allclose(obs[:, 36:68], torch.zeros(4, 32))
    clock = obs[:, s["clock"]]
    assert torch.allclose(clock.pow(2).sum(-1), torch.ones(4))
    # critic = clean observation + 1 height + 2 contacts + 2 foot heights + 8 parameters
    assert critic.shape == (4, 70 + 13) and env.num_critic_obs == 83
    assert torch.allclose(critic[:, :70], obs)
    assert critic[0, 70] == pytest.approx(float(env.state.base_pos[0, 2]))
    assert critic[0, 75] == pytest.approx(1.0)  # friction, nominal without randomization


def test_noise_is_bounded_by_table_3(fake_robot, fake_sim_factory) -> None:
    env = LocomotionEnv(
        fake_sim_factory(256), fake_robot, TaskConfig(noise=NoiseConfig(kind="uniform"))
    )
    obs, critic, _ = env.reset()
    diff = (obs - critic[:, :70]).abs().amax(0)
    s = env.obs_slices
    for name, scale in (
        ("base_lin_vel", 0.01),
        ("base_ang_vel", 0.2),
        ("projected_gravity", 0.05),
        ("joint_pos", 0.01),
        ("joint_vel", 1.5),
    ):
        assert float(diff[s[name]].max()) <= scale + 1e-6
        assert float(diff[s[name]].max()) > 0.8 * scale  # uniform noise reaches near its bound
    assert float(diff[s["command"]].max()) == 0.0 and float(diff[s["clock"]].max()) == 0.0


def test_design_input_is_normalised_to_the_design_space(fake_robot, fake_sim_factory) -> None:
    designs = np.array([[0.5, 1.5], [1.0, 1.0], [1.25, 0.75]])
    env = LocomotionEnv(fake_sim_factory(designs=designs), fake_robot, quiet_task())
    _, _, design = env.reset()
    assert torch.allclose(design, torch.tensor([[-1.0, 1.0], [0.0, 0.0], [0.5, -0.5]]))


def test_commands_have_zeros_threshold_and_a_widening_curriculum() -> None:
    gen = torch.Generator().manual_seed(0)
    sampler = CommandSampler(
        CommandConfig(zero_share=0.1, zero_threshold=0.1, yaw_range=(0.0, 0.0)), "cpu", gen
    )
    cmd = sampler.sample(20_000)
    assert float(cmd[:, 0].max()) <= 0.3 + 1e-6 and float(cmd[:, 0].min()) >= -0.3 - 1e-6
    assert float(cmd[:, 1:].abs().max()) == 0.0
    moving = cmd[:, 0] != 0
    assert float(cmd[moving, 0].abs().min()) >= 0.1
    # zeros: 10 % forced plus the band |vx| < 0.1, i.e. 1/3 of U(-0.3, 0.3) -> about 40 %
    assert 0.36 < float((~moving).float().mean()) < 0.44
    assert not sampler.update_curriculum(0.5)
    assert sampler.update_curriculum(0.9) and sampler.limit == pytest.approx(0.4)
    for _ in range(20):
        sampler.update_curriculum(0.9)
    assert sampler.limit == pytest.approx(1.25)
    assert sampler.ranges()[0] == (-0.5, 1.25)


def test_fall_terminates_and_resets_while_timeout_only_truncates(
    fake_robot, fake_sim_factory
) -> None:
    sim = fake_sim_factory(2)
    env = LocomotionEnv(sim, fake_robot, quiet_task(episode_seconds=0.2))
    env.reset()
    assert env.max_episode_length == 10
    # bending both knees by 2.5 rad (x 0.3 m/rad in the fake) drops the base below half height
    actions = torch.zeros(2, 8)
    actions[0, [2, 6]] = 10.0
    steps = 0
    while steps < 10:
        res = env.step(actions)
        steps += 1
        if bool(res.done[0]):
            break
    assert bool(res.info["terminated"][0]) and not bool(res.timeout[0])
    assert env.episode_length[0] == 0  # restarted
    assert res.info["final_critic_obs"][0, 70] < 0.5 * env.standing_height[0]
    assert res.critic_obs[0, 70] == pytest.approx(float(env.standing_height[0]))
    assert res.reward[0] < -3.9  # termination penalty 200 x dt after clipping at zero
    for _ in range(10 - steps):
        res = env.step(torch.zeros(2, 8))
    assert bool(res.timeout[1]) and bool(res.done[1]) and not bool(res.info["terminated"][1])
    assert res.info["episode"]["count"] >= 1


def test_metrics_come_from_each_objective_in_order(fake_robot, fake_sim_factory) -> None:
    env = LocomotionEnv(
        fake_sim_factory(3), fake_robot, quiet_task(), [SquaredTorque(), SpeedError()]
    )
    env.reset()
    env.set_commands(torch.tensor([0.5, 0.0, 0.0]))
    res = env.step(torch.full((3, 8), 0.2))
    metrics = res.info["metrics"]
    assert metrics.shape == (3, 2)
    torque = env.state.joint_torque
    assert torch.allclose(metrics[:, 0], (torque**2).sum(-1))
    speed = res.info["base_lin_vel"][:, 0]
    assert torch.allclose(metrics[:, 1], (0.5 - speed).abs(), atol=1e-6)
    assert env.metric_names == ["sq_torque", "speed_error"]


def test_zero_command_freezes_the_clock_with_both_feet_in_stance(
    fake_robot, fake_sim_factory
) -> None:
    env = LocomotionEnv(fake_sim_factory(2), fake_robot, quiet_task())
    env.reset()
    env.set_commands(torch.zeros(3))
    phase = env.phase.clone()
    for _ in range(5):
        env.step(torch.zeros(2, 8))
    assert torch.equal(env.phase, phase)
    q_star, stance = env.raibert_joint_targets(env.command, torch.zeros(2, 3))
    assert bool(stance.all())
    assert torch.allclose(q_star, env.default_joint_pos, atol=1e-5)
    env.set_commands(torch.tensor([0.5, 0.0, 0.0]))
    env.step(torch.zeros(2, 8))
    assert torch.allclose(env.phase, torch.full((2,), 0.25 + 0.02 * 1.5))
    assert math.isclose(env.dt, 0.02)


def test_curriculum_widens_only_on_a_full_window_of_well_tracked_upright_episodes() -> None:
    gen = torch.Generator().manual_seed(0)
    sampler = CommandSampler(CommandConfig(curriculum_window=4), "cpu", gen)
    assert not sampler.record_episodes(2, 0, 95.0, 100.0, 40.0)  # window not full yet
    assert sampler.record_episodes(2, 0, 90.0, 100.0, 40.0) and sampler.limit == pytest.approx(0.4)
    assert not sampler.record_episodes(4, 4, 190.0, 200.0, 80.0)  # 0.05 falls/s > 0.03
    assert not sampler.record_episodes(4, 0, 150.0, 200.0, 80.0)  # tracking 0.75 < 0.8
    assert sampler.limit == pytest.approx(0.4)
    # one fall in 80 s of 20 s episodes (a quarter of the episodes fell) no longer blocks it
    assert sampler.record_episodes(4, 1, 190.0, 200.0, 80.0) and sampler.limit == pytest.approx(0.5)


def test_default_commands_cover_the_papers_range_and_yaw_rates_once_the_curriculum_is_wide() -> (
    None
):
    """Issue 17: training draws vx over [-0.5, 1.25] m/s and yaw rates over [-1, 1] rad/s (the
    yaw range was (0, 0), so no policy ever saw a turn command)."""
    sampler = CommandSampler(CommandConfig(zero_share=0.0), "cpu", torch.Generator().manual_seed(1))
    assert sampler.ranges()[2] == (-0.3, 0.3)  # the curriculum's first box limits yaw too
    while sampler.update_curriculum(1.0):
        pass
    assert sampler.ranges() == [(-0.5, 1.25), (0.0, 0.0), (-1.0, 1.0)]
    cmd = sampler.sample(20_000)
    assert -0.5 <= float(cmd[:, 0].min()) < -0.49 and 1.24 < float(cmd[:, 0].max()) <= 1.25
    assert -1.0 <= float(cmd[:, 2].min()) < -0.99 and 0.99 < float(cmd[:, 2].max()) <= 1.0
    turning = cmd[:, 2].abs() >= 0.1
    assert 0.88 < float(turning.float().mean()) < 0.92  # |yaw| < 0.1 of U(-1, 1) becomes 0
    # vx and yaw are drawn independently: turns happen at every speed, standing turns too
    assert float(((cmd[:, 0] == 0) & turning).float().mean()) > 0.04


def test_a_turn_in_place_command_runs_the_gait_clock_and_pays_for_yaw_tracking(
    fake_robot, fake_sim_factory
) -> None:
    env = LocomotionEnv(fake_sim_factory(2), fake_robot, quiet_task())
    env.reset()
    env.set_commands(torch.tensor([0.0, 0.0, 0.5]))
    phase = env.phase.clone()
    res = env.step(torch.zeros(2, 8))
    assert torch.allclose(env.phase, phase + 0.02 * 1.5)  # a yaw command alone is a moving command
    _, stance = env.raibert_joint_targets(env.command, torch.zeros(2, 3))
    assert not bool(stance.all())  # one foot swings
    # the observation carries the yaw command (slice 9:12) and the yaw rate (3:6)
    assert torch.allclose(res.obs[:, 11], torch.full((2,), 0.5))
