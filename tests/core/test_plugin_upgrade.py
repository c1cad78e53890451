"""Upgrading a plugin package written for plugin API 1.x, which declares no version: every
command that names its robot refuses it in one line (what changed, the migration guide),
exit 2, before a run folder or a store exists; the docs say which version a new plugin
declares and that the robot suite needs PyBullet."""

from __future__ import annotations

import re
from pathlib import Path

from coadapt_core.plugin_api import BREAKING_CHANGES, MIGRATION_DOC, PLUGIN_API_VERSION, current
from tests.conftest import make_dist, run_cli

ROOT = Path(__file__).resolve().parents[2]

#: a robot package as written for plugin API 1.x: no declared version, RobotModel's old fields
OLD_ROBOT = """
import numpy as np

from coadapt_core import hookimpl


@hookimpl
def coadapt_register_robots():
    from coadapt_core.design_space import Continuous, DesignSpace
    from coadapt_core.robot import Robot, RobotModel

    class OldBot(Robot):
        name = "oldbot"

        def design_space(self, mixed=False):
            return DesignSpace([Continuous("leg_scale", 0.5, 1.5)])

        def nominal_design(self, mixed=False):
            return np.array([1.0])

        def build(self, design):
            return RobotModel(mjcf="<mujoco/>", urdf="<robot/>")  # 1.x: fields, not `formats`

        def validate(self, design):
            return True

        def leg_inverse_kinematics(self, *args):
            raise NotImplementedError

        def default_foot_positions(self, design):
            raise NotImplementedError

    return [OldBot]
"""


def test_a_1x_package_declaring_no_version_is_one_line_exit_2_and_no_run_folder(tmp_path):
    site = make_dist(
        tmp_path / "site",
        "oldbot-coadapt",
        "[coadapt]\noldbot-coadapt = oldbot_coadapt\n",
        {"oldbot_coadapt": OLD_ROBOT},
    )
    runs = tmp_path / "work" / "runs"
    done = run_cli(
        "run",
        "--robot",
        "oldbot",
        "--preset",
        "smoke",
        "--out",
        str(runs),
        "--no-video",
        pythonpath=[site],
    )
    assert done.returncode == 2, done.stderr[-2000:]
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, done.stderr
    line = lines[0]
    assert line.startswith("error:") and "Traceback" not in done.stderr
    assert "oldbot-coadapt" in line and "robot 'oldbot'" in line
    assert (
        "declares no plugin API version" in line
        and "plugin API 1.x" in line
        and PLUGIN_API_VERSION in line
    )
    assert MIGRATION_DOC in line and f'COADAPT_PLUGIN_API = "{current()[0]}.{current()[1]}"' in line
    for change in BREAKING_CHANGES[2]:  # every change since 1.x, RobotModel's `formats` included
        assert change in line, change
    assert "`formats`" in line
    # nothing was created: no run folder, no default store beside it
    assert not runs.exists() or not any(runs.iterdir())
    assert not (tmp_path / "work" / "coadapt.db").exists()
    # the robot's own commands say the same
    shown = run_cli("robot", "show", "oldbot", pythonpath=[site])
    assert shown.returncode == 2 and len(shown.stderr.strip().splitlines()) == 1
    assert "declares no plugin API version" in shown.stderr


def test_docs_say_which_version_a_new_plugin_declares_and_that_the_robot_suite_needs_pybullet():
    docs = (ROOT / "docs" / "plugins.md").read_text()
    now = f"{current()[0]}.{current()[1]}"
    declared = set(re.findall(r'COADAPT_PLUGIN_API = "([0-9.]+)"', docs))
    declared |= set(re.findall(r'plugin_api = "([0-9.]+)"', docs))
    assert declared == {now}, declared  # one version wherever a plugin declares one
    assert "declares no plugin API version" in docs and "1.x" in docs
    section9 = docs[docs.index("## 9.") : docs.index("## 10.")]
    assert "PyBullet" in section9 and "pip install" in section9
