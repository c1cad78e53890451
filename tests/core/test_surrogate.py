"""The surrogate's quality figures, the fit of the pseudo-critics to labelled designs, and the
uncertainty-triggered evaluation policy (issue 16)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.hybrid import spread_ratio
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.errors import UserError
from coadapt_core.learning.networks import CriticBank
from coadapt_core.learning.surrogate import fit_ensemble
from coadapt_core.surrogate_quality import kendall, pooled, quality, spearman, top_k_regret
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

scipy_stats = pytest.importorskip("scipy.stats")


def test_quality_figures_on_a_known_example():
    real = [2.0, 4.0, 6.0, 8.0]
    q = quality([1.0, 2.0, 3.0, 4.0], real)  # same order, half the cost
    assert q["spearman"] == pytest.approx(1.0) and q["kendall"] == pytest.approx(1.0)
    assert q["mean_relative_error"] == pytest.approx(0.5) and q["bias"] == pytest.approx(-0.5)
    assert q["top_k_regret"] == 0.0 and q["n"] == 4
    r = quality([4.0, 3.0, 2.0, 1.0], real)  # reversed: picks the two dearest designs
    assert r["spearman"] == pytest.approx(-1.0) and r["kendall"] == pytest.approx(-1.0)
    assert top_k_regret([4.0, 3.0, 2.0, 1.0], real, k=1) == pytest.approx((8 - 2) / 2)
    assert top_k_regret([4.0, 3.0, 2.0, 1.0], real, k=2) == pytest.approx((6 - 2) / 2)
    # over-prediction is a positive bias: (surrogate - real) / |real|
    assert quality([3.0, 6.0, 9.0], [2.0, 4.0, 6.0])["bias"] == pytest.approx(0.5)
    # a non-finite prediction is left out and counted
    n = quality([1.0, float("nan"), 3.0, 4.0], real)
    assert n["n"] == 3 and n["nonfinite"] == 1


def test_rank_correlations_match_scipy_with_ties():
    rng = np.random.default_rng(3)
    for _ in range(5):
        a = rng.integers(0, 5, 12).astype(float)  # ties on purpose
        b = a + rng.integers(-2, 3, 12)
        assert spearman(a, b) == pytest.approx(scipy_stats.spearmanr(a, b).statistic)
        assert kendall(a, b) == pytest.approx(scipy_stats.kendalltau(a, b).statistic)


def test_pooled_concatenates_pairs_and_averages_regret():
    rounds = [
        {"surrogate": [1, 2, 3], "real": [1, 2, 3]},
        {"surrogate": [3, 2, 1], "real": [10, 20, 30]},
    ]
    p = pooled(rounds)
    assert p["n"] == 6 and p["rounds"] == 2
    assert p["spearman"] == pytest.approx(spearman([1, 2, 3, 3, 2, 1], [1, 2, 3, 10, 20, 30]))
    assert p["top_k_regret"] == pytest.approx((0.0 + top_k_regret([3, 2, 1], [10, 20, 30])) / 2)


def test_spread_ratio():
    base = np.linspace(1.0, 2.0, 8)[None, :, None]  # designs differ by 1
    assert spread_ratio(np.repeat(base, 5, axis=0)) == 0.0  # members agree
    tilt = np.linspace(-1.0, 1.0, 5)[:, None, None] * np.ones((1, 8, 1))
    ratio = spread_ratio(base + tilt)
    assert ratio == pytest.approx(tilt[:, 0, 0].std() / base.std())
    assert spread_ratio(np.ones((5, 8, 1))) == float("inf")  # designs predicted alike


@pytest.fixture
def one_thread():
    """As the learner runs outside its update (coadapt_core/learning/trainer.py): on a busy
    machine two intra-op threads make these tiny products 30 x slower."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_fit_ensemble_ranks_unseen_designs_through_xi(one_thread):
    """Pseudo-critics that ignore the design (state-only targets) are fitted to labelled
    designs: their mean over states then ranks designs they were not fitted on."""
    torch.manual_seed(0)
    bank = CriticBank(6, 2, (32, 32), "elu", outputs=2)
    states = torch.randn(512, 6)
    cost = lambda xi: 5.0 + 2.0 * xi[:, 0] - 1.0 * xi[:, 1] + 0.5 * xi[:, 0] ** 2  # noqa: E731
    gen = torch.Generator().manual_seed(1)
    seen, unseen = (
        torch.rand(24, 2, generator=gen) * 2 - 1,
        torch.rand(16, 2, generator=gen) * 2 - 1,
    )
    fitted = fit_ensemble(
        bank,
        [1],
        torch.ones(2),
        torch.zeros(2),
        states,
        seen,
        cost(seen)[:, None],
        members=3,
        steps=300,
        batch=64,
        lr=3e-3,
        seed=0,
    )
    members = fitted.predict(states, unseen).numpy()  # [E, K, 1]
    assert members.shape == (3, 16, 1)
    q = quality(members.mean(axis=0)[:, 0], cost(unseen).numpy())
    assert q["spearman"] > 0.9 and q["mean_relative_error"] < 0.1
    again = fit_ensemble(
        bank,
        [1],
        torch.ones(2),
        torch.zeros(2),
        states,
        seen,
        cost(seen)[:, None],
        members=3,
        steps=300,
        batch=64,
        lr=3e-3,
        seed=0,
    )
    np.testing.assert_allclose(
        again.predict(states, unseen).numpy(), members
    )  # a function of its seed
    assert (
        torch.equal(bank.weight_0, CriticBank(6, 2, (32, 32), "elu", outputs=2).weight_0) is False
    )  # untouched copy
    before = bank.weight_0.clone()
    fit_ensemble(
        bank,
        [0],
        torch.ones(2),
        torch.zeros(2),
        states,
        seen,
        cost(seen)[:, None],
        members=2,
        steps=5,
    )
    assert torch.equal(bank.weight_0, before)  # the trained pseudo-critics stay as they are


