"""`UniversalPolicyBackend` on the fake simulator: the CoadaptationBackend protocol,
real fitness per design (Algorithm 2) and pseudo-critic surrogate fitness (Algorithm 3)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.errors import UserError
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.learning.backend import UniversalPolicyBackend
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.evaluate import EvalBuffer
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.physics.randomization import RandomizationConfig


class SquaredTorque(Objective):
    name = "sq_torque"
    display_name = "squared torque"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return 1e-4 * (step.joint_torque**2).sum(-1)


class ShankLength(Objective):
    """Depends on the design only through the sim: here a stand-in that is easy to learn."""

    name = "speed_sq"
    display_name = "speed squared"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return step.base_lin_vel[:, 0] ** 2


@pytest.fixture
def backend(fake_robot, fake_sim_factory):
    sim_type = type(fake_sim_factory(1))

    def build(robot, designs, **kwargs):
        kwargs["randomization"] = RandomizationConfig.off()
        return sim_type(robot, designs, **kwargs)

    build.name = "fake"
    # pseudo-critics train in every PPO epoch here: the test is about their target's scale
    config = TrainConfig(
        num_designs=2,
        agents_per_design=8,
        steps_per_env=16,
        hidden=(64, 64),
        epochs=2,
        minibatches=2,
        pseudo_epochs=0,
        torch_threads=1,
    )
    out = UniversalPolicyBackend(
        fake_robot,
        build,
        [SquaredTorque(), ShankLength()],
        terrain="flat",
        design_space=fake_robot.design_space(),
        agents_per_design=8,
        device="cpu",
        seed=0,
        train_config=config,
    )
    yield out
    out.close()


def test_is_a_coadaptation_backend(backend) -> None:
    assert isinstance(backend, CoadaptationBackend)


def test_train_real_and_surrogate_fitness_shapes_and_units(backend, tmp_path) -> None:
    designs = np.array([[1.0, 1.0], [0.6, 1.4], [1.4, 0.6]])
    result = backend.train(designs, 3 * 8 * 16 * 2)
    assert result.steps == 2 * 3 * 8 * 16 and result.seconds > 0 and np.isfinite(result.mean_reward)
    assert isinstance(result.buffer, EvalBuffer) and len(result.buffer) == 3 * 8 * 16

    objectives = backend.objectives
    fit = backend.real_fitness(designs, objectives, agents=4, steps=20, seed=1)
    assert fit.costs.shape == (3, 2) and fit.interactions == 3 * 4 * 20
    assert fit.survival.shape == (3,) and np.all((fit.survival >= 0) & (fit.survival <= 1))
    assert np.all(fit.costs >= 0)
    again = backend.real_fitness(designs, objectives, agents=4, steps=20, seed=1)
    np.testing.assert_allclose(again.costs, fit.costs, rtol=1e-5)  # deterministic policy + seed

    surrogate = backend.surrogate_fitness(designs, objectives, fit.buffer, samples=256, seed=0)
    assert surrogate.shape == (3, 2) and np.all(np.isfinite(surrogate))
    # the same seed gives the same sample of states; one column follows its objective
    np.testing.assert_allclose(
        backend.surrogate_fitness(designs, objectives, fit.buffer, samples=256, seed=0), surrogate
    )
    reordered = backend.surrogate_fitness(
        designs, objectives[::-1], fit.buffer, samples=256, seed=0
    )
    np.testing.assert_allclose(reordered, surrogate[:, ::-1], rtol=1e-6)

    path = tmp_path / "backend.pt"
    backend.save(str(path))
    other = UniversalPolicyBackend(
        backend.trainer.robot,
        backend.trainer.simulator_cls,
        objectives,
        design_space=backend.trainer.design_space,
        agents_per_design=8,
        seed=3,
        checkpoint=str(path),
        train_config=backend.trainer.config,
    )
    np.testing.assert_allclose(
        other.surrogate_fitness(designs, objectives, fit.buffer, samples=256, seed=0),
        surrogate,
        rtol=1e-6,
    )


@pytest.mark.slow
def test_the_papers_estimator_computes_only_its_heads_to_the_bit(
    fake_robot, fake_sim_factory
) -> None:
    """surrogate_fitness runs only the objectives' pseudo-critics (one alone twice: a batch of
    one takes another product path, 1e-6 apart at these sizes) on the learner's threads:
    every column equals, bit for bit, the mean of all heads computed together on one thread,
    as before. The shipped policies' sizes: 512-256-128 heads, 4096 states."""
    sim_type = type(fake_sim_factory(1))
    config = TrainConfig(
        num_designs=2,
        agents_per_design=8,
        steps_per_env=16,
        hidden=(512, 256, 128),
        torch_threads=1,
    )
    backend = UniversalPolicyBackend(
        fake_robot,
        lambda robot, designs, **kw: sim_type(robot, designs, **kw),
        [SquaredTorque(), ShankLength()],
        design_space=fake_robot.design_space(),
        agents_per_design=8,
        seed=0,
        train_config=config,
    )
    designs = np.array([[1.0, 1.0], [0.6, 1.4], [1.4, 0.6]])
    fit = backend.real_fitness(designs, backend.objectives, agents=4, steps=20, seed=1)
    states = backend._states(fit.buffer, 4096, 0)
    xi = backend.trainer.normalize_designs(designs)
    with torch.no_grad():
        every = torch.stack(
            [
                backend.ppo.pseudo_values(states, xi[k].expand(4096, -1)).mean(dim=0)
                for k in range(3)
            ]
        ).numpy()
    backend.trainer.learner_threads = 2
    for j, objective in enumerate(backend.objectives):
        alone = backend.surrogate_fitness(designs, [objective], fit.buffer, samples=4096, seed=0)
        assert np.array_equal(alone[:, 0], every[:, j])
    assert np.array_equal(
        backend.surrogate_fitness(
            designs, backend.objectives[::-1], fit.buffer, samples=4096, seed=0
        ),
        every[:, ::-1],
    )
    assert torch.get_num_threads() == backend.trainer.collect_threads  # collection's threads again
    backend.close()


def test_pseudo_critic_learns_the_scale_of_the_metric(backend) -> None:
    """After training, the surrogate of the torque cost is within a factor of 2 of the real
    fitness it stands in for (same units: the discounted-average target)."""
    designs = np.array([[1.0, 1.0], [1.0, 1.0]])
    backend.train(designs, 25 * 2 * 8 * 16)
    objectives = backend.objectives[:1]
    fit = backend.real_fitness(designs, objectives, agents=8, steps=40)
    surrogate = backend.surrogate_fitness(designs, objectives, fit.buffer, samples=512)
    ratio = surrogate[:, 0] / fit.costs[:, 0]
    assert np.all((ratio > 0.5) & (ratio < 2.0)), (surrogate, fit.costs)


def test_unknown_objective_and_empty_buffer_are_user_errors(backend) -> None:
    designs = np.array([[1.0, 1.0]])
    backend.train(designs, 8 * 16)

    class Other(SquaredTorque):
        name = "other"

    with pytest.raises(UserError, match="no pseudo-critic"):
        backend.surrogate_fitness(designs, [Other()], EvalBuffer(torch.zeros(4, 83)), samples=4)
    with pytest.raises(UserError, match="buffer"):
        backend.surrogate_fitness(designs, backend.objectives, None, samples=4)
