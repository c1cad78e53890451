"""Resumability: a run interrupted mid-way and resumed from its run folder reaches exactly
the result of an uninterrupted run with the same seed (analytic backend, CPU)."""

from __future__ import annotations

import pytest
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.errors import UserError
from coadapt_core.results.recorders import read_evaluations
from tests.fakes.analytic import MIXED_NOMINAL, MIXED_SPACE, NOMINAL, SPACE, AnalyticBackend

BASE = dict(
    population=10,
    optimizer_iterations=4,
    outer_iterations=3,
    agents_per_design=20,
    eval_steps=10,
    train_steps=1000,
    retrain_steps=500,
    seed=3,
)


class TrainFails(AnalyticBackend):
    def train(self, designs, steps, *, seed=0):
        if self.trainings == 1:  # the second training phase of this process
            raise KeyboardInterrupt("injected interruption during retraining")
        return super().train(designs, steps, seed=seed)


def start(tmp_path, name, factory, **overrides):
    # a store of this test's own (the default, beside the runs folder, is shared by every test
    # of the session, and BO studies are named after the run folder)
    config = make_config(
        "smoke", overrides={**BASE, "store": str(tmp_path / "coadapt.db"), **overrides}
    )
    space, nominal = (
        (MIXED_SPACE, MIXED_NOMINAL)
        if overrides.get("optimizer") == "mixed-pso"
        else (SPACE, NOMINAL)
    )
    return run_coadaptation(
        config,
        backend_factory=factory,
        design_space=space,
        nominal_design=nominal,
        objectives=[TorqueObjective()],
        run_dir=tmp_path / name,
    )


def resume(tmp_path, name, **overrides):
    space, nominal = (
        (MIXED_SPACE, MIXED_NOMINAL)
        if overrides.get("optimizer") == "mixed-pso"
        else (SPACE, NOMINAL)
    )
    return run_coadaptation(
        backend_factory=lambda s: AnalyticBackend(s),
        design_space=space,
        nominal_design=nominal,
        objectives=[TorqueObjective()],
        resume=tmp_path / name,
    )


def comparable(summary):
    keep = (
        "best_design",
        "best_cost",
        "nominal_cost",
        "improvement",
        "interactions",
        "train_interactions",
        "eval_interactions",
        "final_interactions",
        "real_evaluations",
        "surrogate_evaluations",
        "spaces",
        "final_space",
    )
    out = {k: summary[k] for k in keep}
    out["batches"] = [{k: v for k, v in b.items() if k != "seconds"} for b in summary["batches"]]
    return out


def records(run_dir):
    return [
        {
            k: r[k]
            for k in (
                "outer",
                "inner",
                "idx",
                "kind",
                "design",
                "costs",
                "interactions",
                "surrogate_error",
            )
        }
        for r in read_evaluations(run_dir)
    ]


@pytest.mark.parametrize(
    ("method", "optimizer", "failing"),
    [
        ("ours", "pso", lambda s: AnalyticBackend(s, fail_on_real_call=4)),
        ("ours", "pso", lambda s: TrainFails(s)),
        ("ours", "mixed-pso", lambda s: AnalyticBackend(s, fail_on_real_call=5)),
        ("ours", "bo", lambda s: AnalyticBackend(s, fail_on_real_call=3)),
        (
            "bo-specialized",
            "bo",
            lambda s: AnalyticBackend(s, fail_on_real_call=1) if s % 3 == 0 else AnalyticBackend(s),
        ),
    ],
)
def test_interrupted_and_resumed_run_equals_uninterrupted(tmp_path, method, optimizer, failing):
    overrides = dict(method=method, optimizer=optimizer, bo_designs=6)
    full = start(tmp_path, "full", lambda s: AnalyticBackend(s), **overrides).summary
    with pytest.raises((RuntimeError, KeyboardInterrupt), match="injected"):
        start(tmp_path, "cut", failing, **overrides)
    assert (tmp_path / "cut" / "state.json").exists()
    import json

    assert json.loads((tmp_path / "cut" / "summary.json").read_text())["status"] == "interrupted"
    resumed = resume(tmp_path, "cut", **overrides).summary
    assert comparable(resumed) == comparable(full)
    assert records(tmp_path / "cut") == records(tmp_path / "full")


def test_resuming_a_finished_run_returns_its_summary(tmp_path):
    done = start(tmp_path, "done", lambda s: AnalyticBackend(s)).summary
    again = resume(tmp_path, "done").summary
    assert again["best_design"] == done["best_design"]


def test_resume_of_a_folder_without_state_is_a_user_error(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match="cannot resume"):
        resume(tmp_path, "empty")


def test_starting_into_an_existing_run_folder_is_refused(tmp_path):
    start(tmp_path, "r", lambda s: AnalyticBackend(s), outer_iterations=1, optimizer_iterations=1)
    with pytest.raises(UserError, match="already holds a run"):
        start(tmp_path, "r", lambda s: AnalyticBackend(s))


def test_state_is_saved_after_training_and_every_batch(tmp_path):
    saves = []
    import coadapt_core.coadapt.loop as loop_module
    import coadapt_core.coadapt.run as run_module

    original = loop_module.save_state

    def spy(run_dir, state):
        saves.append((state.phase, state.outer, state.inner))
        original(run_dir, state)

    # the first state is written where the run starts (run.py), the others by the loop
    loop_module.save_state = run_module.save_state = spy
    try:
        start(
            tmp_path,
            "spy",
            lambda s: AnalyticBackend(s),
            outer_iterations=2,
            optimizer_iterations=2,
        )
    finally:
        loop_module.save_state = run_module.save_state = original
    # start, then per outer: after training, after each of 2 batches, after narrowing; then done
    assert saves == [
        ("train", 0, 0),
        ("optimize", 0, 0),
        ("optimize", 0, 1),
        ("optimize", 0, 2),
        ("train", 1, 0),
        ("optimize", 1, 0),
        ("optimize", 1, 1),
        ("optimize", 1, 2),
        ("final", 2, 0),
        ("done", 2, 0),
    ]
