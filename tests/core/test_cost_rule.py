"""The cost rule (docs/coadaptation.md, "How a fall enters the fitness"): every design scored
on the same scenarios by the same rule, a fall priced at the cap, the plain mean and fall
rates beside the cost, and the final check's fall gate."""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.coadapt.final_check import batch_errors, final_check
from coadapt_core.coadapt.reliability import fall_verdict
from coadapt_core.costs import (
    TRIMMED,
    CostRule,
    compare_designs,
    fall_statistics,
    falls_more,
    paired_difference,
    plain_mean,
    robust_cost,
)
from coadapt_core.fitness import RealFitness
from coadapt_core.objective import Objective


class Cost(Objective):
    name = "cost"
    display_name = "cost"

    def step_cost(self, step):  # pragma: no cover - not stepped here
        raise NotImplementedError


def test_a_fall_costs_the_cap_whatever_the_scenario_cost():
    per = np.array([[1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 40.0]])[
        :, :, None
    ]  # [2 designs, 4 scenarios, 1]
    falls = np.array([[False, False, False, False], [True, False, False, True]])
    rule = CostRule("capped", cap=3.0)
    ref = rule.reference(per[0], falls[0])
    assert ref[0] == pytest.approx(2.5)  # the nominal design's median scenario
    values = rule.scenario_values(per, falls, ref)
    # design 1 fell in scenario 0, where it cost only 1: the fall costs the cap, 7.5
    np.testing.assert_allclose(values[1, :, 0], [7.5, 2.0, 3.0, 7.5])
    np.testing.assert_allclose(values[0, :, 0], [1.0, 2.0, 3.0, 4.0])  # under the cap, unchanged
    assert rule.cost(per, falls, ref)[1, 0] == pytest.approx(np.mean([7.5, 2.0, 3.0, 7.5]))


def test_falling_never_lowers_a_designs_cost_under_the_capped_rule():
    rng = np.random.default_rng(0)
    rule = CostRule("capped", cap=3.0)
    for _ in range(50):
        per = rng.lognormal(0.0, 0.8, size=(3, 32, 2))
        falls = rng.random((3, 32)) < 0.1
        ref = rule.reference(per[-1], falls[-1])
        base = rule.cost(per, falls, ref)
        more = falls.copy()
        more[0, rng.integers(0, 32)] = True  # one more fall, its scenario's cost as before
        assert (rule.cost(per, more, ref)[0] >= base[0] - 1e-12).all()
        # under the trimmed rule the same fall can be free: it lands in the dropped quarter
    per = np.arange(1.0, 9.0)[None, :, None]
    assert TRIMMED.cost(per)[0, 0] == robust_cost(per)[0, 0]


def test_the_trimmed_rule_drops_each_designs_worst_scenarios_separately_and_misses_falls():
    """What the capped rule fixes: under the trimmed mean a design that falls in a quarter of
    its scenarios costs as little as one that never falls; the capped rule prices them."""
    scen = np.linspace(1.0, 2.0, 16)
    fall_cost = 30.0  # a fall scenario costs 3 to 33 times the median (measured)
    per = np.stack([scen * 0.95, scen])[:, :, None]  # design 0 is 5 % cheaper when it walks
    per[0, -4:, 0] = fall_cost  # it falls in the four hardest scenarios
    falls = np.zeros((2, 16), dtype=bool)
    falls[0, -4:] = True
    trimmed = TRIMMED.cost(per)
    assert trimmed[0, 0] < trimmed[1, 0]  # trimmed: the falling design "wins"
    capped = CostRule("capped", 3.0)
    c = capped.cost(per, falls, capped.reference(per[1], falls[1]))
    assert c[0, 0] > c[1, 0]  # capped: its four falls cost more than its 5 % saving
    assert (
        plain_mean(per)[0, 0] > plain_mean(per)[1, 0]
    )  # the plain mean agrees with the capped rule


