"""The gradient optimizer (issue 52): conformance, steps along a given gradient toward a known
minimum, bounds and motor types kept, the trust region's rules, state as JSON, bad options."""

from __future__ import annotations

import json

import numpy as np
import pytest
from coadapt_plugins.optimizers.gradient import GradientOptimizer

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import UserError
from coadapt_core.optimizer import follows_surrogate_slope
from coadapt_core.testing import OptimizerConformance

SPACE = DesignSpace([Continuous("thigh", 0.5, 1.5), Continuous("shank", 0.5, 1.5)])
MIXED = DesignSpace([*SPACE.variables, Discrete("hip", (1, 2, 3)), Discrete("knee", (1, 2, 3))])
OPTIMUM = np.array([0.62, 1.31])


class TestGradientConformance(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return GradientOptimizer

    @pytest.fixture
    def convergence_budget(self) -> int:
        return 60  # one design per round, as BO

    @pytest.fixture
    def optimizer_options(self) -> dict:
        # the sphere has no surrogate: the linear model's steps need a floor below the
        # defaults' 0.05 (sized for noisy real costs) to reach 1e-4
        return {"min_step": 0.001}


def bowl(designs: np.ndarray) -> np.ndarray:
    return ((np.atleast_2d(designs)[:, :2] - OPTIMUM) ** 2).sum(axis=1)


def bowl_gradient(designs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    designs = np.atleast_2d(designs)
    grads = np.zeros_like(designs)
    grads[:, :2] = 2.0 * (designs[:, :2] - OPTIMUM)
    return bowl(designs), grads


def step(opt: GradientOptimizer, cost=bowl, gradient=bowl_gradient) -> np.ndarray:
    opt.set_slope(gradient)
    design = opt.ask()
    opt.tell(design, cost(design))
    return design[0]


def test_declares_it_follows_the_surrogate_slope():
    assert follows_surrogate_slope(GradientOptimizer)
    assert GradientOptimizer.sequential and GradientOptimizer.supports_mixed


def test_starts_at_the_start_design_then_steps_down_the_gradient_by_the_radius():
    opt = GradientOptimizer(SPACE, budget=5, start_at="1.0,1.0", step_size=0.1)
    np.testing.assert_allclose(step(opt), [1.0, 1.0])
    second = step(opt)
    direction = -(np.array([1.0, 1.0]) - OPTIMUM) / np.linalg.norm(np.array([1.0, 1.0]) - OPTIMUM)
    # a step of 0.1 of the range (1.0 wide) along the negative gradient
    np.testing.assert_allclose(second, np.array([1.0, 1.0]) + 0.1 * direction, atol=1e-12)
    assert bowl(second)[0] < bowl(np.array([1.0, 1.0]))[0]
    assert opt.last_step["accepted"] and opt.last_step["source"] == "surrogate"
    assert opt.radius == pytest.approx(0.15)  # grown by 1.5 after an accepted step
    assert opt.last_step["surrogate_cost"] == pytest.approx(bowl(second)[0])


def test_reaches_the_known_minimum_from_the_nominal_design():
    opt = GradientOptimizer(SPACE, budget=40, start_at="1.0,1.0")
    while not opt.done:
        step(opt)
    np.testing.assert_allclose(opt.center, OPTIMUM, atol=5e-3)


def test_trust_region_shrinks_after_a_step_whose_real_cost_does_not_improve():
    opt = GradientOptimizer(SPACE, budget=5, start_at="1.0,1.0", step_size=0.2, shrink=0.5)
    step(opt)
    center = opt.center.copy()
    # the real cost disagrees with the surrogate: every step away costs more
    worse = lambda d: bowl(d) * 0 + 1.0 + np.abs(d - center).sum()  # noqa: E731
    opt.center_cost = 1.0
    proposed = step(opt, cost=worse)
    assert not opt.last_step["accepted"]
    assert opt.radius == pytest.approx(0.1)
    np.testing.assert_allclose(opt.center, center)  # the centre stays
    again = step(opt, cost=worse)
    # the next step from the same centre along the same gradient is half as long
    assert np.linalg.norm(again - center) == pytest.approx(0.5 * np.linalg.norm(proposed - center))


def test_a_step_the_surrogate_itself_says_overshoots_is_halved_before_it_is_evaluated():
    """A steep bowl 0.05 from the start: a step of 0.3 lands past it (the surrogate predicts
    a higher cost than the centre's), so it is halved on the surrogate until it improves."""
    optimum = np.array([0.95, 1.0])

    def steep(designs):
        designs = np.atleast_2d(designs)
        return 100 * ((designs - optimum) ** 2).sum(axis=1), 200 * (designs - optimum)

    opt = GradientOptimizer(SPACE, budget=3, start_at="1.0,1.0", step_size=0.3, max_step=0.3)
    step(opt, cost=lambda d: steep(d)[0], gradient=steep)
    proposal = step(opt, cost=lambda d: steep(d)[0], gradient=steep)
    last = opt.last_step
    # 0.3 and 0.15 overshoot (cost 6.25 and 1.0 against 0.25 at the centre); 0.075 improves
    assert last["length"] == pytest.approx(0.075)
    np.testing.assert_allclose(proposal, [0.925, 1.0], atol=1e-12)
    assert last["surrogate_cost"] == pytest.approx(0.0625)
    assert last["surrogate_center"] == pytest.approx(0.25)
    assert last["accepted"] and opt.radius == pytest.approx(0.3)  # grown, capped at max_step


def test_the_radius_never_shrinks_below_min_step():
    opt = GradientOptimizer(SPACE, budget=12, start_at="1.0,1.0", step_size=0.1, min_step=0.02)
    step(opt)
    worse = lambda d: np.full(len(np.atleast_2d(d)), 5.0)  # noqa: E731
    radii = []
    for _ in range(8):
        step(opt, cost=worse)
        radii.append(opt.radius)
    assert radii[:3] == pytest.approx([0.05, 0.025, 0.02]) and min(radii) == pytest.approx(0.02)


def test_a_step_is_projected_onto_the_bounds():
    """The minimum of the gradient lies outside the range: the design stops at the bound and
    the slope along a variable pinned there no longer moves the others off course."""
    outside = np.array([0.2, 1.2])

    def gradient(designs):
        designs = np.atleast_2d(designs)
        return ((designs - outside) ** 2).sum(axis=1), 2.0 * (designs - outside)

    opt = GradientOptimizer(SPACE, budget=30, start_at="0.6,1.0", step_size=0.2)
    seen = []
    while not opt.done:
        seen.append(step(opt, cost=lambda d: gradient(d)[0], gradient=gradient))
    seen = np.array(seen)
    assert (seen >= SPACE.lower).all() and (seen <= SPACE.upper).all()
    np.testing.assert_allclose(opt.center, [0.5, 1.2], atol=5e-3)


def test_motor_types_stay_the_start_designs():
    opt = GradientOptimizer(MIXED, budget=8, start_at="1.0,1.0,2,3")
    designs = [step(opt) for _ in range(8)]
    assert all(d[2] == 2 and d[3] == 3 for d in designs)
    assert bowl(opt.center)[0] < bowl(np.array([1.0, 1.0]))[0]


def test_without_a_gradient_it_probes_then_fits_a_linear_model():
    opt = GradientOptimizer(SPACE, budget=4, start_at="1.0,1.0", step_size=0.1)
    kinds = []
    for _ in range(4):
        design = opt.ask()
        opt.tell(design, bowl(design))
        kinds.append((opt.last_step["kind"], opt.last_step.get("source")))
    assert kinds == [("start", None), ("probe", "model"), ("probe", "model"), ("step", "model")]


def test_state_resumes_a_descent_where_it_stopped():
    a = GradientOptimizer(SPACE, budget=10, start_at="1.0,1.0")
    for _ in range(4):
        step(a)
    b = GradientOptimizer(SPACE, budget=10, start_at="1.0,1.0")
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    assert b.radius == a.radius and b.steps == a.steps
    np.testing.assert_allclose(step(b), step(a))


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"step_size": 0.0}, "step_size"),
        ({"step_size": -0.1}, "step_size"),
        ({"shrink": 1.0}, "shrink"),
        ({"step_size": 0.5, "max_step": 0.2}, "max_step"),
        ({"start_at": "1.0"}, "start_at"),
        ({"min_step": 0.3}, "min_step"),
        ({"backtracks": -1}, "backtracks"),
    ],
)
def test_bad_options_are_one_line_naming_the_field(options, field):
    with pytest.raises(UserError) as err:
        GradientOptimizer(SPACE, budget=3, **options)
    assert field in str(err.value) and "\n" not in str(err.value)