def test_prediction_equals_each_members_mlp_averaged_over_its_states(one_thread):
    """The prediction's factored first layer (state part once, each design's part added)
    gives what each member's MLP gives on the concatenated (state, design) rows, averaged over
    that member's share of the states (member e: states e, e + E, ...), for two objectives."""
    torch.manual_seed(3)
    bank = CriticBank(6, 2, (16, 8), "elu", outputs=3)
    states, xi = torch.randn(40, 6), torch.rand(12, 2) * 2 - 1
    costs = torch.stack([1.0 + xi[:, 0], 2.0 - xi[:, 1]], dim=1)
    fitted = fit_ensemble(
        bank, [0, 2], torch.ones(3), torch.zeros(3), states, xi, costs, members=4, steps=3
    )
    designs = torch.rand(5, 2) * 2 - 1
    got = fitted.predict(states, designs, chunk=2)  # [E, K, M]
    e, m = 4, 2
    expected = torch.empty(e, len(designs), m)
    for member in range(e):
        share = states[member::e][: len(states) // e]
        for j in range(m):
            head = member * m + j
            for k, x in enumerate(fitted.frame(designs)):
                h = torch.cat([share, x.expand(len(share), -1)], dim=1)
                for layer in range(fitted.bank.num_layers):
                    weight, bias = fitted.bank.layer(layer)
                    h = h @ weight[head].T + bias[head]
                    if layer < fitted.bank.num_layers - 1:
                        h = fitted.bank.act(h)
                expected[member, k, j] = h.mean() * fitted.scale[j] + fitted.offset[member, j]
    torch.testing.assert_close(got, expected, rtol=1e-5, atol=1e-5)


def run(tmp_path, backend, **overrides):
    config = make_config(
        "smoke",
        overrides={
            "optimizer": "pso",
            "objective": "torque",
            "outer_iterations": 2,
            "population": 8,
            "optimizer_iterations": 5,
            "store": "none",
            "logger": "none",
            "out": str(tmp_path),
            **overrides,
        },
    )
    return run_coadaptation(
        config,
        backend_factory=lambda seed: backend(seed),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
    )


def agreeing(spread):
    def make(seed):
        b = AnalyticBackend(seed, buffer_from_training=False)
        b.member_spread = spread
        return b

    return make


def test_uncertainty_policy_trusts_an_agreeing_ensemble_and_not_a_disagreeing_one(tmp_path):
    agree = run(tmp_path / "a", agreeing(0.0), evaluation_policy="uncertainty").summary
    # one real round per policy (it fills R_eval and labels the fit), then the ensemble agrees
    assert agree["real_evaluations"] == 2 and agree["surrogate_evaluations"] == 8
    ratios = [b["uncertainty"] for b in agree["batches"] if b["kind"] == "surrogate"]
    assert len(ratios) == 8 and all(r < 1e-12 for r in ratios)
    disagree = run(tmp_path / "d", agreeing(50.0), evaluation_policy="uncertainty").summary
    assert disagree["real_evaluations"] == 10 and disagree["surrogate_evaluations"] == 0
    assert all(b["uncertainty"] > 0.5 for b in disagree["batches"] if b["inner"] > 0)
    # the threshold decides: a lax one trusts the same disagreeing ensemble
    lax = run(
        tmp_path / "l", agreeing(50.0), evaluation_policy="uncertainty", uncertainty_threshold=1e9
    ).summary
    assert lax["surrogate_evaluations"] == 8


def test_fixed_policy_is_the_papers_draw_and_fits_before_surrogate_rounds(tmp_path):
    made = []

    def factory(seed):
        made.append(agreeing(50.0)(seed))  # disagreement does not matter to the fixed policy
        return made[-1]

    summary = run(tmp_path, factory, surrogate_probability=1.0).summary
    assert summary["evaluation_policy"] == "fixed"
    assert summary["real_evaluations"] == 2 and summary["surrogate_evaluations"] == 8
    assert all(b.fits >= 1 for b in made if b.surrogate_calls)  # no surrogate round before a fit


def test_surrogate_quality_in_summary_json(tmp_path):
    result = run(tmp_path, agreeing(None), surrogate_probability=0.0, surrogate_error_fits=True)
    summary = json.loads((result.run_dir / "summary.json").read_text())
    summary = summary.get("summary", summary)
    q = summary["surrogate_quality"]
    assert set(q["pooled"]) >= {
        "spearman",
        "kendall",
        "mean_relative_error",
        "bias",
        "top_k_regret",
    }
    rounds = q["rounds"]
    assert (
        len(rounds) == 10 and [r["eligible"] for r in rounds] == [False, True, True, True, True] * 2
    )
    assert [r["estimator"] for r in rounds][:2] == ["paper", "fitted"]
    # the pooled figures are those of the eligible rounds' pairs (kept in the run state)
    state = json.loads((result.run_dir / "state.json").read_text())
    pairs = [
        {
            "surrogate": r["objectives"]["torque"]["surrogate"],
            "real": r["objectives"]["torque"]["real"],
        }
        for r in state["quality_rounds"]
        if r["eligible"]
    ]
    expected = pooled(pairs)
    assert q["pooled"]["n"] == 8 * 8 and q["pooled"]["spearman"] == pytest.approx(
        expected["spearman"]
    )
    assert q["pooled"]["bias"] == pytest.approx(expected["bias"])
    # the fake's fitted surrogate is its bowl plus a shrunk tilt; the real costs add noise
    # that matters once the swarm has gathered near the optimum
    assert q["pooled"]["spearman"] > 0.5 and abs(q["pooled"]["bias"]) < 0.1


def test_real_rounds_are_judged_only_by_a_fit_that_covers_them(tmp_path):
    """Without `surrogate_error_fits` no fit is made only to measure the surrogate's error:
    a run without surrogate rounds fits nothing, and a real round is judged (by the fit the
    surrogate round before it made, no new fit) only right after a surrogate round."""
    made = []

    def factory(seed):
        made.append(agreeing(None)(seed))
        return made[-1]

    none = run(tmp_path / "n", factory, surrogate_probability=0.0).summary
    assert (
        sum(getattr(b, "fits", 0) for b in made) == 0 and none["surrogate_quality"]["rounds"] == []
    )
    assert none["surrogate_seconds"] == 0.0
    made.clear()
    result = run(tmp_path / "h", factory, surrogate_probability=0.5, seed=3)
    kinds = [(b["outer"], b["inner"], b["kind"]) for b in result.summary["batches"]]
    after = [
        (o, i)
        for (o, i, k), (o0, _, k0) in zip(kinds[1:], kinds[:-1], strict=True)
        if k == "real" and k0 == "surrogate" and o == o0
    ]
    judged = [(r["outer"], r["inner"]) for r in result.summary["surrogate_quality"]["rounds"]]
    assert (
        after
        and judged == after
        and all(r["estimator"] == "fitted" for r in result.summary["surrogate_quality"]["rounds"])
    )
    surrogate_rounds = sum(k == "surrogate" for *_, k in kinds)
    assert (
        0 < sum(getattr(b, "fits", 0) for b in made) <= surrogate_rounds
    )  # at most one fit per surrogate round


def test_bad_evaluation_policy_is_one_line_error(tmp_path):
    with pytest.raises(
        UserError, match="evaluation_policy 'sometimes' is not one of fixed, uncertainty"
    ):
        run(tmp_path, agreeing(0.0), evaluation_policy="sometimes")
    with pytest.raises(UserError, match="uncertainty_threshold"):
        run(tmp_path, agreeing(0.0), uncertainty_threshold=-1)


def test_report_figure_reads_each_runs_surrogate_quality(tmp_path):
    from types import SimpleNamespace

    from coadapt_core.analysis.surrogate_figure import figure_surrogate_quality, quality_series

    result = run(tmp_path, agreeing(None), surrogate_probability=0.0)
    facts = [
        SimpleNamespace(run={"summary": result.summary, "seed": 0}, method="ours", terrain="flat")
    ]
    series = quality_series(facts)
    rounds = [r for r in result.summary["surrogate_quality"]["rounds"] if r["eligible"]]
    assert series[("torque", "flat")][0]["spearman"] == pytest.approx(
        [r["objectives"]["torque"]["spearman"] for r in rounds]
    )
    figures = figure_surrogate_quality(facts, tmp_path)
    assert len(figures) == 1 and figures[0][0].stat().st_size > 1000
    assert (
        figure_surrogate_quality(
            [SimpleNamespace(run={"summary": {}}, method="ours", terrain="flat")], tmp_path
        )
        == []
    )
