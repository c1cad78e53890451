"""The learner's device and threads: training allocates nothing on an implicit (default)
device, so `--device cuda` puts everything on the GPU; torch uses every core for the update
and one during collection; the environment converts the randomized parameters once per reset,
not every step; the bf16 and profiling code paths run on the CPU."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.trainer import Trainer
from coadapt_core.plugins import get_registry
from coadapt_core.task.config import NoiseConfig, TaskConfig
from coadapt_core.task.env import LocomotionEnv
from tests.core.test_learning_ppo import make_trainer, small_config


def test_training_allocates_nothing_on_the_default_device() -> None:
    """With torch's default device set to 'meta' (no data), any tensor made without an
    explicit device would fail or poison the run. Training on device 'cpu' must not notice:
    learner, task, robot and simulator all allocate on the device they were given. On a GPU
    the same code therefore keeps everything on 'cuda'."""
    registry = get_registry()
    robot = registry.get("robot", "kuafu")()
    objectives = [registry.get("objective", n)() for n in ("tracking", "power")]
    config = TrainConfig(
        num_designs=2,
        agents_per_design=2,
        steps_per_env=8,
        hidden=(16, 16),
        epochs=2,
        minibatches=2,
        device="cpu",
        torch_threads=1,
    )
    trainer = Trainer(robot, registry.get("simulator", "mujoco"), objectives, train_config=config)
    trainer.set_designs(trainer.sample_designs())  # module construction, then .to(device)
    with torch.device("meta"):
        stats = trainer.learn(2)
    assert np.isfinite(stats.mean_reward) and np.isfinite(stats.losses["loss_pseudo"])
    assert trainer.ppo.pseudo_critic.weight_0.device.type == "cpu"
    assert trainer.total_steps == 2 * 4 * 8


def test_update_uses_the_thread_budget_and_collection_one(fake_robot, fake_sim_cls) -> None:
    """The update runs on the trainer's thread budget (here 2), never on the `torch_threads`
    a configuration (a checkpoint's: the shipped policies record 1) carries; collection on one."""
    trainer = Trainer(
        fake_robot, fake_sim_cls, [], train_config=small_config(torch_threads=1), num_threads=2
    )
    trainer.set_designs(np.array([[1.0, 1.0], [0.8, 1.2]]))
    seen = {"update": set(), "step": set()}
    update, step = trainer.ppo.update, trainer.env.step
    trainer.ppo.update = lambda: (seen["update"].add(torch.get_num_threads()), update())[1]
    trainer.env.step = lambda actions: (seen["step"].add(torch.get_num_threads()), step(actions))[1]
    trainer.learn(2)
    assert seen == {"update": {2}, "step": {1}}
    assert torch.get_num_threads() == 1  # back to one outside the update
    assert (
        trainer.update_threads_seen == 2 and trainer.env.sim.num_threads == 2
    )  # physics: the same budget
    from coadapt_core import threads

    default = Trainer(fake_robot, fake_sim_cls, [], train_config=small_config(torch_threads=1))
    assert default.learner_threads == default.num_threads == threads.budget() >= 1


def test_randomized_parameters_are_converted_once_per_reset(fake_robot, fake_sim_factory) -> None:
    sim = fake_sim_factory(4, randomize=True)
    reads = []
    cls = type(sim)
    sim.__class__ = type(
        "CountingSim",
        (cls,),
        {"env_params": property(lambda s: reads.append(1) or cls.env_params.fget(s))},
    )
    env = LocomotionEnv(
        sim, fake_robot, TaskConfig(noise=NoiseConfig(enabled=False), episode_seconds=0.1)
    )
    env.reset()
    before = len(reads)
    res = env.step(torch.zeros(4, 8))  # 5 steps per episode: nobody restarts yet
    assert not bool(res.done.any()) and len(reads) == before
    for _ in range(4):
        res = env.step(torch.zeros(4, 8))
    assert bool(res.done.all()) and len(reads) == before + 1  # the timeout resets: one read
    friction = torch.as_tensor(sim.env_params.friction, dtype=torch.float32)
    assert torch.equal(res.critic_obs[:, -8], friction)  # the restarted episodes' own parameters


def test_bf16_and_profiled_update_run_on_the_cpu(fake_robot, fake_sim_cls) -> None:
    trainer = make_trainer(
        fake_robot, fake_sim_cls, small_config(precision="bf16", pseudo_precision="bf16")
    )
    trainer.set_designs(np.array([[1.0, 1.0]]))
    trainer.ppo.profile = True
    stats = trainer.learn(2)
    assert all(np.isfinite(v) for v in stats.losses.values())
    assert all(
        p.dtype == torch.float32 for p in trainer.ppo.pseudo_critic.parameters()
    )  # autocast, not a cast
    timing = trainer.ppo.timing
    assert 0 < timing["pseudo"] < timing["returns"] + timing["update"]


def test_auto_precision_is_bf16_only_where_the_device_has_it() -> None:
    from coadapt_core.errors import UserError
    from coadapt_core.learning.config import resolve_precision

    native = torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported()
    assert resolve_precision("auto", "cpu") == ("bf16" if native else "float32")
    assert (
        resolve_precision("float32", "cpu") == "float32"
        and resolve_precision("bf16", "cpu") == "bf16"
    )
    assert TrainConfig().precision == TrainConfig().pseudo_precision == "auto"
    with pytest.raises(UserError, match="pseudo_precision"):
        TrainConfig(pseudo_precision="fp8")
