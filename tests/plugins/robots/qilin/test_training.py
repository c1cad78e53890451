"""`coadapt train --robot qilin` runs the core's task on a 12-joint quadruped without any
quadruped case in the core: observations and actions sized by its joints, its trot read
from `Qilin.legs()`, the walking gate at the end; and its shipped policy walks."""

from __future__ import annotations

import json

import pytest

from coadapt_core.cli import main


@pytest.mark.slow
def test_a_tiny_qilin_training_writes_a_12_joint_policy_and_judges_it(tmp_path, capsys) -> None:
    from coadapt_core.learning.checkpoints import read_checkpoint

    out = tmp_path / "qilin"
    assert (
        main(
            [
                "train",
                "--robot",
                "qilin",
                "--steps",
                "128",
                "--num-designs",
                "2",
                "--agents",
                "4",
                "--steps-per-env",
                "8",
                "--epochs",
                "1",
                "--minibatches",
                "2",
                "--out",
                str(out),
                "--quiet",
                "--logger",
                "none",
            ]
        )
        == 0
    )
    lines = [
        json.loads(line) for line in capsys.readouterr().out.splitlines() if line.startswith("{")
    ]
    state = read_checkpoint(out / "model_final.pt")
    assert state["robot"] == "qilin"
    # 3 + 3 + 3 + 3 base and command, 12 + 12 joints, 5 x 12 past actions, 2 clock values
    assert (
        state["dims"]["num_actions"] == 12
        and state["dims"]["num_obs"] == 98
        and state["dims"]["num_design"] == 2
    )
    gate = lines[-1]["walking_gate"]  # two iterations do not walk
    assert gate["walking"] is False and gate["design"] == [1.0, 1.0]


@pytest.mark.slow
def test_the_shipped_flat_policy_walks_at_the_nominal_design_and_a_corner(capsys) -> None:
    """policies/flat.pt (5.2 M interactions) passes the walking gate without --checkpoint;
    the README's 50 agents x 20 s figures: 0.45-0.52 m/s under 0.5 m/s, survival 1.00."""
    for design in ("1,1", "0.7,0.7"):
        assert (
            main(
                [
                    "eval",
                    "--robot",
                    "qilin",
                    "--design",
                    design,
                    "--agents",
                    "8",
                    "--seconds",
                    "5",
                    "--json",
                ]
            )
            == 0
        )
        result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert result["walking"] is True and result["survival"] >= 0.95
        assert abs(result["vx_mean"] - 0.5) < 0.1 and result["tracking_ratio"] < 0.3
