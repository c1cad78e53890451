"""benchmarks/run_cost.py: a run's wall clock split into phases, and the loop counting each
second of surrogate work once (a fit made for a surrogate round used to count twice)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from tests.benchmarks import load_benchmark
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

ROOT = Path(__file__).resolve().parents[2]


def test_phases_take_surrogate_rounds_out_of_real_evaluation():
    summary = {
        "train_seconds": 30.0,
        "train_interactions": 3000,
        "eval_seconds": 50.0,
        "eval_interactions": 8000,
        "surrogate_seconds": 12.0,
        "final_seconds": 5.0,
        "final_interactions": 400,
    }
    evaluations = [
        {"kind": "real", "seconds": 10.0},
        {"kind": "surrogate", "seconds": 3.0},
        {"kind": "surrogate", "seconds": 4.0},
    ]
    parts = load_benchmark("run_cost").phases(summary, evaluations, wall=100.0)
    assert parts["real evaluation"] == (43.0, 8000)
    assert parts["surrogate"] == (12.0, 0)
    assert parts["other"] == (pytest.approx(100.0 - 30.0 - 43.0 - 12.0 - 5.0), 0)


class Clock:
    """The loop's clock (its modules' `time`), advanced only by the fake's fits."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self) -> float:
        return self.now


class SlowFit(AnalyticBackend):
    """The analytic backend whose surrogate fit takes FIT seconds of `clock`."""

    FIT = 1.0
    clock: Clock

    def fit_surrogate(self, *args, **kwargs):
        self.clock.now += self.FIT
        super().fit_surrogate(*args, **kwargs)


def test_a_fit_for_a_surrogate_round_counts_once(tmp_path, monkeypatch):
    from coadapt_plugins.objectives.locomotion import TorqueObjective

    from coadapt_core.coadapt import hybrid, loop

    clock = Clock()
    monkeypatch.setattr(loop, "time", clock)
    monkeypatch.setattr(hybrid, "time", clock)  # the surrogate's side of a round (its fits)
    backends = []

    def factory(seed):
        backends.append(SlowFit(seed))
        backends[-1].clock = clock
        return backends[-1]

    config = make_config(
        "smoke",
        overrides=dict(
            population=4,
            optimizer_iterations=6,
            outer_iterations=1,
            agents_per_design=4,
            eval_steps=5,
            train_steps=100,
            retrain_steps=50,
            seed=3,
            surrogate_probability=0.5,
            store="none",
            out=str(tmp_path),
        ),
    )
    result = run_coadaptation(
        config,
        backend_factory=factory,
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        run_dir=tmp_path / "r",
    )
    s = result.summary
    fits = sum(getattr(b, "fits", 0) for b in backends)
    assert s["surrogate_evaluations"] >= 1 and fits >= 2
    # the clock moves only in fits: every fit's second is surrogate time, once
    assert s["surrogate_seconds"] == pytest.approx(fits * SlowFit.FIT)
    assert s["surrogate_seconds"] <= s["seconds"]


@pytest.mark.slow
def test_smoke_run_cost_splits_the_wall_clock(capsys, tmp_path):
    """The real learner at the smoke size: the phases add up to the wall clock and each
    rate is set against a ceiling measured in the same process."""
    import json

    assert (
        load_benchmark("run_cost").main(["--size", "smoke", "--json", "--out", str(tmp_path)]) == 0
    )
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    phases = report["phases"]
    assert sum(p["seconds"] for p in phases.values()) == pytest.approx(
        report["wall_seconds"], abs=0.3
    )
    assert all(p["seconds"] >= 0 for p in phases.values())
    assert phases["real evaluation"]["interactions"] > 0 and phases["train"]["interactions"] > 0
    assert (
        0 < report["evaluation_vs_physics_ceiling"] < 2
        and 0 < report["training_vs_physics_ceiling"] < 2
    )
    # the share is computed before rounding; the printed seconds are rounded to 0.1 s, which on a
    # quick smoke run (a few seconds) moves their ratio by up to 0.05 * (1 + share) / wall
    wall = report["wall_seconds"]
    assert report["surrogate_share"] == pytest.approx(
        phases["surrogate"]["seconds"] / wall, abs=0.001 + 0.1 / wall
    )
    assert np.isfinite(report["improvement"])
