"""`coadapt train` and `coadapt eval` end to end on Kuafu and MuJoCo (tiny budgets), and their
one-line errors."""

from __future__ import annotations

import json

import pytest

from coadapt_core.cli import main
from coadapt_core.learning.checkpoints import read_checkpoint


@pytest.mark.slow
def test_train_writes_a_checkpoint_that_eval_and_resume_read(tmp_path, capsys) -> None:
    out = tmp_path / "run"
    args = [
        "train",
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
        "--checkpoint-every",
        "1",
        "--quiet",
    ]
    assert main(args) == 0
    lines = [
        json.loads(line) for line in capsys.readouterr().out.splitlines() if line.startswith("{")
    ]
    # one line per iteration, then the walking gate on the policy written
    # (2 iterations: it does not walk)
    gate = lines.pop()["walking_gate"]
    assert [row["iteration"] for row in lines] == [1, 2] and lines[-1]["total_steps"] == 128
    assert gate["walking"] is False and gate["design"] == [1.0, 1.0] and gate["agents"] == 16
    assert gate["tracking_ratio"] > 0.5 or gate["survival"] < 0.8
    assert (out / "model_final.pt").is_file() and (out / "checkpoints" / "model_2.pt").is_file()
    assert (out / "policy.pt").stat().st_size < 6e6
    assert len((out / "progress.jsonl").read_text().splitlines()) == 2
    assert any((out / "logs").glob("events.out.tfevents.*"))  # TensorBoard, a dependency

    code = main(
        [
            "eval",
            "--checkpoint",
            str(out / "model_final.pt"),
            "--design",
            "1.0,1.0",
            "--agents",
            "2",
            "--seconds",
            "0.4",
            "--command",
            "0.5,0,0.3",
            "--json",
        ]
    )
    assert code == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {
        "survival",
        "vx_mean",
        "yaw_rate_mean",
        "tracking_error",
        "torque_cost",
        "power_cost",
    } <= set(result)
    assert result["yaw_rate_command"] == pytest.approx(0.3) and abs(result["yaw_rate_mean"]) < 20.0
    assert (
        0.0 <= result["survival"] <= 1.0 and result["torque_cost"] > 0 and result["steps"] == 2 * 20
    )
    # speeds carry their standard error over the (two) agents: half the gap between them
    assert result["vx_mean_se"] > 0 and result["yaw_rate_mean_se"] > 0

    resumed = tmp_path / "resumed"
    assert (
        main(
            [
                "train",
                "--resume",
                str(out / "model_final.pt"),
                "--steps",
                "64",
                "--out",
                str(resumed),
                "--quiet",
                "--epochs",
                "1",
            ]
        )
        == 0
    )
    rows = [
        json.loads(line) for line in capsys.readouterr().out.splitlines() if line.startswith("{")
    ][:-1]
    assert (
        rows[0]["iteration"] == 3 and rows[-1]["total_steps"] == 192
    )  # 2 designs x 4 agents from the checkpoint


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["train", "--robot", "nope"], "unknown robot 'nope'"),
        (["train", "--sim", "nope"], "unknown simulator 'nope'"),
        (["train", "--designs", "0.5:2.0,0.5:1.5"], "leaves its bounds"),
        (["train", "--designs", "0.5-1.5"], "low:high"),
        (["train", "--steps", "0"], "--steps must be >= 1"),
        (["train", "--device", "tpu"], "--device 'tpu'"),
        (
            ["train", "--resume", "a.pt", "--init-from", "b.pt"],
            "--resume and --init-from exclude each other",
        ),
        (
            ["train", "--reset-pseudo-critics", "--steps", "8"],
            "--reset-pseudo-critics needs --resume or --init-from",
        ),
        (
            ["train", "--pseudo-critics-only", "--steps", "8"],
            "--pseudo-critics-only needs --resume or --init-from",
        ),
        (["eval", "--command", "fast"], "--command 'fast'"),
        (["eval", "--checkpoint", "/no/such.pt"], "does not exist"),
        # --robot given: another test may have left a second robot (the example plugin's) registered
        (
            ["eval", "--robot", "kuafu", "--design", "3,3", "--checkpoint", "x.pt"],
            "outside its bounds",
        ),
        (["eval", "--video", "out.avi", "--checkpoint", "x.pt"], ".gif or .mp4"),
    ],
)
def test_bad_options_give_one_line_and_exit_2(args, message, capsys) -> None:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err


def test_eval_without_checkpoint_says_no_policy_is_shipped(capsys, monkeypatch) -> None:
    # Kuafu ships a policy for every terrain and both spaces; a robot that ships none for
    # slope and the mixed space (as Kuafu did before slope-mixed.pt) gets one line, exit 2
    from coadapt_core.robot import Robot

    shipped = Robot.shipped_policy
    monkeypatch.setattr(
        Robot,
        "shipped_policy",
        lambda self, terrain, mixed=False: (
            None if (terrain, mixed) == ("slope", True) else shipped(self, terrain, mixed)
        ),
    )
    assert main(["eval", "--robot", "kuafu", "--terrain", "slope", "--design", "1,1,1,1"]) == 2
    assert (
        "robot 'kuafu' ships no policy for terrain 'slope' and the mixed design space"
        in capsys.readouterr().err
    )


@pytest.mark.slow
def test_resume_without_robot_takes_the_checkpoints_robot(tmp_path, capsys) -> None:
    """`coadapt train --resume` of a nezha run, the command the interrupted run prints, had
    to be told `--robot nezha` again (refused: 'trained for robot nezha, not kuafu')."""
    small = ["--num-designs", "2", "--agents", "2", "--steps-per-env", "8", "--epochs", "1"]
    small += ["--minibatches", "1", "--quiet", "--logger", "none", "--threads", "1"]
    out = tmp_path / "nezha"
    assert main(["train", "--robot", "nezha", "--steps", "32", "--out", str(out), *small]) == 0
    capsys.readouterr()
    resumed = ["train", "--resume", str(out / "model_final.pt"), "--steps", "32", *small]
    assert main([*resumed, "--out", str(tmp_path / "resumed")]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("training nezha on") + captured.out.count("training nezha on") == 1
    assert read_checkpoint(tmp_path / "resumed" / "model_final.pt")["robot"] == "nezha"
    assert main([*resumed, "--robot", "kuafu", "--out", str(tmp_path / "kuafu")]) == 2
    assert "trained for robot 'nezha', not 'kuafu'" in capsys.readouterr().err
