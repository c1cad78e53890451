"""A robot without a policy for a cell: `coadapt grid --dry-run` marks the cell, the grid and
`coadapt run` refuse it up front in one line (exit 2), before any run folder exists."""

from __future__ import annotations

import pytest

from coadapt_core.cli import main

NO_SLOPE = "robot 'kuafu' ships no policy for terrain 'slope' and the continuous design space"


@pytest.fixture
def no_slope_policy(monkeypatch):
    """Kuafu as a robot that ships a flat policy only (as a new robot's author has it)."""
    from coadapt_core.robot import Robot

    shipped = Robot.shipped_policy
    monkeypatch.setattr(
        Robot,
        "shipped_policy",
        lambda self, terrain, mixed=False: (
            None if terrain == "slope" else shipped(self, terrain, mixed)
        ),
    )


def _grid(tmp_path, *extra: str) -> list[str]:
    return [
        "grid",
        "--robots",
        "kuafu",
        "--methods",
        "ours",
        "--objectives",
        "torque",
        "--terrains",
        "flat,slope",
        "--seeds",
        "0,1",
        "--preset",
        "smoke",
        "--store",
        str(tmp_path / "g.db"),
        "--out",
        str(tmp_path / "runs"),
        *extra,
    ]


def test_grid_dry_run_marks_the_cells_without_a_policy(no_slope_policy, tmp_path, capsys) -> None:
    assert main(_grid(tmp_path, "--dry-run")) == 2
    lines = capsys.readouterr().out.strip().splitlines()
    new = [line for line in lines if line.startswith("new ")]
    refused = [line for line in lines if line.startswith("refuse ")]
    assert len(new) == 2 and all("terrain=flat" in line for line in new)
    assert len(refused) == 2 and all(
        "terrain=slope" in line and NO_SLOPE in line for line in refused
    )
    assert lines[-1].endswith("0 finished, 2 to run, 2 refused (the grid would not start)")
    assert not list((tmp_path / "runs").glob("*/summary.json"))


def test_grid_refuses_a_cell_without_a_policy_before_any_cell_starts(
    no_slope_policy, tmp_path, capsys
) -> None:
    assert main(_grid(tmp_path)) == 2
    err = capsys.readouterr().err.strip()
    assert (
        len(err.splitlines()) == 1
        and "terrain=slope" in err
        and NO_SLOPE in err
        and "nothing was started" in err
    )
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())


@pytest.mark.parametrize("check", [False, True])
def test_run_refuses_a_robot_without_a_policy_in_one_line(
    no_slope_policy, tmp_path, capsys, check
) -> None:
    args = [
        "run",
        "--terrain",
        "slope",
        "--preset",
        "smoke",
        "--store",
        "none",
        "--out",
        str(tmp_path / "runs"),
    ]
    assert main([*args, *(["--check"] if check else [])]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and NO_SLOPE in err and "--checkpoint none" in err
    assert not list(tmp_path.glob("runs/*"))
    # with --checkpoint none the check passes: training from scratch is asked for
    if check:
        assert main([*args, "--check", "--checkpoint", "none"]) == 0
