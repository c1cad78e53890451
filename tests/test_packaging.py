"""A built wheel carries the plugin data files and the entry points (not only an editable
install): the shipped policy, the mass model, and every built-in plugin's entry point."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_carries_data_and_entry_points(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            str(ROOT),
            "-w",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    wheel = zipfile.ZipFile(next(tmp_path.glob("coadapt-*.whl")))
    names = set(wheel.namelist())
    assert "coadapt_plugins/robots/kuafu/policies/flat.pt" in names
    assert "coadapt_plugins/robots/kuafu/mass_model.json" in names
    assert (
        "coadapt_core/analysis/paper_du2025.json" in names
    )  # the paper's tables, for `coadapt report`
    assert {  # a robot that is only data: its spec, model, README and policy
        "coadapt_plugins/robots/specs/nezha/robot.yaml",
        "coadapt_plugins/robots/specs/nezha/model.xml",
        "coadapt_plugins/robots/specs/nezha/README.md",
        "coadapt_plugins/robots/specs/nezha/policies/flat.pt",
    } <= names
    assert {
        "coadapt_core/dashboard/static/chart.js",
        "coadapt_core/dashboard/static/pages.js",
    } <= names
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    text = wheel.read(entry_points).decode()
    for name in (
        "coadapt.robots.kuafu",
        "coadapt.robots.specs",
        "coadapt.simulators.mujoco",
        "coadapt.optimizers.pso",
        "coadapt.objectives.locomotion",
    ):
        assert name in text
