"""The command line answers without loading torch or a plugin where it needs neither (issue 50):
`coadapt --help`, a command's `--help` page and the refusal of a typo in a choice. Checked
in a fresh interpreter through `sys.modules`, not by timing (benchmarks/cli_startup.py times
the commands); a refused choice names the nearest accepted value."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

PROBE = """
import contextlib, io, json, sys
from coadapt_core.cli import main
err = io.StringIO()
with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(err):
    code = main(sys.argv[1:])
heavy = sorted(m for m in ("torch", "mujoco", "pybullet", "ray", "matplotlib", "sqlalchemy",
                           "coadapt_plugins") if m in sys.modules)
print(json.dumps({"code": code, "heavy": heavy, "out": out.getvalue(), "err": err.getvalue()}))
"""


def _probe(*args: str) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_importing_the_cli_loads_neither_torch_nor_a_plugin():
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, coadapt_core.cli; "
            "print(sorted(m for m in ('torch', 'mujoco', 'coadapt_plugins') if m in sys.modules))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("args", [["--help"], ["report", "--help"], ["export", "--help"]])
def test_help_pages_answer_without_torch_or_plugins(args):
    result = _probe(*args)
    assert result["code"] == 0 and result["heavy"] == []
    assert "Usage: coadapt" in result["out"]


def test_top_level_help_lists_every_command():
    out = _probe("--help")["out"]
    for command in ("run", "plugins", "report", "handoff", "export", "grid"):
        assert f"  {command} " in out, command


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["run", "--preset", "smok"],
            "error: preset 'smok' is not one of smoke, quick, paper; did you mean 'smoke'?",
        ),
        (
            ["export", "-o", "x", "--format", "parket"],
            "error: format 'parket' is not one of csv, parquet; did you mean 'parquet'?",
        ),
        (
            ["report", "--transfer-agents", "0"],
            "error: --transfer-agents, --transfer-steps and --common-blocks must be >= 1",
        ),
    ],
)
def test_a_refusal_is_one_line_exit_2_without_torch(args, line):
    result = _probe(*args)
    assert result["code"] == 2 and result["err"].strip().splitlines() == [line]
    assert "torch" not in result["heavy"] and "coadapt_plugins" not in result["heavy"]


def test_run_help_all_still_lists_the_plugins_aliases():
    """`coadapt run --help-all` makes the aliases the installed plugins declare (the registry
    loads for it): --inertia is an alias of the PSO optimizer's option."""
    result = _probe("run", "--help-all")
    assert result["code"] == 0 and "--inertia" in result["out"]
    assert "coadapt_plugins" in result["heavy"]
