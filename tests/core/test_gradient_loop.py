"""`--optimizer gradient` in the co-adaptation loop on the analytic backend (issue 52): it is
handed the surrogate's gradient, every round is real, each step is kept beside its real cost
and SE, and a run interrupted mid-descent resumes where it stopped."""

from __future__ import annotations

import numpy as np
import pytest
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend, optimum_of, true_cost

BASE = dict(
    optimizer="gradient",
    population=8,
    optimizer_iterations=12,
    outer_iterations=2,
    agents_per_design=16,
    eval_steps=5,
    train_steps=100,
    retrain_steps=50,
    seed=3,
)


def run(tmp_path, factory=lambda s: AnalyticBackend(s, paired=True), **overrides):
    config = make_config("smoke", overrides={**BASE, "out": str(tmp_path), **overrides})
    return run_coadaptation(
        config,
        backend_factory=factory,
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
    )


def test_gradient_descends_from_the_nominal_design_on_real_rounds_only(tmp_path):
    summary = run(tmp_path).summary
    batches = summary["batches"]
    assert {b["kind"] for b in batches} == {"real"} and len(batches) == 24
    steps = [b["descent_step"] for b in batches]
    # the first round of the run is the nominal design; of the next outer iteration, the best
    assert steps[0]["kind"] == "start" and steps[0]["design"] == NOMINAL.tolist()
    first = min(steps[:12], key=lambda s: s["real_cost"])
    assert steps[12]["kind"] == "start"
    np.testing.assert_allclose(steps[12]["design"], first["design"], atol=1e-8)
    taken = [s for s in steps if s["kind"] == "step"]
    assert taken and all(s["source"] == "surrogate" for s in taken)
    assert all(np.isfinite(s["surrogate_cost"]) for s in taken)
    # each step's real cost is its round's, with the round's standard error beside it
    for b, s in zip(batches, steps, strict=True):
        assert s["real_cost"] == pytest.approx(b["best_cost"])
        assert b["best_cost_se"] > 0
    best = np.array(summary["best_design"])
    nominal_gap = true_cost(NOMINAL[None], "torque")[0] - 1.0
    # the bowl's excess cost at the best design is under a tenth of the nominal design's
    assert true_cost(best[None], "torque")[0] - 1.0 < 0.1 * nominal_gap
    assert np.abs(best - optimum_of("torque")).max() < 0.1


def test_the_surrogate_slope_is_the_analytic_backends_own():
    backend = AnalyticBackend(0)
    backend.train(np.array([[0.5, 0.5], [1.5, 1.5]]), 10)
    designs = np.array([[0.7, 1.1], [1.3, 0.6]])
    costs, grads = backend.surrogate_slope(designs, [TorqueObjective()], {}, samples=4)
    h = 1e-6
    for k in range(2):
        for j in range(2):
            e = np.zeros(2)
            e[j] = h
            up = backend.surrogate_fitness(
                (designs[k] + e)[None], [TorqueObjective()], {}, samples=4
            )
            down = backend.surrogate_fitness(
                (designs[k] - e)[None], [TorqueObjective()], {}, samples=4
            )
            assert grads[k, 0, j] == pytest.approx((up - down)[0, 0] / (2 * h), abs=1e-6)
    assert costs.shape == (2, 1) and grads.shape == (2, 1, 2)


def test_an_interrupted_descent_resumes_where_it_stopped(tmp_path):
    whole = run(tmp_path / "whole").summary
    with pytest.raises(RuntimeError, match="injected"):
        run(
            tmp_path / "cut",
            factory=lambda s: AnalyticBackend(s, paired=True, fail_on_real_call=8),
        )
    folder = next((tmp_path / "cut").iterdir())
    resumed = run_coadaptation(
        backend_factory=lambda s: AnalyticBackend(s, paired=True),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        resume=folder,
    ).summary
    assert [b["descent_step"] for b in resumed["batches"]] == [
        b["descent_step"] for b in whole["batches"]
    ]
    assert resumed["best_design"] == whole["best_design"]


def test_a_method_without_a_surrogate_never_falls_back_to_the_gradient_optimizer():
    from coadapt_core.methods import optimizer_for

    # bo-specialized needs a sequential optimizer: bo and gradient both are, gradient
    # follows a surrogate that policies per design do not have
    assert optimizer_for("bo-specialized", "pso") == "bo"
    assert optimizer_for("ours", "gradient") == "gradient"
