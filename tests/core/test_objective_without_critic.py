"""An objective the starting policy has no pseudo-critic for (its head would start untrained)
has a defined behaviour, said on the run's first line: surrogate rounds wait for a fit to a
real round of the current policy (all real with fit_surrogate off), and a surrogate-only
method is refused. The loop runs on the analytic fake; the starting policy is Kuafu's real
shipped checkpoint (pseudo-critics: tracking, power, torque; not `composite`)."""

from __future__ import annotations

import json

import pytest

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from tests.fakes.analytic import AnalyticBackend


@pytest.fixture
def fake_learner(monkeypatch):
    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )


ARGS = [
    "run",
    "--preset",
    "smoke",
    "--store",
    "none",
    "--json",
    "--no-video",
    "--evaluation-probability",
    "0.9",
    "--optimizer-iterations",
    "4",
]


def run(tmp_path, capsys, *extra):
    code = main([*ARGS, "--out", str(tmp_path), *extra])
    captured = capsys.readouterr()
    summary = None
    if code == 0:
        line = json.loads(captured.out.strip().splitlines()[-1])
        summary = json.loads((tmp_path / line["run_id"] / "summary.json").read_text())
    return code, captured.err, summary


def test_without_a_critic_a_surrogate_round_comes_only_after_a_fit(tmp_path, capsys, fake_learner):
    code, err, summary = run(tmp_path, capsys, "--objective", "composite")
    assert code == 0, err
    first = err.strip().splitlines()[0]
    assert first.startswith(
        "note: objective 'composite' has no pseudo-critic in the starting policy flat.pt"
    )
    assert "waits until the pseudo-critics are fitted to a real round" in first
    assert summary["notes"] == [first]
    for outer, seq in _kinds(
        summary
    ).items():  # after each training, a real round comes before any surrogate round
        assert seq[0] == "real", (outer, seq)
    assert summary["surrogate_evaluations"] > 0  # ... and then the fitted surrogate is used


def _kinds(summary):
    out = {}
    for batch in summary["batches"]:
        out.setdefault(batch["outer"], []).append(batch["kind"])
    return out


def test_with_fit_surrogate_off_every_round_is_real(tmp_path, capsys, fake_learner):
    code, err, summary = run(tmp_path, capsys, "--objective", "composite", "--no-fit-surrogate")
    assert code == 0, err
    assert "every round of this run is real" in err.splitlines()[0]
    assert summary["surrogate_evaluations"] == 0 and summary["real_evaluations"] > 0
    # an objective the policy has a pseudo-critic for, same settings: surrogate rounds as usual
    code, err, plain = run(
        tmp_path / "tracking", capsys, "--objective", "tracking", "--no-fit-surrogate"
    )
    assert code == 0 and "pseudo-critic" not in err and plain["notes"] == []
    assert plain["surrogate_evaluations"] > 0


def test_a_surrogate_only_method_is_refused_in_one_line(tmp_path, capsys, fake_learner):
    code, err, _ = run(tmp_path, capsys, "--objective", "composite", "--method", "no-real")
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "no pseudo-critic" in lines[0] and "surrogate only" in lines[0]
    assert "--objectives tracking,power,torque,composite" in lines[0]
