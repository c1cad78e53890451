"""The co-adaptation loop (Algorithm 4) on the analytic backend: convergence of every
optimizer and method to the known optimum, the hybrid switch, interaction accounting,
narrowing, surrogate-error records, the final real re-evaluation and the recorder files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from coadapt_plugins.objectives.locomotion import PowerObjective, TorqueObjective, TrackingObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.summary import JSON_PLAIN_AND_FALLS as PLAIN_AND_FALLS
from coadapt_core.design_space import DesignSpace
from coadapt_core.results.recorders import read_evaluations
from tests.fakes.analytic import (
    MIXED_NOMINAL,
    MIXED_SPACE,
    NOISE_STD,
    NOMINAL,
    SPACE,
    SURROGATE_BIAS,
    AnalyticBackend,
    optimum_of,
    true_cost,
)

# a swarm of 20 for 3 x 5 rounds with 50 agents per design: seconds on the analytic backend
BASE = dict(
    population=20,
    optimizer_iterations=5,
    outer_iterations=3,
    agents_per_design=50,
    eval_steps=20,
    train_steps=5000,
    retrain_steps=2000,
)


def run(
    tmp_path, objectives=None, space=SPACE, nominal=NOMINAL, backend=AnalyticBackend, **overrides
):
    config = make_config("smoke", overrides={**BASE, "out": str(tmp_path), **overrides})
    return run_coadaptation(
        config,
        backend_factory=lambda seed: backend(seed),
        design_space=space,
        nominal_design=nominal,
        objectives=objectives or [TorqueObjective()],
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_ours_finds_torque_optimum_within_0_06(tmp_path, seed):
    summary = run(tmp_path, seed=seed).summary
    best = np.array(summary["best_design"])
    assert np.abs(best - optimum_of("torque")).max() < 0.06
    # nominal (1, 1) costs 1 + 0.32 on the bowl; the optimum 1.0
    assert summary["nominal_cost"] == pytest.approx(1.32, abs=0.01)
    assert summary["improvement"] == pytest.approx(0.32 / 1.32, abs=0.01)


@pytest.mark.parametrize("objective", [PowerObjective(), TrackingObjective()])
def test_ours_finds_other_objectives_optima(tmp_path, objective):
    best = np.array(run(tmp_path, objectives=[objective]).summary["best_design"])
    assert np.abs(best - optimum_of(objective.name)).max() < 0.06


def test_tracking_improvement_is_rms_error_reduction(tmp_path):
    summary = run(tmp_path, objectives=[TrackingObjective()]).summary
    expected = 1 - np.sqrt(summary["best_cost"]) / np.sqrt(summary["nominal_cost"])
    assert summary["improvement"] == pytest.approx(expected)


def test_mixed_pso_finds_lengths_and_motor_types(tmp_path):
    summary = run(tmp_path, space=MIXED_SPACE, nominal=MIXED_NOMINAL, optimizer="mixed-pso").summary
    best = np.array(summary["best_design"])
    assert best[2:].tolist() == [3.0, 2.0]
    assert np.abs(best[:2] - optimum_of("torque")).max() < 0.08


def test_bo_in_the_loop_finds_optimum(tmp_path):
    summary = run(tmp_path, optimizer="bo", optimizer_iterations=15, outer_iterations=2).summary
    assert summary["real_evaluations"] + summary["surrogate_evaluations"] == 30
    assert np.abs(np.array(summary["best_design"]) - optimum_of("torque")).max() < 0.1


def test_nsga2_front_spans_both_optima_with_real_costs(tmp_path):
    summary = run(
        tmp_path,
        objectives=[TorqueObjective(), PowerObjective()],
        optimizer="nsga2",
        objective="torque,power",
    ).summary
    front = summary["pareto_front"]
    designs = np.array(front["designs"])
    assert len(designs) >= 5
    # the true front is the segment between the two optima
    for name in ("torque", "power"):
        assert np.linalg.norm(designs - optimum_of(name), axis=1).min() < 0.1
    for design, costs in zip(designs, front["costs"], strict=True):
        assert costs["torque"] == pytest.approx(true_cost(design, "torque")[0], abs=5 * NOISE_STD)


@pytest.mark.slow
def test_hybrid_switch_uses_surrogate_with_probability_w(tmp_path):
    w = 0.3
    summary = run(
        tmp_path,
        population=2,
        agents_per_design=3,
        eval_steps=7,
        optimizer_iterations=150,
        outer_iterations=2,
        surrogate_probability=w,
    ).summary
    batches = summary["batches"]
    assert len(batches) == 300
    # the first round of each outer iteration is real (it fills the evaluation buffer)
    assert [b["kind"] for b in batches if b["inner"] == 0] == ["real", "real"]
    later = [b["kind"] == "surrogate" for b in batches if b["inner"] > 0]
    fraction = float(np.mean(later))
    assert abs(fraction - w) < 3 * np.sqrt(w * (1 - w) / len(later))
    real = sum(b["kind"] == "real" for b in batches)
    assert summary["eval_interactions"] == real * 2 * 3 * 7
    assert all(b["interactions"] == 0 for b in batches if b["kind"] == "surrogate")


def test_no_surrogate_spends_more_evaluation_interactions_than_ours(tmp_path):
    ours = run(tmp_path / "a", method="ours").summary
    real_only = run(tmp_path / "b", method="no-surrogate").summary
    assert real_only["surrogate_evaluations"] == 0 and real_only["real_evaluations"] == 15
    assert real_only["eval_interactions"] == 15 * 20 * 50 * 20
    assert ours["eval_interactions"] < real_only["eval_interactions"]
    assert ours["train_interactions"] == real_only["train_interactions"] == 5000 + 2 * 2000
    # final check: the 3 lowest real costs (final_candidates) and the nominal design, one rollout
    assert real_only["final_interactions"] == (3 + 1) * 50 * 20


def test_no_real_fills_buffer_from_training_and_spends_no_evaluation_interactions(tmp_path):
    summary = run(tmp_path, method="no-real").summary
    assert summary["eval_interactions"] == 0 and summary["real_evaluations"] == 0
    assert summary["surrogate_evaluations"] == 15
    # its surrogate is tilted, so it lands off the optimum, and the reported cost is still real
    best = np.array(summary["best_design"])
    assert summary["best_cost"] == pytest.approx(
        true_cost(best, "torque")[0], abs=5 * NOISE_STD / np.sqrt(50)
    )
    assert summary["final_interactions"] > 0


def test_no_real_without_training_buffer_spends_one_real_round_per_outer(tmp_path):
    summary = run(
        tmp_path, method="no-real", backend=lambda s: AnalyticBackend(s, buffer_from_training=False)
    ).summary
    assert summary["real_evaluations"] == 3 and summary["surrogate_evaluations"] == 12


def test_no_retrain_trains_once_never_narrows_and_runs_n_times_j_rounds(tmp_path):
    summary = run(tmp_path, method="no-retrain").summary
    assert summary["train_interactions"] == 5000
    assert summary["real_evaluations"] == 15 and summary["surrogate_evaluations"] == 0
    assert DesignSpace.from_dict(summary["final_space"]) == SPACE
    assert np.abs(np.array(summary["best_design"]) - optimum_of("torque")).max() < 0.08


def test_bo_specialized_trains_a_policy_per_design(tmp_path):
    trained = []

    class Recording(AnalyticBackend):
        def train(self, designs, steps, *, seed=0):
            trained.append(np.array(designs))
            return super().train(designs, steps, seed=seed)

    result = run(
        tmp_path,
        method="bo-specialized",
        bo_designs=12,
        specialized_train_steps=300,
        backend=Recording,
    )
    summary = result.summary
    # 12 proposals, then in the final check the nominal design and those of its 3 candidates
    # (the best real designs) whose policies were no longer among the 4 kept
    assert all(d.shape == (1, 2) for d in trained)
    evaluated = [e["design"] for e in read_evaluations(result.run_dir)]
    assert [d[0].tolist() for d in trained[:12]] == evaluated
    final = [d[0].tolist() for d in trained[12:]]
    assert (
        final[-1] == NOMINAL.tolist()
        and 2 <= len(final) <= 4
        and len({tuple(d) for d in final}) == len(final)
    )
    assert all(d in evaluated for d in final[:-1])
    assert summary["train_interactions"] == len(trained) * 300
    assert summary["real_evaluations"] == 12 and summary["surrogate_evaluations"] == 0
    assert summary["optimizer"] == "bo"


def test_narrowing_shrinks_range_around_optimum(tmp_path):
    summary = run(tmp_path).summary
    spaces = [DesignSpace.from_dict(s) for s in summary["spaces"]]
    widths = [float(np.mean(s.upper - s.lower)) for s in spaces]
    assert widths[0] == pytest.approx(1.0)
    assert widths[-1] < 0.5 * widths[0]
    final = DesignSpace.from_dict(summary["final_space"])
    assert np.all(final.lower <= optimum_of("torque") + 0.02) and np.all(
        final.upper >= optimum_of("torque") - 0.02
    )


def test_surrogate_error_recorded_on_real_batches_matches_known_bias(tmp_path):
    # the paper's estimator (no fit to the real rounds): its error is the fake's known bias
    result = run(tmp_path, method="no-surrogate", outer_iterations=1, fit_surrogate=False)
    records = read_evaluations(result.run_dir)
    assert len(records) == 5 * 20
    backend = AnalyticBackend()
    backend.trained_low, backend.trained_high = np.array([0.5, 0.5]), np.array([1.5, 1.5])
    for r in records:
        design = np.array([r["design"]])
        # error = surrogate - real = known bias - noise; first range is ~ the full range
        expected = backend.surrogate_bias(design)[0]
        assert r["surrogate_error"]["torque"] == pytest.approx(
            expected, abs=0.06 * SURROGATE_BIAS + 5 * NOISE_STD / np.sqrt(50)
        )
        assert r["kind"] == "real" and r["interactions"] == 50 * 20


def test_run_folder_holds_config_evaluations_and_summary(tmp_path):
    import yaml

    result = run(tmp_path, seed=4)
    files = {p.name for p in result.run_dir.iterdir()}
    assert {
        "config.yaml",
        "evaluations.jsonl",
        "trainings.jsonl",
        "summary.json",
        "state.json",
    } <= files
    # the evaluation buffer lives in a file of its own while the run can continue; a finished
    # run resumes from its summary alone and keeps none (issue 30: 33 MB per quick run)
    assert [f for f in files if f.startswith("buffer-")] == []
    state = json.loads((result.run_dir / "state.json").read_text())
    assert state["phase"] == "done" and state["buffer_saved_serial"] == -1
    assert yaml.safe_load((result.run_dir / "config.yaml").read_text())["seed"] == 4
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert (
        summary["status"] == "finished" and summary["best_design"] == result.summary["best_design"]
    )
    records = read_evaluations(result.run_dir)
    assert len(records) == result.summary["designs_evaluated"] == 15 * 20
    assert sum(r["interactions"] for r in records) == result.summary["eval_interactions"]
    kinds = {r["kind"] for r in records}
    assert kinds == {"real", "surrogate"}
    assert len((result.run_dir / "trainings.jsonl").read_text().splitlines()) == 3
    line = result.json_line()
    assert set(line) == {
        "run_id",
        "best_design",
        "best_cost",
        "best_cost_se",
        "nominal_cost",
        "nominal_cost_se",
        "improvement",
        "improvement_se",
        "significant",
        "best_fall_rate",
        "nominal_fall_rate",
        *PLAIN_AND_FALLS,
        "interactions",
        "seconds",
        "reliable",
        "reliability",
        "warnings",
        "numerics",
    }
    # the analytic backend reports no precision: said so, never guessed (numerics.py)
    assert line["numerics"]["precision"] is None and line["numerics"]["device"] == "cpu"
    assert (
        line["interactions"]
        == result.summary["train_interactions"]
        + result.summary["eval_interactions"]
        + result.summary["final_interactions"]
    )


def test_same_seed_same_run(tmp_path):
    a = run(tmp_path / "a", seed=9).summary
    b = run(tmp_path / "b", seed=9).summary
    assert a["best_design"] == b["best_design"]
    # everything but the measured wall-clock seconds of surrogate rounds
    strip = [{k: v for k, v in batch.items() if k != "seconds"} for batch in a["batches"]]
    assert strip == [{k: v for k, v in batch.items() if k != "seconds"} for batch in b["batches"]]


def test_diverged_surrogate_nan_is_counted_and_never_best(tmp_path):
    class Diverged(AnalyticBackend):
        def surrogate_fitness(self, designs, objectives, buffer, *, samples, seed=0):
            out = super().surrogate_fitness(designs, objectives, buffer, samples=samples, seed=seed)
            out[::2] = np.nan  # half the candidates come back NaN
            out[1] = -1e9  # and one absurdly good: it must not be reported as a real cost
            return out

    summary = run(tmp_path, backend=Diverged).summary
    surrogate = [b for b in summary["batches"] if b["kind"] == "surrogate"]
    assert surrogate and all(b["nonfinite_costs"] == 10 for b in surrogate)
    assert summary["best_cost"] > 0.9  # re-evaluated for real
    assert np.abs(np.array(summary["best_design"]) - optimum_of("torque")).max() < 0.1


def test_no_retrain_from_a_pretrained_policy_trains_nothing(tmp_path, monkeypatch):
    import coadapt_core.coadapt.setup as loop_setup

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )
    import coadapt_core.coadapt.starting_policy as start

    monkeypatch.setattr(start, "find_checkpoint", lambda *a: "/shipped/policy.pt")
    config = make_config("smoke", overrides={**BASE, "out": str(tmp_path), "method": "no-retrain"})
    summary = run_coadaptation(
        config, design_space=SPACE, nominal_design=NOMINAL, objectives=[TorqueObjective()]
    ).summary
    # the paper's Table 7 row: 0 training + N*J real rounds
    assert summary["train_interactions"] == 0
    assert summary["eval_interactions"] == 15 * 20 * 50 * 20
