"""The PPO learner: pseudo-critic targets and isolation, learning on the fake simulator,
checkpoints and weight exports."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.pseudo_critics import discounted_average_targets
from coadapt_core.learning.trainer import Trainer
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.task.config import CommandConfig, NoiseConfig, TaskConfig


class SquaredTorque(Objective):
    name = "sq_torque"
    display_name = "squared torque"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return 1e-4 * (step.joint_torque**2).sum(-1)


class SpeedError(Objective):
    name = "speed_error"
    display_name = "speed error"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return step.linear_tracking_error**2


def small_config(**over) -> TrainConfig:
    base = dict(
        num_designs=2,
        agents_per_design=16,
        steps_per_env=16,
        hidden=(64, 64),
        epochs=3,
        minibatches=2,
        seed=0,
        torch_threads=1,
    )
    base.update(over)
    return TrainConfig(**base)


def make_trainer(
    fake_robot, fake_sim_cls, config: TrainConfig | None = None, objectives=None, task=None
) -> Trainer:
    task = task or TaskConfig(noise=NoiseConfig(enabled=False))
    objectives = [SquaredTorque(), SpeedError()] if objectives is None else objectives
    return Trainer(
        fake_robot,
        fake_sim_cls,
        objectives,
        train_config=config or small_config(),
        task_config=task,
    )


def test_pseudo_targets_are_the_discounted_average_of_the_metric() -> None:
    metrics = torch.full((3, 5, 2), 2.5)  # [N, T, M]
    value = torch.full((3, 5, 2), 2.5)
    done = torch.zeros(3, 5, 1, dtype=torch.bool)
    target = discounted_average_targets(metrics, value, done, gamma=0.99, lam=0.95)
    assert torch.allclose(target, torch.full_like(target, 2.5))  # scale = the per-step metric
    # a lone step with no future value: (1 - gamma) P; an episode end bootstraps from V(final)
    metrics = torch.tensor([[[1.0], [0.0]]])
    value_next = torch.tensor([[[10.0], [0.0]]])
    done = torch.tensor([[[True], [False]]])
    target = discounted_average_targets(metrics, value_next, done, gamma=0.9, lam=1.0)
    assert float(target[0, 0, 0]) == pytest.approx(0.1 * 1.0 + 0.9 * 10.0)
    assert float(target[0, 1, 0]) == pytest.approx(0.0)


def test_pseudo_critics_get_no_gradient_from_the_policy_loss(fake_robot, fake_sim_cls) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0], [0.7, 1.2]]))
    ppo, env = trainer.ppo, trainer.env
    obs, critic, design = env.reset()
    for _ in range(4):
        actions = ppo.act(obs, critic, design)
        res = env.step(actions)
        ppo.process_env_step(
            res.reward,
            res.done,
            res.timeout,
            res.info["final_critic_obs"],
            res.design_obs,
            res.info["metrics"],
        )
        obs, critic, design = res.obs, res.critic_obs, res.design_obs
    batch = ppo.compute_returns().reshape(-1)
    out = ppo.loss(batch)
    (out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]).backward()
    assert all(p.grad is None for p in ppo.pseudo_critic.parameters())
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in ppo.actor_net.parameters())
    assert not any(p is q for p in ppo.pseudo_critic.parameters() for q in ppo.loss.parameters())
    for p in ppo.actor_net.parameters():
        p.grad = None
    # ... and the pseudo-critic regression sends nothing to the actor
    pred = ppo.pseudo_critic(batch["critic_obs"], batch["design_obs"])
    torch.nn.functional.mse_loss(pred, batch["pseudo_target"]).backward()
    assert all(p.grad is None for p in ppo.actor_net.parameters())
    assert all(p.grad is not None for p in ppo.pseudo_critic.parameters())
    assert batch["pseudo_target"].shape == (2 * 16 * 4, 2)


@pytest.mark.slow
def test_short_training_raises_the_mean_reward(fake_robot, fake_sim_cls) -> None:
    # forward commands of 0.5-1 m/s: standing still tracks badly, so there is reward to gain
    task = TaskConfig(
        noise=NoiseConfig(enabled=False),
        commands=CommandConfig(curriculum=False, vx_range=(0.5, 1.0), zero_share=0.0),
    )
    trainer = make_trainer(fake_robot, fake_sim_cls, small_config(steps_per_env=24), task=task)
    trainer.set_designs(np.array([[1.0, 1.0], [1.0, 1.0]]))
    rewards, errors, pseudo_losses = [], [], []

    def record(stats) -> None:
        rewards.append(stats.mean_reward)
        errors.append(stats.tracking_error)
        pseudo_losses.append(stats.losses["loss_pseudo"])

    trainer.learn(30, record)
    first, last = np.mean(rewards[:3]), np.mean(rewards[-3:])
    assert last > first + 0.01, (first, last)  # measured 0.017 -> 0.041
    assert np.mean(errors[-3:]) < 0.5 * np.mean(errors[:3])  # measured 0.84 -> 0.24 m/s
    assert trainer.total_steps == 30 * 2 * 16 * 24


def test_checkpoint_round_trip_gives_identical_actions(fake_robot, fake_sim_cls, tmp_path) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0], [0.6, 1.4]]))
    trainer.learn(2)
    path = trainer.save(tmp_path / "ckpt.pt")
    obs, _, design = trainer.env.reset()
    expected = trainer.ppo.act_inference(obs, design)

    restored = make_trainer(fake_robot, fake_sim_cls, small_config(seed=7))
    restored.load(path)
    assert restored.iteration == 2 and restored.total_steps == trainer.total_steps
    assert torch.equal(restored.ppo.act_inference(obs, design), expected)
    assert torch.equal(restored.ppo.obs_norm.mean, trainer.ppo.obs_norm.mean)
    assert restored.ppo.learning_rate == trainer.ppo.learning_rate
    saved = trainer.ppo.optimizer.state_dict()["state"]
    loaded = restored.ppo.optimizer.state_dict()["state"]
    assert torch.equal(saved[0]["exp_avg"], loaded[0]["exp_avg"])
    # resume continues the counters
    restored.set_designs(np.array([[1.0, 1.0], [0.6, 1.4]]))
    restored.learn(1)
    assert restored.iteration == 3


def test_weights_export_is_small_float32_and_acts_the_same(
    fake_robot, fake_sim_cls, tmp_path
) -> None:
    config = small_config(hidden=(512, 256, 128))
    trainer = make_trainer(fake_robot, fake_sim_cls, config)
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.learn(1)
    weights = trainer.export_weights(tmp_path / "policy.pt")
    full = trainer.save(tmp_path / "full.pt")
    assert weights.stat().st_size < 6e6 < full.stat().st_size
    state = torch.load(weights, weights_only=True)
    assert all(t.dtype == torch.float32 for t in state["ppo"]["actor"].values())
    restored = make_trainer(fake_robot, fake_sim_cls, small_config(hidden=(512, 256, 128)))
    restored.load(weights)
    obs, _, design = trainer.env.reset()
    assert torch.equal(
        restored.ppo.act_inference(obs, design), trainer.ppo.act_inference(obs, design)
    )


def test_pseudo_critics_follow_objectives_by_name_on_load(
    fake_robot, fake_sim_cls, tmp_path
) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.learn(1)
    path = trainer.save(tmp_path / "ckpt.pt")
    swapped = make_trainer(fake_robot, fake_sim_cls, objectives=[SpeedError(), SquaredTorque()])
    swapped.load(path)
    x = torch.randn(5, trainer.ppo.dims.num_critic_obs)
    xi = torch.zeros(5, 2)
    a = trainer.ppo.pseudo_values(x, xi)
    b = swapped.ppo.pseudo_values(x, xi)
    assert torch.allclose(a[:, [1, 0]], b, atol=1e-6)


def test_designs_are_redrawn_from_the_range_every_n_iterations(fake_robot, fake_sim_cls) -> None:
    space = fake_robot.design_space().with_bounds({"thigh_scale": (0.6, 0.8)})
    trainer = Trainer(
        fake_robot,
        fake_sim_cls,
        [SquaredTorque()],
        design_space=space,
        train_config=small_config(design_resample_every=2, steps_per_env=4),
        task_config=TaskConfig(),
    )
    trainer.set_designs(trainer.sample_designs())
    first = trainer.designs.copy()
    trainer.learn(2)
    assert np.array_equal(trainer.designs, first)
    trainer.learn(1)
    assert not np.array_equal(trainer.designs, first)
    assert np.all((trainer.env.sim.designs[:, 0] >= 0.6) & (trainer.env.sim.designs[:, 0] <= 0.8))


def test_pseudo_epochs_limit_the_pseudo_critic_steps(fake_robot, fake_sim_cls) -> None:
    trainer = make_trainer(
        fake_robot, fake_sim_cls, small_config(epochs=3, minibatches=2, pseudo_epochs=1)
    )
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.learn(1)
    ppo = trainer.ppo
    assert int(ppo.optimizer.state_dict()["state"][0]["step"]) == 3 * 2
    assert int(ppo.pseudo_optimizer.state_dict()["state"][0]["step"]) == 1 * 2


class Exploding(Objective):
    name = "exploding"
    display_name = "exploding"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        cost = torch.full((step.command.shape[0],), 1e30)
        cost[0] = float("inf")
        cost[1] = float("nan")
        return cost


def test_non_finite_metrics_do_not_poison_the_pseudo_critics(fake_robot, fake_sim_cls) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls, objectives=[Exploding(), SquaredTorque()])
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.learn(2)
    ppo = trainer.ppo
    assert all(torch.isfinite(p).all() for p in ppo.pseudo_critic.parameters())
    assert torch.isfinite(ppo.pseudo_norm.var).all() and float(ppo.pseudo_norm.mean[0]) <= 1e15
    values = ppo.pseudo_values(torch.zeros(3, ppo.dims.num_critic_obs), torch.zeros(3, 2))
    assert torch.isfinite(values).all()


def mixed_space():
    from coadapt_core.design_space import Continuous, DesignSpace, Discrete

    return DesignSpace(
        [
            Continuous("thigh_scale", 0.5, 1.5),
            Continuous("shank_scale", 0.5, 1.5),
            Discrete("hip_motor", (1.0, 2.0, 3.0)),
            Discrete("knee_motor", (1.0, 2.0, 3.0)),
        ]
    )


def test_widened_policy_acts_exactly_as_before_whatever_the_new_design_values(
    fake_robot, fake_sim_cls, tmp_path
) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0], [0.6, 1.4]]))
    trainer.learn(2)
    path = trainer.export_weights(tmp_path / "policy.pt")
    obs, critic_obs, design = trainer.env.reset()
    critic_in = trainer.ppo.critic_norm(critic_obs)

    wide = Trainer(
        fake_robot,
        fake_sim_cls,
        [SquaredTorque(), SpeedError()],
        design_space=mixed_space(),
        train_config=small_config(),
        task_config=TaskConfig(noise=NoiseConfig(enabled=False)),
    )
    wide.load(path, optimizers=False, widen=True)
    assert wide.ppo.dims.num_design == 4
    gen = torch.Generator().manual_seed(0)
    for _ in range(3):  # any motor values: the new inputs have zero weights
        extra = torch.randint(-1, 2, (design.shape[0], 2), generator=gen).float()
        xi = torch.cat([design, extra], dim=-1)
        assert torch.allclose(
            wide.ppo.act_inference(obs, xi), trainer.ppo.act_inference(obs, design), atol=1e-6
        )
        assert torch.allclose(
            wide.ppo.pseudo_values(critic_in, xi),
            trainer.ppo.pseudo_values(critic_in, design),
            rtol=1e-5,
        )
    weight = wide.ppo.actor_net.body[0].weight
    assert weight.shape[1] == trainer.ppo.actor_net.body[0].weight.shape[1] + 2
    assert torch.count_nonzero(weight[:, -2:]) == 0


def test_a_command_never_varied_opens_with_zero_weights_and_its_true_scale(
    fake_robot, fake_sim_cls, tmp_path, capsys
) -> None:
    """A policy trained at yaw rate 0 and fine-tuned on yaw commands: its yaw input was always 0
    (variance 0), so it must start with zero weights (acting as before whatever the command)
    and the normaliser must scale the new command by the new range, not by 1/sqrt(eps)."""
    still = TaskConfig(
        noise=NoiseConfig(enabled=False), commands=CommandConfig(yaw_range=(0.0, 0.0))
    )
    trainer = make_trainer(fake_robot, fake_sim_cls, task=still)
    trainer.set_designs(np.array([[1.0, 1.0], [0.6, 1.4]]))
    trainer.learn(2)
    yaw = 11  # o: base_lin_vel 3, base_ang_vel 3, projected_gravity 3, command (vx, vy, yaw)
    assert float(trainer.ppo.obs_norm.var[yaw]) == 0.0
    path = trainer.save(tmp_path / "still.pt")
    obs, critic_obs, design = trainer.env.reset()
    assert torch.count_nonzero(obs[:, yaw]) == 0

    turning = TaskConfig(
        noise=NoiseConfig(enabled=False), commands=CommandConfig(yaw_range=(-1.0, 1.0))
    )
    tuned = make_trainer(fake_robot, fake_sim_cls, task=turning)
    tuned.load(path)
    assert "yaw-rate" in capsys.readouterr().err
    ppo = tuned.ppo
    for norm in (ppo.obs_norm, ppo.critic_norm):
        assert float(norm.mean[yaw]) == 0.0 and float(norm.var[yaw]) == pytest.approx(4.0 / 12.0)
    assert torch.count_nonzero(ppo.actor_net.body[0].weight[:, yaw]) == 0
    # any yaw command: the same actions and pseudo-values as the original policy at yaw 0
    for rate in (-1.0, 0.3, 1.0):
        turned, turned_critic = obs.clone(), critic_obs.clone()
        turned[:, yaw], turned_critic[:, yaw] = rate, rate
        assert torch.allclose(
            ppo.act_inference(turned, design), trainer.ppo.act_inference(obs, design), atol=1e-6
        )
        assert torch.allclose(
            ppo.pseudo_values(ppo.critic_norm(turned_critic), design),
            trainer.ppo.pseudo_values(trainer.ppo.critic_norm(critic_obs), design),
            rtol=1e-5,
        )
        # and the input reaches the network at its true scale (the old normaliser clipped it at 5)
        assert float(ppo.obs_norm(turned)[0, yaw]) == pytest.approx(
            rate / (1.0 / 3.0 + ppo.obs_norm.eps) ** 0.5, rel=1e-5
        )
    assert abs(float(trainer.ppo.obs_norm(turned)[0, yaw])) == pytest.approx(5.0)
    # the vx channel varied in training: left alone
    assert torch.equal(ppo.obs_norm.var[9], trainer.ppo.obs_norm.var[9])
    # loading it again (now it has seen yaw commands vary) opens nothing
    tuned.set_designs(np.array([[1.0, 1.0]]))
    tuned.learn(1)
    again = make_trainer(fake_robot, fake_sim_cls, task=turning)
    again.load(tuned.save(tmp_path / "turning.pt"))
    assert "never saw" not in capsys.readouterr().err
    assert torch.equal(again.ppo.obs_norm.var, tuned.ppo.obs_norm.var)


def test_non_finite_pseudo_critics_in_a_checkpoint_restart_fresh(
    fake_robot, fake_sim_cls, tmp_path, capsys
) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.learn(1)
    with torch.no_grad():
        trainer.ppo.pseudo_norm.mean.fill_(float("nan"))
        trainer.ppo.pseudo_critic.weight_0[0].fill_(float("nan"))
    path = trainer.save(tmp_path / "poisoned.pt")
    restored = make_trainer(fake_robot, fake_sim_cls)
    restored.load(path)
    assert "non-finite" in capsys.readouterr().err
    ppo = restored.ppo
    assert ppo.pseudo_reset
    # the policy itself is restored, the pseudo-critics start over and learn finite values
    obs, _, design = trainer.env.reset()
    assert torch.equal(ppo.act_inference(obs, design), trainer.ppo.act_inference(obs, design))
    restored.set_designs(np.array([[1.0, 1.0]]))
    restored.learn(2)
    values = ppo.pseudo_values(torch.zeros(3, ppo.dims.num_critic_obs), torch.zeros(3, 2))
    assert torch.isfinite(values).all()
    assert torch.isfinite(ppo.pseudo_norm.mean).all() and torch.isfinite(ppo.pseudo_norm.var).all()


def test_weights_export_carries_the_command_curriculum_and_learning_rate(
    fake_robot, fake_sim_cls, tmp_path
) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.env.commands.limit = 0.9
    trainer.ppo.learning_rate = 1.3e-4
    path = trainer.export_weights(tmp_path / "policy.pt")
    restored = make_trainer(fake_robot, fake_sim_cls)
    restored.load(path)
    assert restored.command_state()["limit"] == pytest.approx(0.9)
    # fine-tuning starts at the rate the training had reached, not the configured 1e-3
    assert restored.ppo.learning_rate == pytest.approx(1.3e-4)
    assert all(g["lr"] == pytest.approx(1.3e-4) for g in restored.ppo.optimizer.param_groups)
    restored.set_designs(np.array([[1.0, 1.0]]))
    assert restored.env.commands.limit == pytest.approx(0.9)


def test_act_is_the_torchrl_actors_sample_to_the_bit(fake_robot, fake_sim_cls) -> None:
    """`PPO.act` computes what the TorchRL actor does under ExplorationType.RANDOM (without its
    module dispatch): the same action, log-probability, loc and scale from the same seed."""
    from tensordict import TensorDict
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    trainer = make_trainer(fake_robot, fake_sim_cls, small_config())
    trainer.learn(1)
    ppo = trainer.ppo
    obs, critic_obs, design_obs = trainer._obs
    ppo.training = False  # the normalisers stay as they are between the two calls
    torch.manual_seed(11)
    action = ppo.act(obs, critic_obs, design_obs)
    mine = ppo.transitions.pop()
    torch.manual_seed(11)
    reference = TensorDict(
        {"obs": ppo.obs_norm(obs), "design_obs": design_obs}, batch_size=[obs.shape[0]]
    )
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        ppo.actor(reference)
    key = ppo.loss.tensor_keys.sample_log_prob
    assert torch.equal(action, reference["action"]) and torch.equal(
        mine["action"], reference["action"]
    )
    assert torch.equal(mine[key], reference[key])
    assert torch.equal(mine["loc"], reference["loc"]) and torch.equal(
        mine["scale"], reference["scale"]
    )
    assert not torch.equal(action, mine["loc"])  # a sample, not the mean


def _rollout(ppo, env, steps: int) -> None:
    obs, critic, design = env.reset()
    for _ in range(steps):
        actions = ppo.act(obs, critic, design)
        res = env.step(actions)
        ppo.process_env_step(
            res.reward,
            res.done,
            res.timeout,
            res.info["final_critic_obs"],
            res.design_obs,
            res.info["metrics"],
        )
        obs, critic, design = res.obs, res.critic_obs, res.design_obs


def test_a_runaway_pseudo_critic_cannot_inflate_its_own_targets(fake_robot, fake_sim_cls) -> None:
    # a pseudo-critic predicting absurd values everywhere (as an extrapolating one did on
    # unfamiliar states, which once fed back until every long fine-tune's surrogate ranked
    # designs backwards): its bootstrap is held to the metric's range and the target scale is
    # the metric's own, so neither moves
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0], [0.7, 1.2]]))
    ppo, env = trainer.ppo, trainer.env
    bank = ppo.pseudo_critic
    with torch.no_grad():
        getattr(bank, f"bias_{bank.num_layers - 1}").fill_(1e4)  # 1e4 "standard deviations"
    _rollout(ppo, env, 12)
    batch = ppo.compute_returns()
    metrics = batch["metrics"].reshape(-1, 2)
    lo, hi = metrics.amin(0), metrics.amax(0)
    norm = ppo.pseudo_norm
    target = (
        batch["pseudo_target"].reshape(-1, 2) * torch.sqrt(norm.var[:2] + norm.eps) + norm.mean[:2]
    )
    assert bool((target >= lo - 1e-4 * hi.abs()).all()) and bool((target <= hi * (1 + 1e-4)).all())
    # the normaliser holds the statistics of the per-step metric, whatever the critic says
    torch.testing.assert_close(norm.mean[:2], metrics.mean(0), rtol=1e-4, atol=1e-6)
    torch.testing.assert_close(norm.var[:2], metrics.var(0, unbiased=False), rtol=1e-3, atol=1e-6)


def test_pseudo_critics_only_leaves_the_policy_exactly_as_loaded(fake_robot, fake_sim_cls) -> None:
    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0], [0.7, 1.2]]))
    trainer.learn(1)
    ppo = trainer.ppo
    before = {
        name: {k: t.clone() for k, t in getattr(ppo, attr).state_dict().items()}
        for name, attr in (
            ("actor", "actor_net"),
            ("critic", "critic_net"),
            ("obs", "obs_norm"),
            ("critic_obs", "critic_norm"),
        )
    }
    pseudo_before = {k: t.clone() for k, t in ppo.pseudo_critic.state_dict().items()}
    adam_steps = int(ppo.optimizer.state_dict()["state"][0]["step"])
    rate = ppo.learning_rate
    ppo.freeze_policy()
    trainer.learn(2)
    for name, attr in (
        ("actor", "actor_net"),
        ("critic", "critic_net"),
        ("obs", "obs_norm"),
        ("critic_obs", "critic_norm"),
    ):
        for k, t in getattr(ppo, attr).state_dict().items():
            assert torch.equal(t, before[name][k]), (name, k)
    assert (
        int(ppo.optimizer.state_dict()["state"][0]["step"]) == adam_steps
        and ppo.learning_rate == rate
    )
    moved = [
        k for k, t in ppo.pseudo_critic.state_dict().items() if not torch.equal(t, pseudo_before[k])
    ]
    assert len(moved) == len(pseudo_before)  # every pseudo-critic parameter learned
    per_iteration = (ppo.config.pseudo_epochs or ppo.config.epochs) * ppo.config.minibatches
    assert (
        int(ppo.pseudo_optimizer.state_dict()["state"][0]["step"]) == 3 * per_iteration
    )  # 1 + 2 iterations


def test_rollout_speeds_are_the_mean_of_each_agents_mean(fake_robot, fake_sim_cls) -> None:
    from coadapt_core.learning.evaluate import rollout

    task = TaskConfig(
        noise=NoiseConfig(enabled=False),
        commands=CommandConfig(
            curriculum=False, vx_range=(0.5, 1.0), yaw_range=(-0.5, 0.5), zero_share=0.0
        ),
    )
    trainer = make_trainer(fake_robot, fake_sim_cls, task=task)
    trainer.set_designs(np.array([[1.0, 1.0], [0.7, 1.2]]))
    result = rollout(trainer.ppo.action_distribution, trainer.env, 2, 20, seed=3)
    per_agent = result.per_agent_velocity
    assert per_agent.shape == (2, 16, 3)
    np.testing.assert_allclose(per_agent[:, :, 0].mean(axis=1), result.vx, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(
        per_agent[:, :, 2].mean(axis=1), result.yaw_rate, rtol=1e-5, atol=1e-7
    )
    assert (
        per_agent[:, :, 0].std(axis=1).min() > 0
    )  # agents differ: the standard error has something to measure


def test_rollout_takes_any_policy_callable_and_pairs_its_action_noise(
    fake_robot, fake_sim_cls
) -> None:
    """A rollout needs only a callable to a Gaussian's (mean, std): deterministic steps take
    the mean, stochastic ones the mean plus std times noise that agent i of every design shares;
    the learner's own `action_distribution` gives the policy mean `act_inference` gives."""
    from coadapt_core.learning.evaluate import apply_scenarios, rollout

    trainer = make_trainer(fake_robot, fake_sim_cls)
    trainer.set_designs(np.array([[1.0, 1.0], [0.7, 1.2]]))
    env = trainer.env
    obs, _, design = env.reset()
    assert torch.equal(
        trainer.ppo.action_distribution(obs, design)[0], trainer.ppo.act_inference(obs, design)
    )

    mean = torch.linspace(-0.3, 0.3, env.num_actions)
    seen: list[torch.Tensor] = []

    def policy(o: torch.Tensor, xi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return mean.expand(o.shape[0], -1), torch.full((o.shape[0], env.num_actions), 0.1)

    def record(e) -> None:
        seen.append(e.action_history[:, 0].clone())

    result = rollout(policy, env, 2, 3, seed=1, on_step=record)
    assert result.steps == env.num_envs * 3
    for actions in seen:  # deterministic: the mean itself, every environment
        torch.testing.assert_close(actions, mean.expand(env.num_envs, -1))
    seen.clear()
    agents = env.num_envs // 2
    apply_scenarios(env, agents, 2, 5)
    rollout(policy, env, 2, 3, seed=1, stochastic=True, on_step=record)
    for actions in seen:
        noise = (actions - mean) / 0.1
        assert noise.abs().max() > 0.05  # the std is used
        torch.testing.assert_close(
            noise[:agents], noise[agents:]
        )  # paired: design 2's agent i = design 1's
        assert not torch.allclose(noise[0], noise[1])  # agents differ
