"""One sim-to-sim protocol (issue 50): the report's column and the handoff's check compute the
same figures the same way. Planted scenarios show the fall rules: a fall that makes most of the
difference brings a warning, both designs falling or one falling beyond the gate withholds the
percentage; a real PyBullet evaluation through the report's path and the handoff's path gives
the same figure."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from coadapt_core import sim_to_sim
from coadapt_core.costs import CostRule
from coadapt_core.fitness import RealFitness
from coadapt_core.plugins import get_registry


def _fit(per: np.ndarray, falls: np.ndarray) -> RealFitness:
    per = np.asarray(per, dtype=float)[:, :, None]  # [2, A, 1]
    return RealFitness(
        costs=per.mean(axis=1),
        buffer=None,
        interactions=0,
        seconds=0.0,
        per_scenario=per,
        scenario_falls=np.asarray(falls, dtype=bool),
        fall_rate=np.asarray(falls, dtype=float).mean(axis=1),
    )


def _read(per, falls, gate=0.01) -> sim_to_sim.Reading:
    torque = get_registry().create("objective", "torque")
    protocol = sim_to_sim.Protocol(scenarios=len(per[0]), steps=10)
    best, nominal = sim_to_sim.figures(_fit(per, falls), [torque], CostRule(), gate, protocol)
    read = sim_to_sim.reading(best, nominal, "torque")
    assert read is not None
    return read


def test_no_fall_gives_the_capped_improvement_with_the_plain_mean_beside():
    per = [[8.0] * 16, [10.0] * 16]
    read = _read(per, np.zeros((2, 16)))
    assert read.answer == pytest.approx(0.2) and read.plain == pytest.approx(0.2)
    assert read.refusal == "" and read.warning == "" and read.scenarios == 16
    text = sim_to_sim.line(read)
    assert text.startswith("torque +20.0 % ± 0.0 (capped cost); plain mean +20.0 %")
    assert "fall rate 0.00 vs 0.00" in text and "16 paired scenarios" in text


def test_one_planted_fall_that_decides_the_figure_brings_a_warning():
    """15 scenarios 1 % cheaper, one in which the design fell with a huge cost: the plain mean
    says the design is far worse, the capped rule prices the fall at 3 x the nominal median
    (cost 30 against 10) and the fall makes 20 / (20 + 1.5) = 93 % of the difference."""
    per = np.array([[9.9] * 15 + [500.0], [10.0] * 16])
    falls = np.zeros((2, 16), dtype=bool)
    falls[0, 15] = True
    read = _read(per, falls)
    capped = 1 - (15 * 9.9 + 30.0) / 160.0
    assert read.answer == pytest.approx(capped)  # -11.8 %: the gate lets one fall in 16 through
    assert read.plain == pytest.approx(1 - (15 * 9.9 + 500.0) / 160.0)  # -305.8 %
    assert read.falls_share == pytest.approx(20.0 / 21.5)
    assert read.fall_rate == pytest.approx(1 / 16) and read.nominal_fall_rate == 0.0
    assert (
        read.warning
        == "falls decide the figure: the scenarios with a fall make 93% of the cost difference"
    )
    assert sim_to_sim.line(read).endswith("warning: " + read.warning)


def test_both_designs_falling_prints_no_percentage():
    per = np.array([[30.0] * 16, [30.0] * 16])
    falls = np.ones((2, 16), dtype=bool)
    falls[:, :3] = False
    read = _read(per, falls)
    assert read.answer is None
    assert read.refusal == "no answer: both designs fall (fall rate 0.81 vs 0.81 of 16 scenarios)"
    text = sim_to_sim.line(read)
    assert text.startswith(read.refusal + "; plain mean") and "(capped cost)" not in text


def test_a_design_falling_beyond_the_gate_prints_no_percentage():
    per = np.array([[5.0] * 16, [10.0] * 16])
    falls = np.zeros((2, 16), dtype=bool)
    falls[0, :6] = True  # 6 of 16: difference 0.375, 2 SE = 0.25
    read = _read(per, falls, gate=0.05)
    assert read.answer is None and read.refusal.startswith(
        "no answer: the design falls more (fall rate 0.38 vs 0.00 of 16 scenarios, beyond the gate"
    )
    falls = falls[::-1].copy()  # the nominal design falls: said the same way
    assert _read(per, falls, gate=0.05).refusal.startswith("no answer: the nominal design falls")


def test_the_protocol_takes_the_runs_evaluation_length_and_block_one():
    p = sim_to_sim.protocol_of({"eval_steps": 250})
    assert (p.scenarios, p.steps, p.block) == (16, 250, 1)
    assert sim_to_sim.protocol_of({}, 4, 30) == sim_to_sim.Protocol(4, 30, 1)
    assert p.seed(3) != p.seed(4) and p.seed(3) == sim_to_sim.Protocol(8, 5).seed(3)
    assert sim_to_sim.gate_of({"fall_tolerance": 0.2}) == 0.2 and sim_to_sim.gate_of(None) == 0.01


# -- the report's path and the handoff's path on real physics ------------------------------------
@pytest.mark.slow
def test_report_and_handoff_give_the_same_pybullet_figure(tmp_path):
    """The shipped Kuafu policy, one design against the nominal one on PyBullet: the
    report's path (`transfer_run`, rows in the store, read back by the report's facts) and
    the handoff's (`measure.evaluate_on`) print the same line and the same numbers."""
    pytest.importorskip("pybullet")
    from coadapt_core.analysis.facts import transfer_improvement
    from coadapt_core.experiments.transfer import transfer_run
    from coadapt_core.handoff.measure import evaluate_on
    from coadapt_core.results import SqliteRecorder

    robot = get_registry().create("robot", "kuafu")
    run_dir = tmp_path / "run-s3"  # a run folder named after the run, as the loop writes
    (run_dir / "checkpoints").mkdir(parents=True)
    policy = run_dir / "checkpoints" / "policy.pt"
    policy.write_bytes(Path(robot.shipped_policy("flat")).read_bytes())
    config = {
        "method": "ours",
        "objective": "torque",
        "terrain": "flat",
        "seed": 3,
        "preset": "smoke",
        "sim": "mujoco",
        "robot": "kuafu",
        "optimizer": "pso",
        "cost_rule": "capped",
        "cost_cap": 3.0,
        "fall_tolerance": 0.01,
        "eval_steps": 20,
        "run_dir": str(run_dir),
        "run_id": "run-s3",
    }
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = rec.start_run(config)
    design = np.array([0.8, 1.2])
    rec.record_checkpoint(run_id, outer=0, path=str(policy))
    rec.finish(run_id, {"run_id": run_id, "best_design": design.tolist()})
    run = rec.store.get_run(run_id)
    assert transfer_run(rec.store, run, design, simulator="pybullet", agents=4) == ""
    value, note = transfer_improvement(rec.store, SimpleNamespace(run=run))
    fresh = evaluate_on(
        "pybullet",
        robot="kuafu",
        checkpoint=policy,
        objectives=["torque"],
        design=design,
        nominal=np.ones(2),
        terrain="flat",
        seed=3,
        agents=4,
        steps=None,
        config=config,
    )
    assert "error" not in fresh and (fresh["scenarios"], fresh["steps"]) == (4, 20)
    assert note == f"pybullet: {fresh['sim_to_sim']}"
    assert value == fresh["answer"] == fresh["objectives"]["torque"]["improvement"]
    assert np.isfinite(value) and "4 paired scenarios" in note


