"""The refinement stage after the search (`refine_with`, coadapt/refine.py; issue 52) on the
analytic backend: after the last outer iteration's optimizer, the descent optimizer steps
from the best real design along the surrogate's gradient, every step real and recorded with
its surrogate and real cost and SE, only real improvements accepted, resumable mid-stage."""

from __future__ import annotations

import json

import numpy as np
import pytest
from coadapt_plugins.objectives.locomotion import PowerObjective, TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.errors import UserError
from coadapt_core.results import ResultsStore
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

BASE = dict(
    optimizer="pso",
    population=6,
    optimizer_iterations=3,
    outer_iterations=2,
    agents_per_design=16,
    eval_steps=5,
    train_steps=100,
    retrain_steps=50,
    seed=5,
)
REFINE = dict(refine_with="gradient", refine_rounds=7)


def run(tmp_path, factory=lambda s: AnalyticBackend(s, paired=True), objectives=None, **over):
    config = make_config("smoke", overrides={**BASE, "out": str(tmp_path), **over})
    return run_coadaptation(
        config,
        backend_factory=factory,
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=objectives or [TorqueObjective()],
    )


def refine_batches(summary):
    return [b for b in summary["batches"] if b.get("stage") == "refine"]


def test_off_by_default_and_the_run_unchanged(tmp_path):
    plain = run(tmp_path / "a").summary
    assert "refinement" not in plain and not refine_batches(plain)
    assert make_config("quick").refine_with == ""


def test_refines_the_best_real_design_every_step_real_recorded_and_only_gains_accepted(
    tmp_path,
):
    plain = run(tmp_path / "plain").summary
    result = run(tmp_path / "refined", store=str(tmp_path / "coadapt.db"), **REFINE)
    summary = result.summary
    batches = refine_batches(summary)

    # the search is the same; the refinement adds its rounds after the last outer iteration
    def timeless(bs):
        return [{k: v for k, v in b.items() if k != "seconds"} for b in bs]

    assert timeless(summary["batches"][: len(plain["batches"])]) == timeless(plain["batches"])
    assert len(batches) == 7 and {b["kind"] for b in batches} == {"real"}
    assert {b["outer"] for b in batches} == {1}
    assert [b["inner"] for b in batches] == list(range(3, 10))
    steps = [b["descent_step"] for b in batches]
    ref = summary["refinement"]
    assert ref["with"] == "gradient" and ref["rounds"] == 7 and ref["done"] is True
    assert ref["steps"] == steps
    # the start is the search's best real design (projected into the last range), evaluated
    # again under the final policy
    assert steps[0]["kind"] == "start" and steps[0]["accepted"] is True
    assert ref["start"] == steps[0]["design"]
    plain_state = json.loads(next((tmp_path / "plain").glob("*/state.json")).read_text())
    last = plain_state["spaces"][-1]["variables"]
    low, high = [v["low"] for v in last], [v["high"] for v in last]
    best = np.clip(plain_state["best_real"]["__tuple__"][0], low, high)
    np.testing.assert_allclose(steps[0]["design"], best, atol=1e-8)
    center_cost = steps[0]["real_cost"]
    for b, st in zip(batches, steps, strict=True):
        # each step beside its round's real cost, the cost's SE and the surrogate's cost
        assert st["real_cost"] == pytest.approx(b["best_cost"])
        assert st["real_cost_se"] == pytest.approx(b["best_cost_se"]) and st["real_cost_se"] > 0
        assert np.isfinite(st["surrogate_cost"])
        if st["kind"] == "start":
            continue
        assert st["source"] == "surrogate"
        # never accepted without a real improvement over the centre it left, never refused one
        assert st["accepted"] == (st["real_cost"] < center_cost)
        assert st["center_cost"] == pytest.approx(center_cost)
        if st["accepted"]:
            center_cost = st["real_cost"]
    assert ref["center_cost"] == pytest.approx(center_cost)
    assert ref["accepted_steps"] == sum(1 for s in steps[1:] if s["accepted"])
    assert ref["accepted_steps"] >= 1  # on the bowl the surrogate's slope points downhill
    # the refinement's design went to the final check; the summary says whether it won
    assert isinstance(ref["chosen"], bool)
    assert ref["chosen"] == bool(np.allclose(ref["center"], summary["best_design"]))
    picked = [i for i, st in enumerate(steps) if np.allclose(st["design"], summary["best_design"])]
    assert ref["chosen_step"] == (picked[0] if picked else None)
    # the run folder's summary.json (what the store's run row carries) holds every step
    on_disk = json.loads((result.run_dir / "summary.json").read_text())
    assert on_disk["refinement"]["steps"] == json.loads(json.dumps(steps))
    with ResultsStore(tmp_path / "coadapt.db", create=False) as store:
        stored = store.get_run(result.run_id)["summary"]["refinement"]
    assert stored["steps"] == json.loads(json.dumps(steps))


