"""The learner's `surrogate_slope` (issue 52): the surrogate's cost and its gradient in the
design, on the fake simulator; the gradient predicts the surrogate's change along any
direction, on the paper's estimator and on the ensemble fitted to real rounds."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.fitness import surrogate_slope
from coadapt_core.learning.backend import UniversalPolicyBackend
from coadapt_core.learning.config import TrainConfig
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.physics.randomization import RandomizationConfig


class SquaredTorque(Objective):
    name = "sq_torque"
    display_name = "squared torque"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return 1e-4 * (step.joint_torque**2).sum(-1)


@pytest.fixture
def trained(fake_robot, fake_sim_factory):
    sim_type = type(fake_sim_factory(1))

    def build(robot, designs, **kwargs):
        kwargs["randomization"] = RandomizationConfig.off()
        return sim_type(robot, designs, **kwargs)

    build.name = "fake"
    config = TrainConfig(
        num_designs=2, agents_per_design=8, steps_per_env=16, hidden=(64, 64), epochs=2,
        minibatches=2, torch_threads=1,
    )  # fmt: skip
    backend = UniversalPolicyBackend(
        fake_robot,
        build,
        [SquaredTorque()],
        design_space=fake_robot.design_space(),
        agents_per_design=8,
        train_config=config,
    )
    designs = np.array([[1.0, 1.0], [0.6, 1.4], [1.4, 0.6]])
    result = backend.train(designs, 3 * 8 * 16 * 2)
    yield backend, result.buffer
    backend.close()


def directional(backend, buffer, design, v, t):
    up = backend.surrogate_fitness((design + t * v)[None], backend.objectives, buffer, samples=512)
    down = backend.surrogate_fitness(
        (design - t * v)[None], backend.objectives, buffer, samples=512
    )
    return float((up - down)[0, 0] / (2 * t))


@pytest.mark.parametrize("fitted", [False, True])
def test_slope_predicts_the_surrogates_change_along_any_direction(trained, fitted):
    backend, buffer = trained
    assert surrogate_slope(backend) is backend
    objectives = backend.objectives
    if fitted:  # the ensemble fitted to labelled designs: surrogate_fitness is its mean
        labelled = np.array([[0.7, 0.8], [1.2, 1.3], [1.0, 0.6], [0.9, 1.1]])
        backend.fit_surrogate(labelled, np.array([[1.0], [2.0], [1.5], [1.2]]), objectives, buffer)
        assert backend.fitted is not None
    designs = np.array([[0.8, 1.2], [1.3, 0.7]])
    costs, grads = backend.surrogate_slope(designs, objectives, buffer, samples=512)
    assert costs.shape == (2, 1) and grads.shape == (2, 1, 2)
    np.testing.assert_allclose(
        costs, backend.surrogate_fitness(designs, objectives, buffer, samples=512), rtol=1e-6
    )
    rng = np.random.default_rng(0)
    scale = np.abs(grads).max()
    assert scale > 0
    for k in range(2):
        for v in rng.normal(size=(3, 2)):
            v /= np.linalg.norm(v)
            # a wider central difference (2 % of the range): agrees to curvature and rounding
            expected = directional(backend, buffer, designs[k], v, 0.02)
            assert grads[k, 0] @ v == pytest.approx(expected, abs=0.05 * scale)
