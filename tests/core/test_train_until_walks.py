"""`coadapt train --until-walks` on real MuJoCo at a tiny size: the walking checks leave the
training's random draws as they were, each budget stops it (exit 3), a check that walks stops
it and keeps its checkpoint as OUT/walks.pt (Kuafu's shipped policy as the start, so the gate
holds after one update; the pseudo-critics, paused meanwhile, fitted before it is written), and
bad options are one line with exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from coadapt_core.cli import main
from coadapt_core.cli.until_walks import EXIT_NOT_WALKING
from coadapt_core.experiments.walking_check import (
    GATE_DESIGNS,
    check_text,
    training_draws_kept,
    worst_design,
)

#: 2 designs x 4 agents x 8 steps = 64 interactions an iteration; checks of 2 agents x 1 s
TINY = ["--num-designs", "2", "--agents", "4", "--steps-per-env", "8"]
CHECK = ["--check-agents", "2", "--check-seconds", "1", "--threads", "1", "--logger", "none"]


def _train(out, *args: str) -> int:
    return main(["train", *TINY, *CHECK, "--out", str(out), "--until-walks", *args])


def _checks(out) -> list[dict]:
    return [json.loads(line) for line in (out / "checks.jsonl").read_text().splitlines()]


def _actor(path) -> dict:
    state = torch.load(path, map_location="cpu", weights_only=True)
    return {k: v for k, v in state["ppo"]["actor"].items()}


@pytest.mark.slow
def test_checks_leave_the_training_draws_as_they_were(tmp_path, capsys):
    every, once = tmp_path / "every", tmp_path / "once"
    scratch = ["--robot", "qilin", "--terrain", "slope", "--steps", "128", "--quiet"]
    # two iterations: checked after each, or once after the last
    assert _train(every, *scratch, "--check-every", "1") == EXIT_NOT_WALKING
    assert _train(once, *scratch, "--check-every", "2") == EXIT_NOT_WALKING
    assert [r["interactions"] for r in _checks(every)] == [64, 128]
    assert [r["interactions"] for r in _checks(once)] == [128]
    # the same training either way: the final weights are equal to the bit
    a, b = _actor(every / "model_final.pt"), _actor(once / "model_final.pt")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    last = _checks(every)[-1]
    assert last["mean_reward"] == _checks(once)[-1]["mean_reward"]
    # two updates from scratch do not walk: the gate says so at all five designs
    assert last["walking"] is False and list(last["designs"]) == list(GATE_DESIGNS)
    assert last["designs"]["upper"]["design"] == [1.3, 1.3]  # Qilin's range is [0.7, 1.3]^2
    assert not (every / "walks.pt").exists() and (every / "check.pt").is_file()
    out = capsys.readouterr()
    summary = json.loads(out.out.strip().splitlines()[-1])["until_walks"]
    assert summary["walked"] is False and summary["budget"] == "interactions"
    assert summary["interactions"] == 128
    assert "the interaction budget (--steps 128) ran out" in out.err
    assert f"--terrain slope --resume {every / 'model_final.pt'} --until-walks" in out.err


@pytest.mark.slow
def test_the_wall_clock_budget_stops_it_with_one_last_check(tmp_path, capsys, monkeypatch):
    from coadapt_core.cli import progress
    from coadapt_core.cli import train as train_cli

    shown = []  # what the progress line was given to show

    class Recording(progress.ProgressLine):
        def update(self, done=None, detail=None, **kw):
            shown.append(detail)
            super().update(done, detail, **kw)

    monkeypatch.setattr(train_cli, "ProgressLine", Recording)
    out = tmp_path / "t"
    code = _train(
        out, "--robot", "qilin", "--terrain", "slope", "--steps", "6400", "--max-seconds", "0.001"
    )
    assert code == EXIT_NOT_WALKING
    # the first iteration spent the budget; its state was checked, then training stopped
    assert [r["interactions"] for r in _checks(out)] == [64]
    assert len((out / "progress.jsonl").read_text().splitlines()) == 1
    err = capsys.readouterr().err
    assert "the wall-clock budget (--max-seconds 0.001) ran out after 64 interactions" in err
    assert "last check it 1: no, worst " in err
    # the progress line shows the last check after the iteration's figures
    row = _checks(out)[0]
    assert check_text(row).startswith(f"check it 1: no, worst {row['worst']}: survival ")
    assert "reward" in shown[-1] and shown[-1].endswith("  " + check_text(row))
    assert "check it" not in shown[0]


@pytest.mark.slow
def test_a_check_that_walks_stops_it_and_keeps_the_checkpoint(tmp_path, capsys):
    out = tmp_path / "k"
    # Kuafu's shipped flat policy walks; a small learning rate keeps it so through two updates
    code = _train(
        out,
        *("--robot", "kuafu", "--init-from", "plugins/robots/kuafu/policies/flat.pt"),
        *("--learning-rate", "1e-5", "--steps", "640", "--check-every", "2"),
        *("--pseudo-catch-up", "3"),
    )
    assert code == 0
    checks = _checks(out)
    assert len(checks) == 1 and checks[0]["walking"] is True
    # stopped at the first check: 2 of the budget's 10 iterations, then the pseudo-critics'
    # 3 iterations of fit on the walking policy
    assert len((out / "progress.jsonl").read_text().splitlines()) == 2 + 3
    for name in GATE_DESIGNS:
        d = checks[0]["designs"][name]
        assert d["survival"] >= 0.8 and d["tracking_ratio"] <= 0.5
    # the checkpoint judged is kept, and the final one and its export are the same policy
    assert (out / "walks.pt").is_file() and not (out / "check.pt").exists()
    a, b = _actor(out / "walks.pt"), _actor(out / "model_final.pt")
    assert all(torch.equal(a[k], b[k]) for k in a)
    # paused while it trained, the pseudo-critics were fitted before walks.pt was written:
    # they are no longer the ones it started from
    walks = torch.load(out / "walks.pt", map_location="cpu", weights_only=True)
    start = torch.load(
        "plugins/robots/kuafu/policies/flat.pt", map_location="cpu", weights_only=True
    )
    fitted, initial = walks["ppo"]["pseudo_critic"], start["ppo"]["pseudo_critic"]
    assert fitted.keys() == initial.keys()
    assert all(not torch.equal(fitted[k], initial[k]) for k in fitted)
    assert walks["total_steps"] - start["total_steps"] == 128 + 3 * 64
    err = capsys.readouterr().err
    assert "walks at the nominal design and the four corners after 128 interactions" in err
    assert "the pseudo-critics' fit on the walking policy 192 interactions" in err
    assert "policies/flat.pt" in err and str(out / "walks.pt") in err
    # a new run from a shipped policy: its training clock started at 0, and walks.pt holds it
    assert "before the resume" not in err and "train_seconds" not in start
    assert 0 < walks["train_seconds"] == pytest.approx(checks[0]["train_seconds"], abs=0.01)


@pytest.mark.slow
def test_a_resumed_run_counts_the_training_seconds_before_the_resume(tmp_path, capsys):
    out = tmp_path / "r"
    scratch = ["--robot", "qilin", "--terrain", "slope", "--quiet"]
    assert _train(out, *scratch, "--steps", "64") == EXIT_NOT_WALKING
    first = torch.load(out / "model_final.pt", map_location="cpu", weights_only=True)
    carried = first["train_seconds"]  # one iteration's training, the check's not counted
    assert carried > 0 and _checks(out)[0]["train_seconds"] == round(carried, 2)
    capsys.readouterr()
    # resumed under a wall-clock budget the first part already spent: one iteration, then it
    # stops, its count going on from the checkpoint's
    code = _train(
        out, *scratch, "--resume", str(out / "model_final.pt"), "--steps", "640",
        "--max-seconds", f"{carried:.6f}",
    )  # fmt: skip
    assert code == EXIT_NOT_WALKING
    printed = capsys.readouterr()
    summary = json.loads(printed.out.strip().splitlines()[-1])["until_walks"]
    assert summary["budget"] == "seconds" and summary["interactions"] == 64
    assert summary["carried_seconds"] == round(carried, 2)
    second = torch.load(out / "model_final.pt", map_location="cpu", weights_only=True)
    assert second["train_seconds"] > carried
    assert summary["train_seconds"] == round(second["train_seconds"], 2)
    assert [r["interactions"] for r in _checks(out)] == [64, 128]
    assert _checks(out)[1]["train_seconds"] == summary["train_seconds"]
    assert f"{carried:.0f} s of it before the resume" in printed.err
    assert f"--max-seconds S (S above {second['train_seconds']:.0f}" in printed.err
    # --init-from starts a new run: its count from 0
    new = tmp_path / "n"
    assert _train(new, *scratch, "--init-from", str(out / "model_final.pt"), "--steps", "64") == 3
    printed = capsys.readouterr()
    summary = json.loads(printed.out.strip().splitlines()[-1])["until_walks"]
    assert summary["carried_seconds"] == 0 and _checks(new)[0]["interactions"] == 128 + 64
    assert _checks(new)[0]["train_seconds"] == summary["train_seconds"]  # one iteration's
    assert "before the resume" not in printed.err


@pytest.mark.parametrize(
    "args, says",
    [
        (["--until-walks", "--max-seconds", "0"], "max_seconds must be a finite number > 0"),
        (["--until-walks", "--max-seconds", "-5"], "max_seconds must be a finite number > 0"),
        (["--until-walks", "--check-every", "0"], "check_every must be an integer >= 1"),
        (["--max-seconds", "60"], "--max-seconds is the wall-clock budget of --until-walks"),
        (["--until-walks", "--check-seconds", "0.5"], "check_seconds must be >= 1"),
    ],
)
def test_bad_budgets_are_one_line_and_exit_2(tmp_path, capsys, args, says):
    out = tmp_path / "bad"
    base = ["train", "--robot", "qilin", "--terrain", "slope", *TINY, "--steps", "64"]
    assert main([*base, "--out", str(out), "--logger", "none", *args]) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and says in lines[0] and "Traceback" not in err, err
    assert not out.exists()


def test_the_draws_are_restored_and_the_worst_design_is_furthest_from_the_gate():
    torch.manual_seed(3)
    np.random.seed(3)
    with training_draws_kept():
        torch.manual_seed(0)  # as an evaluation's Trainer does
        np.random.seed(0)
        torch.rand(5)
    after = torch.rand(2), np.random.rand(2)
    torch.manual_seed(3)
    np.random.seed(3)
    assert torch.equal(after[0], torch.rand(2)) and np.array_equal(after[1], np.random.rand(2))
    designs = {
        "nominal": {"survival": 1.0, "tracking_ratio": 0.3},
        "lower": {"survival": 0.7, "tracking_ratio": 0.4},  # 12.5 % short of 0.8
        "upper": {"survival": 1.0, "tracking_ratio": 0.9},  # 80 % over 0.5: the worst
    }
    assert worst_design(designs) == "upper"


@pytest.fixture(autouse=True)
def _restore_threads():
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
