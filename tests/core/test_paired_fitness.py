"""Paired real fitness (common random numbers, docs/coadaptation.md "Evaluation protocol"):
the scenario streams each design sees, the statistics behind every error bar, the final
check's stopping rule, and on real MuJoCo with the shipped policy that pairing holds and
that a ranking repeats across scenario seeds."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.coadapt.final_check import batch_errors, final_check
from coadapt_core.costs import (
    TRIM_SHARE,
    improvement_se,
    paired_difference,
    robust_cost,
    scenario_se,
)
from coadapt_core.fitness import RealFitness
from coadapt_core.objective import Objective
from coadapt_core.task.commands import CommandSampler
from coadapt_core.task.config import CommandConfig


class Cost(Objective):
    name = "cost"
    display_name = "cost"

    def step_cost(self, step):  # pragma: no cover - not stepped here
        raise NotImplementedError


# -- commands ------------------------------------------------------------------------------
def test_stratified_commands_are_a_fixed_vx_grid_and_a_latin_hypercube():
    cfg = CommandConfig(
        vx_range=(-0.5, 1.25),
        vy_range=(-0.4, 0.4),
        yaw_range=(-1.0, 1.0),
        zero_share=0.0,
        zero_threshold=0.0,
        curriculum=False,
    )
    sampler = CommandSampler(cfg, "cpu", torch.Generator())
    a = sampler.stratified(20, torch.Generator().manual_seed(0))
    b = sampler.stratified(20, torch.Generator().manual_seed(1))
    mid = -0.5 + 1.75 * (np.arange(20) + 0.5) / 20
    np.testing.assert_allclose(a[:, 0].numpy(), mid, atol=1e-6)  # the same vx grid for every seed
    np.testing.assert_allclose(b[:, 0].numpy(), mid, atol=1e-6)
    for j, (lo, hi) in ((1, (-0.4, 0.4)), (2, (-1.0, 1.0))):
        strata = np.floor((a[:, j].numpy() - lo) / (hi - lo) * 20).astype(int)
        assert sorted(strata.tolist()) == list(range(20))  # each stratum exactly once
    assert not torch.equal(a[:, 1], b[:, 1])  # the shuffle follows the seed


def test_stratified_commands_keep_the_zero_rules():
    cfg = CommandConfig(
        vx_range=(-0.5, 1.25),
        vy_range=(0.0, 0.0),
        yaw_range=(0.0, 0.0),
        zero_share=0.05,
        zero_threshold=0.1,
        curriculum=False,
    )
    cmd = CommandSampler(cfg, "cpu", torch.Generator()).stratified(40).numpy()
    standing = np.abs(cmd).sum(axis=1) == 0
    # the strata with |vx| < 0.1 stand (the threshold), and round(0.05 * 40) = 2 more, the slowest
    assert standing.sum() == int((np.abs(-0.5 + 1.75 * (np.arange(40) + 0.5) / 40) < 0.1).sum()) + 2
    moving = np.abs(cmd[~standing, 0])
    assert moving.min() > 0.1


# -- statistics ----------------------------------------------------------------------------
def test_robust_cost_drops_the_costliest_quarter_of_scenarios():
    per = np.arange(1.0, 9.0)[None, :, None]  # 8 scenarios costing 1..8
    assert TRIM_SHARE == 0.25
    assert robust_cost(per)[0, 0] == pytest.approx(np.mean([1, 2, 3, 4, 5, 6]))
    falls = per.copy()
    falls[0, 7, 0] = 1e6  # one fall among eight scenarios does not move the cost
    assert robust_cost(falls)[0, 0] == robust_cost(per)[0, 0]


def test_identical_designs_have_zero_paired_difference_and_pairing_beats_unpaired():
    rng = np.random.default_rng(0)
    shared = rng.lognormal(0.0, 0.6, size=64)  # what a scenario does to every design
    per = np.stack([shared * 1.0, shared * 1.0, shared * 0.9 + rng.normal(0, 0.02, 64)])[:, :, None]
    diff, se = paired_difference(per, 0, 1)
    assert diff[0] == 0.0 and se[0] == 0.0
    diff, paired = paired_difference(per, 2, 0)
    unpaired = np.hypot(*scenario_se(per)[[2, 0], 0])
    assert diff[0] < 0 and paired[0] < 0.25 * unpaired  # the shared spread cancels
    assert (scenario_se(per) > 0).all()


def test_improvement_se_matches_the_spread_of_repeated_experiments():
    rng = np.random.default_rng(1)
    objective = Cost()
    values, ses = [], []
    for _ in range(200):
        shared = rng.lognormal(0.0, 0.5, size=32)
        nominal = shared + rng.normal(0, 0.1, 32)
        best = 0.8 * shared + rng.normal(0, 0.1, 32)
        per = np.stack([best, nominal])[:, :, None]
        cost = robust_cost(per)[:, 0]
        values.append(objective.improvement(cost[0], cost[1]))
        ses.append(improvement_se(objective, best, nominal))
    # the bootstrap error bar of one experiment estimates the spread over experiments
    assert np.mean(ses) == pytest.approx(np.std(values), rel=0.3)
    assert np.mean(values) == pytest.approx(0.2, abs=0.03)


# -- the final check -----------------------------------------------------------------------
def _synthetic(effect: float, agents: int = 16):
    """real_fitness(designs, block) for [candidate, nominal]: paired scenarios, the candidate
    `effect` cheaper (relative), scenario noise shared plus a little of its own."""
    calls = []

    def real_fitness(designs, block):
        calls.append(block)
        rng = np.random.default_rng(block)
        shared = rng.lognormal(0.0, 0.5, size=agents)
        own = rng.normal(0.0, 0.15, size=(len(designs), agents))
        scale = np.array([1.0 - effect] * (len(designs) - 1) + [1.0])[:, None]
        per = (scale * shared[None, :] + own)[:, :, None]
        return RealFitness(
            costs=robust_cost(per),
            buffer=None,
            interactions=len(designs) * agents,
            seconds=0.0,
            per_scenario=per,
            cost_se=scenario_se(per),
            fall_rate=np.zeros(len(designs)),
        )

    return real_fitness, calls


def test_final_check_stops_once_the_improvement_is_four_standard_errors():
    fitness, calls = _synthetic(0.3)
    check = final_check(fitness, np.array([[0.5, 0.5], [1.0, 1.0]]), [Cost()], max_blocks=8)
    gain = Cost().improvement(check.fit.costs[0, 0], check.fit.costs[1, 0])
    assert check.significant is True and gain >= 4 * check.improvement_se["cost"]
    assert calls == list(range(1, check.blocks + 1)) and check.scenarios == 16 * check.blocks
    assert check.blocks < 8


def test_final_check_says_not_significant_when_there_is_nothing_to_find():
    fitness, calls = _synthetic(0.0)
    check = final_check(
        fitness, np.array([[0.5, 0.5], [0.6, 0.6], [1.0, 1.0]]), [Cost()], max_blocks=3
    )
    assert check.significant is False and check.blocks == 3 and calls == [1, 2, 3]
    summary = check.uncertainty(["cost"])
    assert (
        summary["improvement_se"] > 0
        and summary["best_cost_se"] > 0
        and summary["final_scenarios"] == 48
    )


def test_final_check_without_per_scenario_costs_evaluates_once():
    def plain(designs, block):
        return RealFitness(costs=np.array([[1.0], [2.0]]), buffer=None, interactions=2, seconds=0.0)

    check = final_check(plain, np.array([[0.5, 0.5], [1.0, 1.0]]), [Cost()], max_blocks=5)
    assert (
        check.blocks == 1
        and check.significant is None
        and check.uncertainty(["cost"])["improvement_se"] is None
    )


def test_a_real_round_records_its_error_bars_and_fall_rate():
    fitness, _ = _synthetic(0.3)
    fit = fitness(np.array([[0.5, 0.5], [1.0, 1.0]]), 1)
    fit.fall_rate = np.array([0.25, 0.0])
    errors = batch_errors(fit)
    assert errors["best_cost_se"] == pytest.approx(fit.cost_se[0, 0]) and errors["best_cost_se"] > 0
    assert errors["best_fall_rate"] == 0.25 and errors["fall_rate"] == 0.125
    assert 0 < errors["median_relative_se"] < 1
    assert (
        batch_errors(RealFitness(costs=np.ones((2, 1)), buffer=None, interactions=2, seconds=0.0))
        == {}
    )


# -- real MuJoCo, the shipped policy ---------------------------------------------------------
@pytest.fixture(scope="module")
def shipped_backend():
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    checkpoint = shipped_checkpoint("kuafu", "flat")
    assert checkpoint is not None, "the built-in Kuafu robot ships flat.pt"
    robot, sim_cls, objectives = resolve_plugins("kuafu", "mujoco", ["tracking", "power", "torque"])
    backend = make_backend(
        robot, sim_cls, objectives, terrain="flat", checkpoint=str(checkpoint), agents_per_design=4
    )
    yield backend, objectives
    backend.close()


def test_every_design_sees_the_same_scenarios(shipped_backend):
    backend, objectives = shipped_backend
    designs = np.array([[1.0, 1.0], [0.7, 1.3], [1.0, 1.0]])
    fit = backend.real_fitness(designs, objectives, agents=4, steps=40, seed=3)
    env = backend.trainer.eval_env
    a = 4
    cmd = env.command.reshape(3, a, 3)
    assert torch.equal(cmd[0], cmd[1]) and torch.equal(cmd[0], cmd[2])  # agent i: one command
    assert len(torch.unique(cmd[0, :, 0])) == a  # stratified: four different speeds
    params = env.sim.env_params
    for field in ("friction", "restitution", "pd_factor", "motor_strength", "delay"):
        values = getattr(params, field).reshape(3, a)
        assert np.array_equal(values[0], values[1]) and np.array_equal(values[0], values[2]), field
        assert len(np.unique(values[0])) == a, field  # a different draw per agent
    # identical designs: every scenario costs the same, the paired difference is exactly 0
    np.testing.assert_array_equal(fit.per_scenario[0], fit.per_scenario[2])
    diff, se = paired_difference(fit.per_scenario, 0, 2)
    assert (diff == 0).all() and (se == 0).all()
    assert fit.cost_se.shape == (3, 3) and (fit.cost_se > 0).all() and fit.fall_rate.shape == (3,)
    # a design's scenarios do not depend on the other designs of the call
    alone = backend.real_fitness(designs[1:2], objectives, agents=4, steps=40, seed=3)
    np.testing.assert_allclose(alone.per_scenario[0], fit.per_scenario[1], rtol=1e-5)
    other = backend.real_fitness(designs[:1], objectives, agents=4, steps=40, seed=4)
    assert not np.allclose(
        other.per_scenario[0], fit.per_scenario[0]
    )  # another seed, other scenarios


def test_ranking_of_two_clearly_different_designs_repeats_across_scenario_seeds(shipped_backend):
    backend, objectives = shipped_backend
    designs = np.array(
        [[0.7, 0.7], [1.3, 1.3]]
    )  # short legs: far lower torque (Table 6's direction)
    orders = []
    for seed in (0, 1):
        fit = backend.real_fitness(designs, objectives, agents=16, steps=100, seed=seed)
        torque = fit.costs[:, 2]
        diff, se = paired_difference(fit.per_scenario, 0, 1)
        assert diff[2] < 0 and abs(diff[2]) > 4 * se[2]  # significant on one seed alone
        orders.append(np.argsort(torque).tolist())
    assert orders[0] == orders[1] == [0, 1]
