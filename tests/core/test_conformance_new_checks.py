"""The conformance checks added with plugin API 2.0 catch what they are for: an objective
that is NaN only when the robot stands still, constructors that skip the base initialiser,
and an optimizer whose proposals only fit after clipping (which is also warned about at run
time)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from coadapt_core.design_space import Continuous, DesignSpace
from coadapt_core.optimizer import Optimizer, OutOfBoundsProposal

pytest_plugins = ["pytester"]

BROKEN = '''
import numpy as np
import pytest
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer
from coadapt_core.testing import ObjectiveConformance, OptimizerConformance


class CostOfTransport(Objective):
    """Power over weight times speed: 0/0 when the robot stands still (random steps never do)."""
    name = "cot"
    display_name = "CoT"

    def step_cost(self, step):
        power = (step.joint_torque * step.joint_vel).abs().sum(-1)
        return power / (step.total_mass * 9.81 * step.base_lin_vel[:, :2].norm(dim=-1))


class NoSuperObjective(Objective):
    name = "no-super"
    display_name = "No super"

    def __init__(self, scale=1.0):
        self.scale = scale  # forgot super().__init__()

    def step_cost(self, step):
        return self.scale * step.joint_vel.abs().mean(-1)


class Overshoot(Optimizer):
    """Samples a box 20 % wider than the space on each side and lets the base class clip."""
    name = "overshoot"

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        self._rng = np.random.default_rng(self.seed)
        self._first = self.initial_designs

    def _ask(self):
        if self._first is not None:
            first, self._first = self._first, None
            return first
        width = self.space.upper - self.space.lower
        return self._rng.uniform(self.space.lower - 0.2 * width, self.space.upper + 0.2 * width,
                                 (self.population, self.space.dim))

    def _tell(self, designs, costs):
        pass


class NoSuperOptimizer(Optimizer):
    name = "no-super-opt"

    def __init__(self, space, **kwargs):
        self.space = space  # forgot super().__init__(space, **kwargs)
        self.population = kwargs.get("population", 1)

    def _ask(self):
        return self.space.sample(self.population, np.random.default_rng(0))

    def _tell(self, designs, costs):
        pass


class TestCoT(ObjectiveConformance):
    @pytest.fixture
    def objective(self):
        return CostOfTransport()


class TestNoSuperObjective(ObjectiveConformance):
    @pytest.fixture
    def objective(self):
        return NoSuperObjective()


class TestOvershoot(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return Overshoot


class TestNoSuperOptimizer(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return NoSuperOptimizer
'''


def test_new_checks_fail_exactly_the_broken_plugins(pytester):
    pytester.makepyfile(test_broken=BROKEN)
    result = pytester.runpytest_subprocess("-q", "-p", "no:cacheprovider", "-rf")
    failed = {
        line.split(" ")[1].split("::", 1)[1]
        for line in result.outlines
        if line.startswith("FAILED")
    }
    assert "TestCoT::test_standing_still_and_zero_commands_give_finite_costs" in failed
    assert (
        "TestCoT::test_one_finite_cost_per_env" not in failed
    )  # random steps never stand still: only the new check sees it
    assert "TestNoSuperObjective::test_calls_the_base_initialiser" in failed
    assert "TestOvershoot::test_proposals_stay_inside_the_bounds_without_clipping" in failed
    assert (
        "TestOvershoot::test_ask_returns_population_inside_bounds" not in failed
    )  # clipped: it looked fine before
    assert "TestNoSuperOptimizer::test_calls_the_base_initialiser" in failed
    assert "did not run" in "\n".join(result.outlines)


def test_an_out_of_bounds_proposal_is_clipped_and_warned_about():
    class Wide(Optimizer):
        name = "wide"

        def _ask(self):
            return np.array([[0.4, 1.0], [1.0, 1.2]])  # 0.4 lies below the lower bound 0.5

        def _tell(self, designs, costs):
            pass

    opt = Wide(
        DesignSpace([Continuous("a", 0.5, 1.5), Continuous("b", 0.5, 1.5)]), population=2, budget=1
    )
    with pytest.warns(
        OutOfBoundsProposal, match=r"proposed 1 of 2 designs outside the design space's bounds"
    ):
        designs = opt.ask()
    assert designs[0, 0] == 0.5 and opt.out_of_bounds == 1
    with warnings.catch_warnings():
        warnings.simplefilter(
            "error", OutOfBoundsProposal
        )  # rounding at a bound is no proposal outside it
        opt2 = type(
            "Edge", (Wide,), {"_ask": lambda self: np.array([[1.5 + 1e-12, 0.5 - 1e-12]] * 2)}
        )(
            DesignSpace([Continuous("a", 0.5, 1.5), Continuous("b", 0.5, 1.5)]),
            population=2,
            budget=1,
        )
        opt2.ask()
