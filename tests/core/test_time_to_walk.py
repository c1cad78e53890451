"""benchmarks/time_to_walk.py on real MuJoCo at a tiny size: the checks do not change what the
training draws, the budgets stop it, `--out` keeps each check's checkpoint, and the corners
are the design range's (`coadapt_core.experiments.walking_check`, which `coadapt train
--until-walks` shares: tests/core/test_train_until_walks.py)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from tests.benchmarks import load_benchmark

TINY = [
    "--robot",
    "qilin",
    "--num-designs",
    "2",
    "--agents",
    "4",
    "--steps-per-env",
    "8",
    "--eval-agents",
    "2",
    "--eval-seconds",
    "0.5",
    "--threads",
    "1",
]


def _run(monkeypatch, capsys, *extra: str) -> dict:
    bench = load_benchmark("time_to_walk")
    monkeypatch.setattr(sys, "argv", ["time_to_walk.py", *TINY, *extra])
    bench.main()
    captured = capsys.readouterr()
    rows = [json.loads(line) for line in captured.err.splitlines() if line.startswith("{")]
    return {"result": json.loads(captured.out), "rows": rows}


def test_checks_leave_the_training_as_it_was_and_out_keeps_each_checkpoint(
    monkeypatch, capsys, tmp_path
):
    every = _run(
        monkeypatch, capsys, "--max-steps", "192", "--eval-every", "1", "--out", str(tmp_path)
    )
    once = _run(monkeypatch, capsys, "--max-steps", "192", "--eval-every", "3")
    # 2 designs x 4 agents x 8 steps = 64 interactions an iteration, 3 iterations
    assert [r["interactions"] for r in every["rows"]] == [64, 128, 192]
    assert [r["interactions"] for r in once["rows"]] == [192]
    # the same training with three checks as with one: the last iteration's reward is equal
    assert every["rows"][-1]["mean_reward"] == once["rows"][-1]["mean_reward"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["check_1.pt", "check_2.pt", "check_3.pt"]
    result = every["result"]
    assert result["interactions"] == 192 and result["num_envs"] == 8
    # a policy of 3 updates does not walk: the gate says so at all five designs
    assert result["walked"] is False and result["interactions_to_walk"] is None
    assert set(every["rows"][-1]["designs"]) == {
        "nominal",
        "lower",
        "upper",
        "alternate",
        "alternate_mirror",
    }
    # the new-robot recipe's 2 epochs under the options given (2 designs)
    assert result["train_config"]["epochs"] == 2 and result["train_config"]["num_designs"] == 2


def test_the_wall_clock_budget_stops_after_the_first_check(monkeypatch, capsys):
    out = _run(
        monkeypatch,
        capsys,
        *("--max-steps", "640", "--eval-every", "1", "--max-seconds", "0.001"),
        *("--start", "defaults"),
    )
    assert len(out["rows"]) == 1 and out["result"]["interactions"] == 64
    # TrainConfig's defaults (5 epochs, 4 minibatches) under the options given
    assert out["result"]["train_config"]["epochs"] == 5


def test_corners_are_the_ranges_ends_and_their_two_alternations():
    from coadapt_core.experiments.walking_check import corners

    class Space:
        lower, upper = [0.5, 0.7, 1.0], [1.5, 1.3, 2.0]

    got = corners(Space())
    np.testing.assert_array_equal(got["lower"], [0.5, 0.7, 1.0])
    np.testing.assert_array_equal(got["upper"], [1.5, 1.3, 2.0])
    np.testing.assert_array_equal(got["alternate"], [0.5, 1.3, 1.0])
    np.testing.assert_array_equal(got["alternate_mirror"], [1.5, 0.7, 2.0])


@pytest.fixture(autouse=True)
def _restore_threads():
    import torch

    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
