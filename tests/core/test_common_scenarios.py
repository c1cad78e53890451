"""benchmarks/common_scenarios.py --policy run: each run is judged with the policy it handed
back, found by file name inside its own checkpoints/ folder, never by a recorded path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from coadapt_core.errors import UserError
from tests.benchmarks import load_benchmark

ROOT = Path(__file__).resolve().parents[2]


def run_folder(tmp_path: Path, rows: list[dict], files: list[str]) -> Path:
    folder = tmp_path / "20261201-000000-ours-pso-torque-s0-abcdef"
    (folder / "checkpoints").mkdir(parents=True)
    for name in files:
        (folder / "checkpoints" / name).write_bytes(b"x")
    (folder / "checkpoints.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def test_the_last_outer_iteration_policy_is_chosen_by_name(tmp_path):
    rows = [
        {"outer": 0, "path": "/elsewhere/backend-outer0.pt"},
        {"outer": 2, "path": "/moved/backend-outer2.pt"},
        {"outer": 1, "path": "/elsewhere/backend-outer1.pt"},
    ]
    folder = run_folder(
        tmp_path, rows, ["backend-outer0.pt", "backend-outer1.pt", "backend-outer2.pt"]
    )
    assert (
        load_benchmark("common_scenarios")._run_policy(folder)
        == (folder / "checkpoints" / "backend-outer2.pt").resolve()
    )


@pytest.mark.parametrize(
    "rows, files",
    [
        ([], []),  # no checkpoint recorded
        ([{"outer": 0, "path": "backend-outer0.pt"}], []),  # recorded, file missing
        (
            [{"outer": 0, "path": "../../../etc/passwd"}],
            [],
        ),  # a path is never followed: only its name counts
        ([{"outer": "0", "path": 3}], []),  # malformed row
    ],
)
def test_a_run_without_its_policy_is_a_one_line_error(tmp_path, rows, files):
    folder = run_folder(tmp_path, rows, files)
    with pytest.raises(UserError):
        load_benchmark("common_scenarios")._run_policy(folder)


def test_policy_run_refuses_hand_given_designs(capsys):
    assert load_benchmark("common_scenarios").main(["--design", "0.5,0.6", "--policy", "run"]) == 2
    assert "--policy run" in capsys.readouterr().err
