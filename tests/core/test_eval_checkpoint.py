"""`coadapt eval --checkpoint` (issue 43): a `coadapt run` folder or run id stands for the run's
last policy; `none` and a folder without a policy say what is accepted; eval's costs say
their protocol."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from coadapt_core.cli import main

SHIPPED = (
    Path(__file__).resolve().parents[2] / "plugins" / "robots" / "kuafu" / "policies" / "flat.pt"
)
RUN_ID = "20261203-091311-ours-pso-torque-s0-abc123"


@pytest.fixture
def run_folder(tmp_path, monkeypatch) -> Path:
    """./runs/<run id> as `coadapt run` leaves it: config.yaml and a checkpoint per outer
    iteration (here the shipped policy, the last one marked by its name)."""
    monkeypatch.chdir(tmp_path)
    run_dir = tmp_path / "runs" / RUN_ID
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "config.yaml").write_text("robot: kuafu\nterrain: flat\ncheckpoint: ''\n")
    for outer in range(3):
        shutil.copy(SHIPPED, run_dir / "checkpoints" / f"backend-outer{outer}.pt")
    return run_dir


@pytest.mark.parametrize("given", ["none", "None"])
def test_checkpoint_none_says_what_is_accepted(capsys, given):
    assert main(["eval", "--checkpoint", given]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(
        f"error: --checkpoint {given}: coadapt eval needs a policy"
    )
    for accepted in (
        "checkpoint file",
        "`coadapt train`",
        "`coadapt run` folder or run id",
        "shipped policy",
    ):
        assert accepted in err


def test_a_run_folder_without_a_policy_says_what_is_accepted(run_folder, capsys):
    for stale in (run_folder / "checkpoints").iterdir():
        stale.unlink()
    (run_folder / "config.yaml").write_text("robot: kuafu\ncheckpoint: none\n")
    assert main(["eval", "--checkpoint", str(run_folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "holds no policy" in err and "run id" in err


@pytest.mark.parametrize("by", ["folder", "id"])
def test_a_run_folder_or_id_is_its_last_checkpoint(run_folder, capsys, by):
    given = str(run_folder) if by == "folder" else RUN_ID
    assert main(["eval", "--checkpoint", given, "--agents", "2", "--seconds", "0.2", "--json"]) == 0
    captured = capsys.readouterr()
    assert (
        f"policy: {Path('runs') / RUN_ID / 'checkpoints' / 'backend-outer2.pt'}" in captured.err
        or f"policy: {run_folder / 'checkpoints' / 'backend-outer2.pt'}" in captured.err
    )
    result = json.loads(captured.out.strip().splitlines()[-1])
    assert result["robot"] == "kuafu" and result["steps"] == 2 * 10 and result["torque_cost"] > 0


def test_every_cost_eval_prints_says_eval(run_folder, capsys):
    assert (
        main(
            [
                "eval",
                "--checkpoint",
                RUN_ID,
                "--agents",
                "2",
                "--seconds",
                "0.2",
                "--objective",
                "power",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert out.lstrip().startswith("coadapt eval: kuafu design")
    rows = [
        line
        for line in out.splitlines()
        if "cost" in line and "│" in line and "cost_rule" not in line
    ]
    assert len(rows) >= 5 and all("(eval" in row for row in rows), (
        rows
    )  # power/torque cost, SEs, per-step rows
    assert "`coadapt eval` protocol" in " ".join(out.split())