def test_the_reports_column_is_empty_with_the_reason_where_both_designs_fall(tmp_path):
    """Rows stored from a both-fall evaluation: the report's figure is None (no percentage in
    Table 6) and its note is the protocol's line, starting with the reason."""
    from coadapt_core.analysis.facts import transfer_improvement
    from coadapt_core.results import SqliteRecorder
    from coadapt_core.results.recorders import batch_rows

    torque = get_registry().create("objective", "torque")
    falls = np.ones((2, 8), dtype=bool)
    per = np.full((2, 8), 30.0)
    rows = sim_to_sim.figures(
        _fit(per, falls), [torque], CostRule(), 0.01, sim_to_sim.Protocol(8, 10)
    )
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = rec.start_run({"objective": "torque", "cost_rule": "capped", "robot": "kuafu"})
    rec.store.record_evaluations(
        run_id,
        batch_rows(
            outer=-1,
            inner=0,
            kind="sim2sim",
            designs=[[0.8, 1.2], [1.0, 1.0]],
            costs=rows,
            interactions=0,
            seconds=0.0,
            simulator="pybullet",
        ),
    )
    value, note = transfer_improvement(rec.store, SimpleNamespace(run=rec.store.get_run(run_id)))
    assert value is None
    assert note.startswith(
        "pybullet: no answer: both designs fall (fall rate 1.00 vs 1.00 of 8 scenarios); "
        "plain mean +0.0 %"
    )


def test_tracking_says_its_improvement_is_the_rms_error_reduction():
    from coadapt_core.analysis.measures import improvement_measure

    registry = get_registry()
    assert improvement_measure(registry.create("objective", "tracking")) == (
        "RMS error reduction 1 - √(c/c0)"
    )
    assert improvement_measure(registry.create("objective", "torque")) == ""
    read = _read([[8.0] * 4, [10.0] * 4], np.zeros((2, 4)))
    assert sim_to_sim.line(read, "capped", "RMS error reduction 1 - √(c/c0)").startswith(
        "torque +20.0 % ± 0.0 (capped cost; RMS error reduction 1 - √(c/c0))"
    )


def test_the_design_sheet_prints_no_percentage_where_the_protocol_refuses():
    from coadapt_core.handoff.sheet import _evaluation_lines

    read = _read(np.full((2, 8), 30.0), np.ones((2, 8), dtype=bool))
    ev = {
        "simulator": "pybullet",
        "source": "evaluated by coadapt handoff (8 paired scenarios)",
        "scenarios": 8,
        "steps": 10,
        "objectives": {"torque": {"design": 30.0, "nominal": 30.0, "improvement": 0.0}},
        "design_fall_rate": 1.0,
        "nominal_fall_rate": 1.0,
        "refusal": read.refusal,
        "sim_to_sim": sim_to_sim.line(read),
        "cost_rule": "capped",
    }
    lines = _evaluation_lines(ev)
    (row,) = [line for line in lines if line.startswith("| torque |")]
    assert row == "| torque | 30 | 30 | no answer (below) |"
    assert lines[-2] == f"Sim-to-sim protocol (capped cost rule): {sim_to_sim.line(read)}"
    assert "%" not in sim_to_sim.line(read).split("; ")[0]


def test_a_backend_that_reports_no_falls_is_said_so_not_read_as_none():
    torque = get_registry().create("objective", "torque")
    fit = _fit([[8.0] * 4, [10.0] * 4], np.zeros((2, 4)))
    fit.scenario_falls = None
    best, nominal = sim_to_sim.figures(fit, [torque], CostRule(), 0.01, sim_to_sim.Protocol(4, 10))
    read = sim_to_sim.reading(best, nominal, "torque")
    assert read.answer == pytest.approx(0.2) and np.isnan(read.fall_rate)
    assert sim_to_sim.line(read) == (
        "torque +20.0 % ± 0.0 (capped cost); plain mean +20.0 % ± 0.0; falls not reported by "
        "the backend; 4 paired scenarios"
    )
