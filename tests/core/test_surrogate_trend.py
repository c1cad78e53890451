"""`surrogate_trend` (issue 52): the plane through this policy's real rounds costs the
surrogate rounds and is what the judged real rounds record; refused beside the uncertainty
policy. The fit itself on planted planes."""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.coadapt.trend import fit_trend, trend_of_labels
from coadapt_core.errors import UserError
from tests.core.test_surrogate import run
from tests.fakes.analytic import AnalyticBackend


def test_a_planted_plane_is_recovered_in_any_range_and_too_few_labels_give_none():
    rng = np.random.default_rng(0)
    for lo, hi in ((0.5, 1.5), (0.98, 1.02)):  # the full range and a narrowed one
        x = rng.uniform(lo, hi, size=(16, 2))
        y = np.stack([3.0 + 2.0 * x[:, 0] - 5.0 * x[:, 1], 1.0 - x[:, 0]], axis=1)
        trend = fit_trend(x, y)
        probe = rng.uniform(lo, hi, size=(5, 2))
        want = np.stack([3.0 + 2.0 * probe[:, 0] - 5.0 * probe[:, 1], 1.0 - probe[:, 0]], 1)
        np.testing.assert_allclose(trend.predict(probe), want, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(trend.slope(), [[2.0, -5.0], [-1.0, 0.0]], atol=1e-7)
    # D + 1 designs fix a plane in D variables; fewer, or a cost that is not finite, do not
    assert fit_trend(np.eye(2), [1.0, 2.0]) is None
    assert fit_trend(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), [1.0, np.nan, 2.0]) is None
    # a variable that never moved (a motor type held) gets no slope and no division by zero
    held = np.array([[0.6, 2.0], [0.8, 2.0], [1.0, 2.0], [1.2, 2.0]])
    np.testing.assert_allclose(fit_trend(held, [1.0, 2.0, 3.0, 4.0]).predict([[0.7, 2.0]]), [[1.5]])
    labels = [
        {"designs": [[0.6, 1.0], [0.8, 1.2]], "costs": [[1.0], [2.0]]},
        {"designs": [[1.0, 0.9]], "costs": [[3.0]]},
    ]
    assert trend_of_labels(labels).labels == 3 and trend_of_labels([]) is None


def _run(tmp_path, **overrides):
    """test_surrogate.py's small PSO run on the analytic fake, its buffer from real rounds."""
    return run(
        tmp_path, lambda seed: AnalyticBackend(seed, buffer_from_training=False), **overrides
    )


def test_surrogate_rounds_cost_the_plane_through_this_policys_real_rounds(tmp_path):
    result = _run(tmp_path, surrogate_trend=True, surrogate_probability=0.5, seed=3)
    s = result.summary
    assert s["surrogate_evaluations"] > 0 and s["surrogate_quality"]["estimator"] == "trend"
    import json

    rows = [json.loads(line) for line in (result.run_dir / "evaluations.jsonl").open()]
    for outer in {r["outer"] for r in rows}:
        mine = [r for r in rows if r["outer"] == outer]
        for inner in sorted({r["inner"] for r in mine if r["kind"] == "surrogate"}):
            before = [r for r in mine if r["kind"] == "real" and r["inner"] < inner]
            trend = fit_trend([r["design"] for r in before], [r["costs"]["torque"] for r in before])
            here = [r for r in mine if r["inner"] == inner]
            np.testing.assert_allclose(
                [r["costs"]["torque"] for r in here],
                trend.predict([r["design"] for r in here])[:, 0],
                rtol=1e-9,
            )
    # every eligible real round is judged by the plane (it costs no fit)
    rounds = s["surrogate_quality"]["rounds"]
    eligible = [r for r in rounds if r["eligible"]]
    assert eligible and all(r["estimator"] == "trend" for r in eligible)
    real_after_first = sum(1 for b in s["batches"] if b["kind"] == "real" and b["inner"] > 0)
    assert len(eligible) == real_after_first


def test_refused_beside_the_uncertainty_policy(tmp_path):
    with pytest.raises(UserError, match="surrogate_trend"):
        _run(tmp_path, surrogate_trend=True, evaluation_policy="uncertainty")


def test_the_ceiling_benchmark_replays_the_plane_a_trend_run_used(tmp_path):
    """benchmarks/surrogate_ceiling.py's replayed plane, on a run whose surrogate was the
    plane: the same Spearman as the run recorded, round by round."""
    from tests.benchmarks import load_benchmark

    result = _run(tmp_path, surrogate_trend=True, surrogate_probability=0.5, seed=3)
    rounds = load_benchmark("surrogate_ceiling").run_rounds(result.run_dir)["rounds"]
    judged = [r for r in rounds if r["eligible"]]
    assert len(judged) >= 2
    for r in judged:
        assert r["trend_spearman"] == pytest.approx(r["spearman"], abs=1e-12)
