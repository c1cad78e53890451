"""Experiment tracking: a `coadapt run` writes TensorBoard event files with its training
curves, best cost per round and surrogate error; `--logger wandb` without wandb is one
line and exit 2; `--logger none` writes nothing."""

from __future__ import annotations

import importlib.util

import pytest

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from tests.fakes.analytic import AnalyticBackend


@pytest.fixture
def fake_learner(monkeypatch):
    monkeypatch.setattr(loop_setup, "universal_policy_factory", lambda *a, **k: (lambda seed: AnalyticBackend(seed)))


def scalars(folder):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(folder))
    acc.Reload()
    return {tag: [(e.step, e.value) for e in acc.Scalars(tag)] for tag in acc.Tags()["scalars"]}


def test_run_writes_rounds_phases_and_surrogate_error_to_tensorboard(tmp_path, fake_learner):
    assert main(["run", "--preset", "smoke", "--out", str(tmp_path), "--store", "none", "--json"]) == 0
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
    assert main(["run", "--preset", "smoke", "--out", str(tmp_path), "--store", "none", "--logger", "none", "--json"]) == 0
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert not (run_dir / "tb").exists()


@pytest.mark.skipif(importlib.util.find_spec("wandb") is not None, reason="wandb is installed here")
def test_wandb_without_wandb_is_one_line_exit_2(tmp_path, capsys, fake_learner):
    code = main(["run", "--preset", "smoke", "--out", str(tmp_path), "--logger", "wandb"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "pip install wandb" in err[0]
    assert not any(tmp_path.iterdir())  # checked before anything runs
