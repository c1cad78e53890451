"""The paper's measure (coadapt_core/analysis/measures.py): every improvement restated as the
cost reduction 1 - c / c0, with its standard error carried by the delta method; the committed
report's tracking cells say the same as the runs' own costs."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from coadapt_plugins.objectives.locomotion import PowerObjective, TrackingObjective

from coadapt_core.analysis.measures import as_cost_reduction, cost_ratio, differs
from coadapt_core.costs import improvement_se, plain_mean

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"


def test_tracking_improvement_is_restated_as_the_reduction_of_p_cmd():
    tracking = TrackingObjective()
    # 1 - sqrt(c/c0) = 0.1 means c/c0 = 0.81: the cost reduction is 19 %, its SE 2 x 0.9 x SE
    assert cost_ratio(tracking, 0.1) == pytest.approx(0.81, abs=1e-12)
    value, se = as_cost_reduction(tracking, 0.1, 0.01)
    assert value == pytest.approx(0.19, abs=1e-12) and se == pytest.approx(0.018, rel=1e-6)
    # a design worse than nominal: 1 - sqrt(c/c0) = -0.2, c/c0 = 1.44
    assert as_cost_reduction(tracking, -0.2)[0] == pytest.approx(-0.44, abs=1e-12)
    assert differs(tracking) and not differs(PowerObjective()) and not differs(None)
    # an objective whose improvement is the cost reduction already: unchanged, SE too
    assert as_cost_reduction(PowerObjective(), 0.14, 0.006) == (
        pytest.approx(0.14),
        pytest.approx(0.006),
    )
    assert as_cost_reduction(None, 0.3, None) == (pytest.approx(0.3), None)
    assert as_cost_reduction(tracking, None, 0.1) == (None, None)


def test_delta_method_se_matches_a_paired_bootstrap_of_the_cost_reduction():
    rng = np.random.default_rng(3)
    nominal = rng.gamma(4.0, 0.035, size=64)  # P_cmd per scenario, mean about 0.14
    best = nominal * rng.normal(0.9, 0.08, size=64).clip(0.5)  # paired, 10 % lower
    rms_imp = TrackingObjective().improvement(best.mean(), nominal.mean())
    rms_se = improvement_se(TrackingObjective(), best, nominal, plain_mean)
    value, se = as_cost_reduction(TrackingObjective(), rms_imp, rms_se)
    # the same scenarios bootstrapped for 1 - c/c0 directly (PowerObjective's improvement is it)
    direct_se = improvement_se(PowerObjective(), best, nominal, plain_mean)
    assert value == pytest.approx(1 - best.mean() / nominal.mean(), abs=1e-9)
    assert se == pytest.approx(direct_se, rel=0.05)
    assert se == pytest.approx(2 * (1 - rms_imp) * rms_se, rel=1e-5)


def _rows(path: Path) -> list[dict[str, str]]:
    csv.field_size_limit(1 << 26)
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_committed_tracking_cells_are_the_reduction_of_the_runs_own_costs():
    runs = {r["id"]: json.loads(r["summary"]) for r in _rows(RESULTS / "export" / "runs.csv")}
    table6 = {
        (r["objective"], r["method"], r["optimizer"], r["terrain"]): r
        for r in _rows(RESULTS / "report" / "table6.csv")
    }
    checked = 0
    for name in ("paper_table6.csv", "paper_table9.csv"):
        for row in _rows(RESULTS / "report" / name):
            source = table6[(row["objective"], row["method"], row["optimizer"], row["terrain"])]
            summaries = [runs[i] for i in source["run_ids"].split()]
            direct = np.mean([1 - s["best_cost"] / s["nominal_cost"] for s in summaries])
            assert float(row["improvement"]) == pytest.approx(direct, abs=1e-9), row
            if row["objective"] == "tracking":
                own = np.mean([1 - np.sqrt(s["best_cost"] / s["nominal_cost"]) for s in summaries])
                assert float(row["improvement_own"]) == pytest.approx(own, abs=1e-9)
                if own > 0.005:  # about twice as large: 1 - r^2 = (1 - r)(1 + r)
                    assert 1.8 < float(row["improvement"]) / own <= 2.0
                    checked += 1
    assert checked >= 4