def test_the_capped_rule_keeps_the_pairing_and_a_design_costs_the_same_in_any_batch():
    rng = np.random.default_rng(1)
    shared = rng.lognormal(0.0, 0.6, size=64)
    per = np.stack([shared, shared, 0.9 * shared + rng.normal(0, 0.02, 64)])[:, :, None]
    falls = np.zeros((3, 64), dtype=bool)
    rule = CostRule("capped")
    ref = rule.reference(per[0], falls[0])
    values = rule.scenario_values(per, falls, ref)
    diff, se = paired_difference(values, 0, 1, rule.aggregate)
    assert diff[0] == 0.0 and se[0] == 0.0
    alone = rule.cost(per[2:3], falls[2:3], ref)
    assert alone[0, 0] == rule.cost(per, falls, ref)[2, 0]
    with pytest.raises(ValueError, match="reference"):
        rule.cost(per, falls, None)
    with pytest.raises(ValueError, match="one of"):
        CostRule("median")
    with pytest.raises(ValueError, match="> 1"):
        CostRule("capped", cap=1.0)


def test_mean_rule_is_the_plain_mean():
    per = np.random.default_rng(2).lognormal(size=(2, 10, 3))
    falls = np.ones((2, 10), dtype=bool)
    np.testing.assert_allclose(CostRule("mean").cost(per, falls), per.mean(axis=1))


def test_compare_designs_reports_both_costs_with_paired_errors_and_fall_rates():
    rng = np.random.default_rng(3)
    shared = rng.lognormal(0.0, 0.4, size=128)
    per = np.stack([0.8 * shared + rng.normal(0, 0.02, 128), shared])[:, :, None]
    falls = np.zeros((2, 128), dtype=bool)
    falls[0, :6] = True  # the candidate falls in 6 scenarios, the nominal design in none
    per[0, :6, 0] = 20.0
    out = compare_designs(CostRule("capped"), [Cost()], per, falls, 0, 1)
    o = out["objectives"]["cost"]
    assert (
        o["cost_se"] > 0
        and o["plain_mean_se"] > 0
        and o["improvement_se"] > 0
        and o["improvement_plain_se"] > 0
    )
    assert o["plain_mean"] == pytest.approx(per[0, :, 0].mean())
    assert o["improvement_plain"] == pytest.approx(1 - per[0, :, 0].mean() / per[1, :, 0].mean())
    assert out["fall_rate"] == pytest.approx(6 / 128) and out["reference_fall_rate"] == 0.0
    assert out["fall_rate_difference"] == pytest.approx(6 / 128)
    d = np.r_[np.ones(6), np.zeros(122)]
    assert out["fall_rate_difference_se"] == pytest.approx(d.std(ddof=1) / np.sqrt(128))
    assert falls_more(out["fall_rate_difference"], out["fall_rate_difference_se"], 0.01)
    assert not falls_more(0.009, 0.001, 0.01) and not falls_more(
        0.03, 0.02, 0.01
    )  # within max(1 pt, 2 SE)


def test_fall_statistics_of_identical_designs():
    falls = np.array([[True, False, False, True], [True, False, False, True]])
    st = fall_statistics(falls, 0, 1)
    assert (
        st["fall_rate"] == 0.5
        and st["fall_rate_difference"] == 0.0
        and st["fall_rate_difference_se"] == 0.0
    )


def _with_falls(fall_rates: list[float], effects: list[float], agents: int = 64):
    """real_fitness(designs, block): candidates `effects` cheaper when they walk, each falling
    in the first fall_rate x agents scenarios of every block (a fall costs 20x)."""

    def real_fitness(designs, block):
        rng = np.random.default_rng(block)
        shared = rng.lognormal(0.0, 0.3, size=agents)
        scale = np.array([1.0 - e for e in effects] + [1.0])[:, None]
        per = scale * shared[None, :] + rng.normal(0.0, 0.02, size=(len(designs), agents))
        falls = np.zeros((len(designs), agents), dtype=bool)
        for i, rate in enumerate([*fall_rates, 0.0]):
            falls[i, : int(round(rate * agents))] = True
        per = np.where(falls, 20.0, per)[:, :, None]
        return RealFitness(
            costs=per.mean(axis=1),
            buffer=None,
            interactions=len(designs) * agents,
            seconds=0.0,
            per_scenario=per,
            fall_rate=falls.mean(axis=1),
            scenario_falls=falls,
        )

    return real_fitness


