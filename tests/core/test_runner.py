"""The training runner (`coadapt_core.learning.runner.Runner`): the cadence of a budget, the
files of a run (progress.jsonl, checkpoints, model_final.pt, policy.pt), the learning rate
given over a checkpoint's, Ctrl-C after the iteration under way and the resume that follows,
and a runner that writes nothing training exactly as the trainer alone (the loop's retraining
goes through it). Learner logic: the fake simulator of tests/core/conftest.py."""

from __future__ import annotations

import json
import os
import signal

import pytest
import torch

from coadapt_core.learning.checkpoints import read_checkpoint
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.runner import Runner, TrainingInterrupted
from coadapt_core.learning.trainer import Trainer
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.task.config import NoiseConfig, TaskConfig


class SquaredTorque(Objective):
    name = "sq_torque"
    display_name = "squared torque"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return 1e-4 * (step.joint_torque**2).sum(-1)


def trainer_for(robot, sim_cls, seed: int = 0) -> Trainer:
    config = TrainConfig(
        num_designs=2,
        agents_per_design=4,
        steps_per_env=8,
        hidden=(32, 32),
        epochs=1,
        minibatches=2,
        seed=seed,
        torch_threads=1,
    )
    trainer = Trainer(
        robot,
        sim_cls,
        [SquaredTorque()],
        train_config=config,
        task_config=TaskConfig(noise=NoiseConfig(enabled=False)),
    )
    trainer.set_designs(trainer.sample_designs())
    return trainer


def test_a_budget_is_whole_iterations_recorded_and_checkpointed(tmp_path, fake_robot, fake_sim_cls):
    trainer = trainer_for(fake_robot, fake_sim_cls)
    runner = Runner(trainer, tmp_path / "run", checkpoint_every=2)
    assert (
        runner.iterations_for(100) == 2 and runner.iterations_for(1) == 1
    )  # 64 samples an iteration
    seen = []
    stats = runner.learn(100, seen.append)
    assert [s.iteration for s in seen] == [1, 2] and stats.total_steps == 128 == trainer.total_steps
    rows = [
        json.loads(line) for line in (tmp_path / "run" / "progress.jsonl").read_text().splitlines()
    ]
    assert [r["iteration"] for r in rows] == [1, 2] and rows[-1]["total_steps"] == 128
    assert sorted(p.name for p in (tmp_path / "run" / "checkpoints").iterdir()) == ["model_2.pt"]
    assert runner.run(0) is None and trainer.iteration == 2  # no iteration: the trainer untouched
    final, weights = runner.finish()
    assert final.name == "model_final.pt" and weights.name == "policy.pt"
    assert (
        int(read_checkpoint(final)["iteration"]) == 2
        and read_checkpoint(weights)["ppo"]["learning_rate"] > 0
    )


def test_a_runner_without_a_folder_writes_nothing_and_trains_as_the_trainer(
    tmp_path, fake_robot, fake_sim_cls, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    alone = trainer_for(
        fake_robot, fake_sim_cls, seed=3
    )  # each seeds torch's global generator: one after the other
    expected = alone.learn(alone.iterations_for(100))
    driven = trainer_for(fake_robot, fake_sim_cls, seed=3)
    got = Runner(driven).learn(100)
    assert got.iteration == expected.iteration == 2
    assert got.mean_reward == expected.mean_reward and got.losses == expected.losses
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(Exception, match="writes nothing"):
        Runner(driven).checkpoint()


def test_the_learning_rate_given_wins_over_the_checkpoints(tmp_path, fake_robot, fake_sim_cls):
    first = Runner(trainer_for(fake_robot, fake_sim_cls), tmp_path / "a")
    first.learn(64)
    saved, _ = first.finish()
    resumed = Runner(trainer_for(fake_robot, fake_sim_cls), tmp_path / "b")
    resumed.resume(saved)
    resumed.set_learning_rate(2.5e-4)
    ppo = resumed.trainer.ppo
    assert ppo.learning_rate == 2.5e-4 and {g["lr"] for g in ppo.optimizer.param_groups} == {2.5e-4}
    assert resumed.trainer.iteration == 1
    resumed.close()


def test_ctrl_c_stops_after_the_iteration_with_a_checkpoint_and_the_run_resumes(
    tmp_path, fake_robot, fake_sim_cls
):
    out = tmp_path / "run"
    runner = Runner(
        trainer_for(fake_robot, fake_sim_cls), out, checkpoint_every=1000, catch_ctrl_c=True
    )
    previous = signal.getsignal(signal.SIGINT)

    def press_ctrl_c(stats) -> None:
        if stats.iteration == 1:
            os.kill(os.getpid(), signal.SIGINT)  # the handler only asks for a stop

    with pytest.raises(TrainingInterrupted) as stop:
        runner.learn(64 * 5, press_ctrl_c)
    assert signal.getsignal(signal.SIGINT) is previous  # the handler is put back
    assert stop.value.iteration == 1 and stop.value.checkpoint == out / "checkpoints" / "model_1.pt"
    assert int(read_checkpoint(stop.value.checkpoint)["iteration"]) == 1
    assert len((out / "progress.jsonl").read_text().splitlines()) == 1
    runner.close()
    again = Runner(trainer_for(fake_robot, fake_sim_cls), out)
    again.resume(stop.value.checkpoint)
    assert again.learn(64).iteration == 2
    assert [
        json.loads(r)["iteration"] for r in (out / "progress.jsonl").read_text().splitlines()
    ] == [1, 2]
    again.close()
