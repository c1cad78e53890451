"""Everyday use (issue 30): the walking gate on smoke runs, progress that is never silent and
whose ETA holds, a short `run --help`, and small things a user reads."""

from __future__ import annotations

import json

import pytest

from coadapt_core.cli import main
from coadapt_core.coadapt.reliability import MIN_JUDGED_STEPS, judge_short

FAILED = (False, "the policy does not walk (real rounds: tracking error 0.54 x command > 0.5)")


def test_a_short_evaluation_does_not_judge_a_trained_policy_but_still_fails_one_from_scratch():
    verdict, reason = judge_short(FAILED, 20, from_scratch=False)
    assert verdict is None and reason.startswith("not judged: 20 steps per scenario") and "0.54" in reason
    verdict, reason = judge_short(FAILED, 20, from_scratch=True)
    assert verdict is False and "trained from scratch" in reason
    assert judge_short(FAILED, MIN_JUDGED_STEPS, from_scratch=False) == FAILED  # long enough: the gate stands
    passed = (True, "passed the walking gate")
    assert judge_short(passed, 20, from_scratch=True) == passed


@pytest.mark.slow
def test_smoke_run_with_the_shipped_policy_is_not_called_unreliable_but_one_from_scratch_is(tmp_path, capsys):
    small = ["--preset", "smoke", "--outer-iterations", "1", "--optimizer-iterations", "1", "--out", str(tmp_path),
             "--store", "none", "--no-video"]
    assert main(["run", *small]) == 0
    out = capsys.readouterr().out
    assert "UNRELIABLE" not in out
    assert "walking gate: " in out and "starting policy: " in out and "flat.pt" in out
    assert main(["run", *small, "--checkpoint", "none"]) == 0
    out = capsys.readouterr().out
    assert "UNRELIABLE" in out and "starting policy: none" in out