def test_final_check_never_picks_a_candidate_that_falls_more_than_nominal():
    designs = np.array([[0.5, 0.5], [0.7, 0.7], [1.0, 1.0]])
    # candidate 0: 40 % cheaper when it walks but falls in 10 % of scenarios;
    # candidate 1: 10 % cheaper, no falls
    fitness = _with_falls([0.10, 0.0], [0.4, 0.1])
    check = final_check(
        fitness,
        designs,
        [Cost()],
        max_blocks=4,
        min_blocks=2,
        rule=CostRule("capped"),
        fall_tolerance=0.01,
    )
    assert check.best == 1 and check.blocks >= 2
    assert check.fall_check[0]["eligible"] is False and check.fall_check[1]["eligible"] is True
    summary = check.uncertainty(["cost"])
    assert summary["best_fall_rate"] == 0.0 and summary["fall_rate_difference"] == 0.0
    assert (
        summary["improvement_plain"] > 0
        and summary["best_plain_mean_se"] > 0
        and summary["best_is_nominal"] is False
    )
    # with the gate off (tolerance 1) the trimmed rule of old picks the faller
    old = final_check(fitness, designs, [Cost()], max_blocks=2, rule=TRIMMED)
    assert old.best == 0


def test_final_check_keeps_the_nominal_design_when_every_candidate_falls_more():
    designs = np.array([[0.5, 0.5], [0.7, 0.7], [1.0, 1.0]])
    check = final_check(
        _with_falls([0.10, 0.08], [0.4, 0.3]),
        designs,
        [Cost()],
        max_blocks=2,
        min_blocks=2,
        rule=CostRule("capped"),
        fall_tolerance=0.01,
    )
    assert check.best == 2
    summary = check.uncertainty(["cost"])
    assert summary["best_is_nominal"] is True and summary["improvement_plain"] == 0.0


def test_reliability_says_when_the_best_design_falls_more():
    summary = {
        "reliable": True,
        "reliability": "passed",
        "best_fall_rate": 0.043,
        "nominal_fall_rate": 0.004,
        "fall_rate_difference": 0.039,
        "fall_rate_difference_se": 0.013,
    }
    out = fall_verdict(summary)
    assert out["falls_more"] is True and out["reliable"] is False
    assert (
        "4.3 %" in out["reliability"]
        and "0.4 %" in out["reliability"]
        and "3.9 +- 1.3" in out["reliability"]
    )
    assert fall_verdict(
        {**summary, "fall_rate_difference": 0.02, "fall_rate_difference_se": 0.012}
    ) == {"falls_more": False}
    assert fall_verdict({}) == {"falls_more": None}


def test_a_real_round_records_the_plain_mean_and_fall_rate_of_its_best_design():
    fit = _with_falls([0.25, 0.0], [0.5, 0.1], agents=16)(
        np.array([[0.5, 0.5], [0.7, 0.7], [1.0, 1.0]]), 1
    )
    rule = CostRule("capped")
    ref = rule.reference(fit.per_scenario[-1], fit.scenario_falls[-1])
    errors = batch_errors(fit, rule, ref)
    # under the capped rule the faller (0.5 cheaper, 25 % falls) is not the round's best
    assert errors["best_fall_rate"] == 0.0 and errors["best_fall_rate_se"] == 0.0
    assert errors["best_plain_mean"] == pytest.approx(fit.per_scenario[1, :, 0].mean())
    assert errors["best_cost_se"] > 0


