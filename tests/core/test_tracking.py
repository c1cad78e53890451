"""Experiment tracking: a `coadapt run` writes TensorBoard event files with its training
curves, best cost per round and surrogate error; `--logger wandb` without wandb is one
line and exit 2; `--logger none` writes nothing."""

from __future__ import annotations

import importlib.util
import re

import pytest

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from tests.fakes.analytic import AnalyticBackend


@pytest.fixture
def fake_learner(monkeypatch):
    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )


def scalars(folder):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(folder))
    acc.Reload()
    return {tag: [(e.step, e.value) for e in acc.Scalars(tag)] for tag in acc.Tags()["scalars"]}


def test_run_writes_rounds_phases_and_surrogate_error_to_tensorboard(tmp_path, fake_learner):
    # every real round judged (a fit before each), so the surrogate's error is logged
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--out",
                str(tmp_path),
                "--store",
                "none",
                "--json",
                "--surrogate-error-fits",
            ]
        )
        == 0
    )
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    found = scalars(run_dir / "tb")
    # smoke: 2 outer x 2 rounds; one training phase per outer iteration
    best = found["round/best_real_torque"]
    assert [s for s, _ in found["round/surrogate_round"]] == [1, 2, 3, 4]
    values = [v for _, v in best]
    assert values == sorted(values, reverse=True)  # the best so far never gets worse
    assert [s for s, _ in found["phase/steps"]] == [1, 2]
    assert "surrogate/rel_error_torque" in found and "final/improvement" in found


def test_logger_none_writes_no_events(tmp_path, fake_learner):
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--out",
                str(tmp_path),
                "--store",
                "none",
                "--logger",
                "none",
                "--json",
            ]
        )
        == 0
    )
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert not (run_dir / "tb").exists()


@pytest.mark.skipif(importlib.util.find_spec("wandb") is not None, reason="wandb is installed here")
def test_wandb_without_wandb_is_one_line_exit_2(tmp_path, capsys, fake_learner):
    code = main(["run", "--preset", "smoke", "--out", str(tmp_path), "--logger", "wandb"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "pip install wandb" in err[0]
    assert not any(tmp_path.iterdir())  # checked before anything runs


@pytest.mark.slow
def test_real_smoke_run_leaves_event_files_and_a_best_vs_nominal_gif(tmp_path, capsys):
    """The real learner on MuJoCo at a tiny size: the run folder holds TensorBoard events
    with per-iteration training curves and a GIF of both designs walking side by side."""
    from PIL import Image

    args = [
        "run",
        "--preset",
        "smoke",
        "--population",
        "3",
        "--agents-per-design",
        "2",
        "--eval-steps",
        "10",
        "--train-steps",
        "100",
        "--retrain-steps",
        "50",
        "--store",
        "none",
        "--out",
        str(tmp_path),
        "--json",
    ]
    assert main(args) == 0
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    found = scalars(run_dir / "tb")
    assert len(found["train/mean_reward"]) >= 2 and len(found["round/best_real_torque"]) == 4
    err = capsys.readouterr().err
    gif = run_dir / "best_vs_nominal.gif"
    if "no offscreen GL" in err:
        pytest.skip("no EGL/OSMesa here: " + err.split("video:")[-1].strip())
    with Image.open(gif) as image:
        assert image.n_frames >= 10 and image.size == (480, 240)  # two 240 x 240 panels


def test_run_without_gl_still_finishes_with_one_line_note(tmp_path, capsys, monkeypatch):
    from coadapt_core.viz.video import render_run_video

    monkeypatch.setenv("MUJOCO_GL", "not-a-backend")
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "backend-outer0.pt").write_bytes(b"not a checkpoint")
    written = render_run_video(
        tmp_path, {"best_design": [1.0, 1.0], "nominal_design": [1.0, 1.0]}, {"robot": "kuafu"}
    )
    lines = capsys.readouterr().err.strip().splitlines()
    assert written == [] and len(lines) == 1 and lines[0].startswith("video: not rendered")


def test_bo_study_is_kept_in_the_run_store_under_the_run_id(tmp_path, fake_learner):
    """bo-specialized keeps its optuna study in the run's results store by default, named
    `<run id>-outer0`, readable by optuna's own tools; the run records optimizer bo."""
    import optuna

    from coadapt_core.results import ResultsStore

    db = tmp_path / "s.db"
    assert (
        main(
            [
                "run",
                "--method",
                "bo-specialized",
                "--preset",
                "smoke",
                "--bo-designs",
                "3",
                "--out",
                str(tmp_path),
                "--store",
                str(db),
                "--json",
                "--no-video",
            ]
        )
        == 0
    )
    (run,) = ResultsStore(db).list_runs()
    assert run["optimizer"] == "bo" and "-bo-specialized-bo-" in run["id"]
    study = optuna.load_study(study_name=f"{run['id']}-outer0", storage=f"sqlite:///{db}")
    assert len(study.trials) == 3


def test_export_names_design_columns_after_the_run_design_space(tmp_path, fake_learner):
    """A run records its design space, so `coadapt export` names the design columns
    thigh_scale, shank_scale, hip_motor, knee_motor (not x0, x1, ...)."""
    import csv

    db = tmp_path / "s.db"
    assert (
        main(
            [
                "run",
                "--optimizer",
                "mixed-pso",
                "--preset",
                "smoke",
                "--out",
                str(tmp_path / "runs"),
                "--store",
                str(db),
                "--json",
                "--no-video",
            ]
        )
        == 0
    )
    assert main(["export", "--store", str(db), "-o", str(tmp_path / "x")]) == 0
    with (tmp_path / "x" / "evaluations.csv").open() as fh:
        header = next(csv.reader(fh))
    assert {"thigh_scale", "shank_scale", "hip_motor", "knee_motor"} <= set(header)
    assert not any(re.fullmatch(r"x\d+", h) for h in header)
