"""The walking gate of `coadapt run` wherever a policy is judged: `coadapt eval` (table and
--json) and the end of `coadapt train` (`training_verdict`). A policy that stands still is
not passed as walking; the shipped Kuafu flat policy at its nominal design is."""

from __future__ import annotations

import json

import pytest
import torch

from coadapt_core.cli import main
from coadapt_core.coadapt.reliability import MIN_JUDGED_STEPS, WALKING_GATE, judge_policy

KUAFU_FLAT = "plugins/robots/kuafu/policies/flat.pt"


def test_judge_policy_applies_the_run_gate_with_numbers() -> None:
    assert judge_policy(1.0, 0.2, 250)[0] is True
    walking, reason = judge_policy(1.0, 0.97, 250)  # stands still: error about the command's size
    assert walking is False
    assert "tracking ratio 0.97 (RMS velocity error / command size) > 0.5" in reason
    walking, reason = judge_policy(0.5, 0.1, 250)
    assert walking is False and "survival 0.50 < 0.8" in reason
    assert (
        judge_policy(WALKING_GATE.min_survival, WALKING_GATE.max_tracking_ratio, MIN_JUDGED_STEPS)[
            0
        ]
        is True
    )
    # too short to judge tracking, unless it falls or stands still
    assert judge_policy(1.0, 0.6, MIN_JUDGED_STEPS - 1)[0] is None
    assert judge_policy(1.0, 0.99, MIN_JUDGED_STEPS - 1)[0] is False
    assert judge_policy(None, None, 250) == (None, "not measured")
    assert judge_policy(1.0, None, 250)[0] is True  # a zero command: survival alone


def _standing_policy(path) -> None:
    """The shipped flat policy with its action layer zeroed: every action 0, i.e. the
    default joint pose as the PD target (the robot stands)."""
    state = torch.load(KUAFU_FLAT, map_location="cpu", weights_only=True)
    last = max(k for k in state["ppo"]["actor"] if k.startswith("body.") and k.endswith(".weight"))
    state["ppo"]["actor"][last].zero_()
    state["ppo"]["actor"][last.replace("weight", "bias")].zero_()
    torch.save(state, path)


def _eval(capsys, *args: str) -> dict:
    assert (
        main(["eval", "--robot", "kuafu", "--agents", "8", "--seconds", "4", "--json", *args]) == 0
    )
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


@pytest.mark.slow
def test_eval_does_not_pass_a_standing_policy_as_walking(tmp_path, capsys) -> None:
    _standing_policy(tmp_path / "standing.pt")
    result = _eval(capsys, "--checkpoint", str(tmp_path / "standing.pt"))
    # survives and stands: survival alone would call this a good policy
    assert result["survival"] >= 0.95 and abs(result["vx_mean"]) < 0.1
    assert result["tracking_ratio"] > 0.8
    assert result["walking"] is False and "does not walk (tracking ratio" in result["walking_gate"]
    # the end of `coadapt train` says the same of it
    from coadapt_core.design_space import DesignSpace
    from coadapt_core.experiments.evaluate import training_verdict
    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", "kuafu")
    space = DesignSpace.from_dict(torch.load(KUAFU_FLAT, weights_only=True)["design_space"])
    verdict = training_verdict(
        tmp_path / "standing.pt",
        robot,
        get_registry().get("simulator", "mujoco"),
        space,
        terrain="flat",
    )
    assert (
        verdict["walking"] is False
        and verdict["design"] == [1.0, 1.0]
        and verdict["tracking_ratio"] > 0.8
    )


@pytest.mark.slow
def test_eval_passes_the_shipped_flat_policy_as_walking(capsys) -> None:
    result = _eval(capsys, "--design", "1,1")
    assert result["survival"] >= 0.95 and abs(result["vx_mean"] - 0.5) < 0.1
    assert result["tracking_ratio"] < 0.3
    assert result["walking"] is True and result["walking_gate"].startswith("walks (survival 1.00")
    # the table says it too, in the same words
    assert main(["eval", "--robot", "kuafu", "--agents", "8", "--seconds", "4"]) == 0
    assert "walking gate: walks (survival" in " ".join(capsys.readouterr().out.split())
