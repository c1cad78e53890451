"""The conformance suites must be able to fail: run them on deliberately broken plugins."""

from __future__ import annotations

pytest_plugins = ["pytester"]

BROKEN = '''
import numpy as np
import pytest
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer
from coadapt_core.testing import ObjectiveConformance, OptimizerConformance


class Unseeded(Optimizer):
    """Ignores its seed and never learns from costs."""
    name = "unseeded"

    def _ask(self):
        draw = np.random.default_rng().uniform(size=(self.population, self.space.dim))
        return self.space.decode(draw)

    def _tell(self, designs, costs):
        pass


class Stuck(Optimizer):
    """Always proposes the same grid, whatever the costs say."""
    name = "stuck"

    def _ask(self):
        u = (np.arange(self.population)[:, None] + 0.5) / self.population
        return self.space.decode(np.repeat(u, self.space.dim, axis=1))

    def _tell(self, designs, costs):
        pass


class WrongShape(Objective):
    name = "wrong-shape"
    display_name = "Wrong shape"

    def step_cost(self, step):
        return step.joint_vel  # [N, J] instead of [N]


class TestUnseeded(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return Unseeded


class TestStuck(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return Stuck


class TestWrongShape(ObjectiveConformance):
    @pytest.fixture
    def objective(self):
        return WrongShape()
'''


def test_suites_fail_on_broken_plugins(pytester):
    pytester.makepyfile(test_broken=BROKEN)
    result = pytester.runpytest_subprocess("-q", "-p", "no:cacheprovider")
    outcomes = result.parseoutcomes()
    failed = {
        line.split("::")[-1].split(" ")[0] for line in result.outlines if line.startswith("FAILED")
    }
    assert outcomes.get("failed", 0) >= 3, result.outlines[-15:]
    assert "test_same_seed_same_proposals" in failed
    assert "test_finds_sphere_optimum_region" in failed
    assert "test_one_finite_cost_per_env" in failed
