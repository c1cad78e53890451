"""Bad inputs found only after work had begun (issue 43): each is refused in one line, exit 2,
before a run folder, a store row or a long evaluation exists."""

from __future__ import annotations

import time

import pytest
import torch

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from tests.fakes.analytic import AnalyticBackend

RO = "/sys/coadapt-readonly"  # creating anything there fails (EPERM / EROFS), even as root


def _mixed_policy() -> str:
    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", get_registry().default("robot"))
    return str(robot.shipped_policy("flat", True))


CASES = [
    (
        "bo study storage bad://",
        ["--optimizer", "bo", "--bo-storage", "bad://x"],
        "bo_storage 'bad://x'",
    ),
    ("mixed policy on the continuous space", ["--checkpoint", "{MIXED}"], "takes 4 design values"),
    ("cuda without CUDA", ["--device", "cuda"], "no CUDA device"),
]


@pytest.mark.parametrize("args, says", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_run_refuses_before_a_run_folder_or_store_exists(tmp_path, capsys, monkeypatch, args, says):
    if "cuda" in args and torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    monkeypatch.delenv("COADAPT_STORE", raising=False)
    runs = tmp_path / "runs"  # the default store would be runs/../coadapt.db
    argv = [
        "run",
        "--preset",
        "smoke",
        "--out",
        str(runs),
        "--no-video",
        *[a.replace("{MIXED}", _mixed_policy()) for a in args],
    ]
    t0 = time.perf_counter()
    assert main(argv) == 2
    seconds = time.perf_counter() - t0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and says in lines[0], err
    assert "Traceback" not in err
    assert not runs.exists() or not any(runs.iterdir())
    assert not (tmp_path / "coadapt.db").exists()
    assert seconds < 30  # no training phase started


def test_report_to_a_read_only_folder_refuses_before_evaluating(tmp_path, capsys, monkeypatch):
    import coadapt_core.cli.report as report_cli

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )
    db = tmp_path / "s.db"
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--population",
                "4",
                "--optimizer-iterations",
                "2",
                "--out",
                str(tmp_path / "runs"),
                "--store",
                str(db),
                "--no-video",
                "--json",
            ]
        )
        == 0
    )
    evaluated = []
    monkeypatch.setattr(
        report_cli, "_evaluate", lambda *a, **k: evaluated.append(1) or (None, None)
    )
    capsys.readouterr()
    assert main(["report", "--store", str(db), "--no-sim-to-sim", "-o", RO]) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and RO in lines[0], err
    assert evaluated == []  # refused before the yardstick or sim-to-sim evaluation
    # the same report to a folder it can write evaluates (the check is not a refusal of everything)
    assert main(["report", "--store", str(db), "--no-sim-to-sim", "-o", str(tmp_path / "rep")]) == 0
    assert evaluated == [1]


def test_run_check_and_so_a_grid_refuse_a_policy_of_the_other_design_space(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.delenv("COADAPT_STORE", raising=False)
    mixed = _mixed_policy()
    assert (
        main(
            [
                "run",
                "--check",
                "--preset",
                "smoke",
                "--checkpoint",
                mixed,
                "--out",
                str(tmp_path / "runs"),
            ]
        )
        == 2
    )
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "takes 4 design values" in err[0] and "--mixed" in err[0], err
    assert (
        main(
            [
                "run",
                "--check",
                "--preset",
                "smoke",
                "--mixed",
                "--checkpoint",
                mixed,
                "--out",
                str(tmp_path / "runs"),
            ]
        )
        == 0
    )  # the same policy on the mixed space is fine
    capsys.readouterr()
    grid = [
        "grid",
        "--methods",
        "ours",
        "--objectives",
        "torque",
        "--terrains",
        "flat",
        "--seeds",
        "0",
        "--preset",
        "smoke",
        "--store",
        str(tmp_path / "g.db"),
        "--out",
        str(tmp_path / "g"),
        f"--run-arg=--checkpoint={mixed}",
    ]
    assert main(grid) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "takes 4 design values" in err[0], err
    out = tmp_path / "g"
    assert not (out.is_dir() and any(p.name != "grid-logs" for p in out.iterdir()))