# -- the loop on an analytic backend with falls --------------------------------------------
class FallingBackend:
    """The analytic torque bowl (optimum (0.6, 0.6)) with paired scenarios, and a fall region
    (both scales below 0.75) where designs walk 15 % cheaper but fall in 15 % of scenarios
    (a fall scenario costs 20 x): what the trimmed rule rewarded."""

    def __init__(self, seed: int = 0):
        from tests.fakes.analytic import AnalyticBackend

        self.inner = AnalyticBackend(seed)
        self.real_calls = 0

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def real_fitness(self, designs, objectives, *, agents, steps, seed=0):
        from tests.fakes.analytic import true_cost

        self.real_calls += 1
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        rng = np.random.default_rng(seed)
        shared = rng.lognormal(0.0, 0.2, size=agents)  # what a scenario does to every design
        u = rng.random(agents)  # the scenario's "hardness": the same for every design
        falling = (designs[:, 0] < 0.75) & (designs[:, 1] < 0.75)  # [K]
        base = np.stack([true_cost(designs, o.name) for o in objectives], axis=1)  # [K, M]
        base = np.where(falling[:, None], 0.85 * base, base)
        per = base[:, None, :] * shared[None, :, None] + rng.normal(
            0, 0.01, size=(len(designs), agents, len(objectives))
        )
        falls = falling[:, None] & (u[None, :] < 0.15)
        per = np.where(falls[:, :, None], 20.0 * per, per)
        buffer = {"kind": "evaluation", "designs": designs.copy()}
        return RealFitness(
            costs=per.mean(axis=1),
            buffer=buffer,
            interactions=len(designs) * agents * steps,
            seconds=0.0,
            per_scenario=per,
            scenario_falls=falls,
            fall_rate=falls.mean(axis=1),
            survival=1.0 - falls.mean(axis=1),
        )


def _falling_run(tmp_path, rule: str, fall_tolerance: float = 0.01):
    from coadapt_plugins.objectives.locomotion import TorqueObjective

    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.coadapt.run import run_coadaptation
    from tests.fakes.analytic import NOMINAL, SPACE

    backends = []

    def factory(seed):
        backends.append(FallingBackend(seed))
        return backends[-1]

    config = make_config(
        "smoke",
        overrides=dict(
            population=16,
            optimizer_iterations=4,
            outer_iterations=2,
            agents_per_design=64,
            eval_steps=10,
            train_steps=1000,
            retrain_steps=1000,
            out=str(tmp_path / f"{rule}-{fall_tolerance}"),
            cost_rule=rule,
            fall_tolerance=fall_tolerance,
            surrogate_probability=0.0,
        ),
    )
    result = run_coadaptation(
        config,
        backend_factory=factory,
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
    )
    return result, backends


def test_a_capped_run_does_not_buy_cost_with_falls_where_a_trimmed_one_did(tmp_path):
    import yaml

    trimmed, _ = _falling_run(
        tmp_path, "trimmed", fall_tolerance=1.0
    )  # the rule before, no fall gate
    capped, backends = _falling_run(tmp_path, "capped")
    in_region = lambda d: d[0] < 0.75 and d[1] < 0.75  # noqa: E731
    assert in_region(
        trimmed.summary["best_design"]
    )  # the old rule picks a design that falls in 15 %
    assert trimmed.summary["best_fall_rate"] > 0.1 and trimmed.summary["falls_more"] is True
    assert (
        trimmed.summary["reliable"] is False
        and "falls more often" in trimmed.summary["reliability"]
    )
    # the fall gate alone keeps the trimmed rule's best outside the fall region too
    gated, _ = _falling_run(tmp_path, "trimmed")
    assert not in_region(gated.summary["best_design"]) and gated.summary["best_fall_rate"] == 0.0
    s = capped.summary
    assert (
        not in_region(s["best_design"]) and s["best_fall_rate"] == 0.0 and s["falls_more"] is False
    )
    assert (
        s["cost_rule"] == "capped"
        and s["cost_reference"] is not None
        and len(s["cost_reference"]) == 1
    )
    assert s["improvement_plain"] > 0 and s["improvement"] > 0 and s["improvement_plain_se"] > 0
    assert (
        s["final_blocks"] >= 4 and s["fall_check"] and all("eligible" in c for c in s["fall_check"])
    )
    assert yaml.safe_load((capped.run_dir / "config.yaml").read_text())["cost_rule"] == "capped"
    # the nominal design is evaluated once per policy for the reference level, and counted
    rounds = s["real_evaluations"]
    assert sum(b.real_calls for b in backends) == rounds + 2 + s["final_blocks"]
    real_batches = [b for b in s["batches"] if b["kind"] == "real"]
    assert all("best_plain_mean" in b and "best_fall_rate_se" in b for b in real_batches)
