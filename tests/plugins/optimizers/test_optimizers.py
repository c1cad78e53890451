"""The built-in optimizers: conformance, convergence to a known optimum, options, state as JSON."""

from __future__ import annotations

import json

import numpy as np
import pytest
from coadapt_plugins.optimizers.bo import BOOptimizer
from coadapt_plugins.optimizers.mixed_pso import MixedPSOOptimizer
from coadapt_plugins.optimizers.nsga2 import NSGA2Optimizer
from coadapt_plugins.optimizers.pso import PSOOptimizer

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import UserError
from coadapt_core.pareto import pareto_mask
from coadapt_core.plugins import get_registry
from coadapt_core.testing import OptimizerConformance

SPACE = DesignSpace([Continuous("thigh", 0.5, 1.5), Continuous("shank", 0.5, 1.5)])
MIXED = DesignSpace(
    [
        Continuous("thigh", 0.5, 1.5),
        Continuous("shank", 0.5, 1.5),
        Discrete("hip", (1, 2, 3)),
        Discrete("knee", (1, 2, 3)),
    ]
)


class TestPSOConformance(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return PSOOptimizer


class TestMixedPSOConformance(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return MixedPSOOptimizer


class TestBOConformance(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return BOOptimizer

    @pytest.fixture
    def convergence_budget(self) -> int:
        return 60  # one design per round, so more rounds than the swarms need


class TestNSGA2Conformance(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return NSGA2Optimizer


def run(opt, cost):
    while not opt.done:
        d = opt.ask()
        opt.tell(d, cost(d))
    return opt


def test_pso_reaches_known_optimum_within_0_02():
    optimum = np.array([0.55, 1.37])
    opt = run(
        PSOOptimizer(SPACE, population=20, budget=25, seed=0), lambda d: ((d - optimum) ** 2).sum(1)
    )
    best, cost = opt.best()
    assert np.abs(best - optimum).max() < 0.02
    assert cost < 4e-4


def test_pso_starts_from_initial_designs_and_uses_set_coefficients():
    initial = SPACE.sample(6, rng=1)
    opt = PSOOptimizer(
        SPACE, population=6, budget=2, seed=0, initial_designs=initial, inertia=0.5, c1=1.0, c2=1.5
    )
    np.testing.assert_allclose(opt.ask(), initial)
    algorithm = opt._algorithm
    assert (algorithm.w, algorithm.c1, algorithm.c2, algorithm.adaptive) == (0.5, 1.0, 1.5, False)


def test_pso_rejects_wrong_initial_shape_and_negative_inertia():
    with pytest.raises(UserError, match="initial_designs"):
        PSOOptimizer(SPACE, population=4, initial_designs=SPACE.sample(3, rng=0))
    with pytest.raises(UserError, match="inertia"):
        PSOOptimizer(SPACE, population=4, inertia=-0.1)


def test_mixed_pso_finds_continuous_and_discrete_optimum():
    optimum = np.array([0.8, 1.2])

    def cost(d):
        # motor 3 at the hip and 2 at the knee are best; a wrong motor costs 0.3 each
        return ((d[:, :2] - optimum) ** 2).sum(1) + 0.3 * (d[:, 2] != 3) + 0.3 * (d[:, 3] != 2)

    opt = run(MixedPSOOptimizer(MIXED, population=16, budget=25, seed=2), cost)
    best, value = opt.best()
    assert best[2:].tolist() == [3.0, 2.0]
    assert np.abs(best[:2] - optimum).max() < 0.03
    assert value < 1e-3


def test_mixed_pso_keeps_relaxed_position_as_particle_state():
    opt = MixedPSOOptimizer(MIXED, population=5, budget=3, seed=0)
    d = opt.ask()
    opt.tell(d, d[:, 0])
    d2 = opt.ask()
    # the particle state is not on bin centres, yet what is asked decodes exactly
    centres = (np.arange(3) + 0.5) / 3
    assert not np.all(np.isin(np.round(opt.x[:, 2], 9), np.round(centres, 9)))
    np.testing.assert_allclose(d2, MIXED.decode(opt.x))
    assert np.all(np.abs(opt.v) <= opt.max_velocity + 1e-12)


def test_bo_handles_mixed_space_and_finds_motor():
    def cost(d):
        return ((d[:, :2] - 1.0) ** 2).sum(1) + 0.5 * (d[:, 3] != 3)

    opt = run(BOOptimizer(MIXED, population=1, budget=40, seed=0), cost)
    best, value = opt.best()
    assert best[3] == 3.0 and value < 0.02


@pytest.mark.slow
def test_bo_gp_sampler_and_bad_sampler():
    opt = run(
        BOOptimizer(SPACE, budget=12, seed=0, sampler="gp", n_startup_trials=4),
        lambda d: ((d - 1.1) ** 2).sum(1),
    )
    assert opt.best()[1] < 0.05
    with pytest.raises(UserError, match="sampler"):
        BOOptimizer(SPACE, sampler="cmaes")


def test_bo_study_in_sqlite_storage_survives_a_state_round_trip(tmp_path):
    import optuna

    url = f"sqlite:///{tmp_path / 'study.db'}"
    a = BOOptimizer(SPACE, budget=6, seed=3, storage=url, study_name="s")
    b = BOOptimizer(SPACE, budget=6, seed=3, study_name="mem")
    for _ in range(3):
        for opt in (a, b):
            d = opt.ask()
            opt.tell(d, d.sum(1))
    state = json.loads(json.dumps(a.state_dict()))
    a = BOOptimizer(SPACE, budget=6, seed=3, storage=url, study_name="s")
    a.load_state_dict(state)
    assert (
        len(optuna.load_study(study_name="s", storage=url).trials) == 3
    )  # in the database, not told twice
    np.testing.assert_allclose(a.ask(), b.ask())


def test_nsga2_pareto_front_is_non_dominated_and_spans_tradeoff():
    a, b = np.array([0.6, 0.6]), np.array([1.4, 1.4])

    def cost(d):
        return np.stack([((d - a) ** 2).sum(1), ((d - b) ** 2).sum(1)], axis=1)

    opt = run(NSGA2Optimizer(SPACE, population=20, budget=20, seed=0, num_objectives=2), cost)
    designs, costs = opt.pareto_front()
    assert len(designs) >= 10
    assert pareto_mask(costs).all()
    # the true front is the segment from a to b: every front design lies close to it
    off_segment = np.abs(designs[:, 0] - designs[:, 1])
    assert off_segment.mean() < 0.1 and off_segment.max() < 0.3
    assert costs[:, 0].min() < 0.01 and costs[:, 1].min() < 0.01


def test_nsga2_refuses_single_objective():
    with pytest.raises(UserError, match="at least 2 objectives"):
        NSGA2Optimizer(SPACE, num_objectives=1)


@pytest.mark.parametrize("cls", [PSOOptimizer, MixedPSOOptimizer, BOOptimizer, NSGA2Optimizer])
def test_json_state_continues_identically(cls):
    m = 2 if cls.multi_objective else 1

    def cost(d):
        f = ((d - 0.9) ** 2).sum(1)
        return np.stack([f, d.sum(1)], 1) if m == 2 else f

    a = cls(SPACE, population=6, budget=6, seed=5, num_objectives=m)
    for _ in range(2):
        d = a.ask()
        a.tell(d, cost(d))
    b = cls(SPACE, population=6, budget=6, seed=5, num_objectives=m)
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    for _ in range(3):
        da, db = a.ask(), b.ask()
        np.testing.assert_allclose(da, db)
        a.tell(da, cost(da))
        b.tell(db, cost(db))


def test_all_registered_under_their_names():
    registry = get_registry()
    for name, cls in {
        "pso": PSOOptimizer,
        "mixed-pso": MixedPSOOptimizer,
        "bo": BOOptimizer,
        "nsga2": NSGA2Optimizer,
    }.items():
        assert registry.get("optimizer", name) is cls