def test_an_interrupted_refinement_resumes_where_it_stopped(tmp_path):
    whole = run(tmp_path / "whole", **REFINE).summary
    # cut inside the refinement: the search's real rounds and reference levels come first
    searched = sum(1 for b in whole["batches"] if b["kind"] == "real" and "stage" not in b)
    cut_at = searched + 2 + 4  # + the two policies' nominal references + 3 refine rounds
    with pytest.raises(RuntimeError, match="injected"):
        run(
            tmp_path / "cut",
            factory=lambda s: AnalyticBackend(s, paired=True, fail_on_real_call=cut_at),
            **REFINE,
        )
    folder = next((tmp_path / "cut").iterdir())
    state = json.loads((folder / "state.json").read_text())
    assert state["phase"] == "refine" and 0 < len(state["refine"]["steps"]) < 7
    resumed = run_coadaptation(
        backend_factory=lambda s: AnalyticBackend(s, paired=True),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        resume=folder,
    ).summary
    assert resumed["refinement"]["steps"] == whole["refinement"]["steps"]
    assert [b.get("descent_step") for b in resumed["batches"]] == [
        b.get("descent_step") for b in whole["batches"]
    ]
    assert resumed["best_design"] == whole["best_design"]


def test_refused_before_training_when_it_cannot_refine(tmp_path):
    with pytest.raises(UserError, match="does not follow the surrogate's gradient"):
        run(tmp_path / "a", refine_with="pso")
    with pytest.raises(UserError, match="descends one objective"):
        run(
            tmp_path / "b",
            optimizer="nsga2",
            objective="torque,power",
            objectives=[TorqueObjective(), PowerObjective()],
            refine_with="gradient",
        )
    assert not any((tmp_path / "a").glob("*/state.json"))


def test_a_refined_run_is_a_row_of_its_own_in_the_report_and_a_cell_of_its_own_in_a_grid(
    tmp_path,
):
    import csv

    from coadapt_core.analysis.report import write_report
    from coadapt_core.experiments.cell import Cell
    from coadapt_core.experiments.cell_hash import cell_config_hash
    from coadapt_core.results.recorders import SqliteRecorder

    rec = SqliteRecorder(tmp_path / "r.db")
    for refine, best in (("", 0.6), ("gradient", 0.5)):
        config = {"method": "ours", "objective": "torque", "terrain": "flat", "seed": 0}
        config |= {"preset": "quick", "sim": "mujoco", "robot": "kuafu", "optimizer": "pso"}
        run_id = rec.start_run({**config, "refine_with": refine})
        rec.record_evaluations(
            run_id,
            outer=0,
            inner=0,
            designs=np.array([[best, 1.0]]),
            kind="real",
            costs=[{"torque": best}],
            interactions=100,
            seconds=1.0,
        )
        summary = {"run_id": run_id, "best_design": [best, 1.0], "best_cost": best}
        rec.finish(run_id, {**summary, "nominal_cost": 2.0, "improvement": (2 - best) / 2})
    files = write_report(rec.store, None, tmp_path / "report", sim2sim=False)
    with open(files["table6.csv"]) as fh:
        rows = list(csv.DictReader(fh))
    assert sorted((r["optimizer"], r["runs"], float(r["best_cost"])) for r in rows) == [
        ("pso", "1", 0.6),
        ("pso+gradient", "1", 0.5),
    ]
    # a grid given --run-arg=--refine-with=gradient: its cells' runs are not the plain ones
    cell = Cell("ours", "torque", "flat", 0, "smoke", "mujoco", "pso", "kuafu")
    plain, refined = cell_config_hash(cell), cell_config_hash(cell, ["--refine-with=gradient"])
    assert plain is not None and refined is not None and plain != refined


def test_the_run_summary_says_what_the_refinement_bought():
    from coadapt_core.cli.run_summary import refinement_line

    ref = {"with": "gradient", "rounds": 8, "start_cost": 1.2345, "start_cost_se": 0.012}
    ref |= {"center_cost": 1.2, "center_cost_se": 0.011, "accepted_steps": 2, "chosen": False}
    assert refinement_line(ref) == (
        "refinement (gradient, 8 real rounds on the run's scenarios): start 1.234 +- 0.012 -> "
        "1.200 +- 0.011, 2 of 7 steps accepted; the final check chose another design"
    )
    assert refinement_line(ref | {"chosen_step": 2}).endswith(
        "the final check chose its step 2's design (not the last accepted)"
    )
    assert refinement_line(ref | {"chosen_step": 0}).endswith(
        "the final check chose its start (the search's design)"
    )


def test_the_progress_of_a_run_in_its_refinement_is_that_of_its_last_outer_iterations_end():
    from coadapt_core.coadapt.schedule import Schedule
    from coadapt_core.coadapt.state import LoopState
    from coadapt_core.methods import get_method

    config = make_config("smoke", overrides={**BASE, **REFINE})
    schedule = Schedule.of(config, get_method("ours"), pretrained=False)
    end = LoopState("r", {}, phase="optimize", outer=1, inner=3)
    refining = LoopState("r", {}, phase="refine", outer=1, inner=7)
    final = LoopState("r", {}, phase="final", outer=2)
    assert schedule.fraction_of_steps(refining) == schedule.fraction_of_steps(end)
    assert schedule.fraction_of_steps(refining) <= schedule.fraction_of_steps(final) < 1
