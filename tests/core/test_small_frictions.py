"""Small things a new user read wrong (issue 43, item 10): `coadapt robot show` without a robot,
one `error:` prefix for every error, `run --help` naming the default preset, the video's
panel label, whole-number round ticks on surrogate_quality.png, and no PyBullet banner from
its worker processes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from coadapt_core.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_robot_show_needs_no_robot_argument(capsys):
    assert main(["robot", "show", "--json", "--no-validate"]) == 0
    shown = json.loads(capsys.readouterr().out)
    from coadapt_core.plugins import get_registry

    assert shown["robot"] == get_registry().default("robot")
    assert shown["design"] == {"thigh_scale": 1.0, "shank_scale": 1.0} or shown["robot"] != "kuafu"


@pytest.mark.parametrize("argv", [["run", "--bogus"], ["export"], ["robot", "show", "--design"]])
def test_every_usage_error_starts_with_error_colon(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err, err
    assert "error (" not in err


def test_run_help_names_the_default_preset(capsys):
    assert main(["run", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    preset = text.split("--preset <str>", 1)[1].split(" --", 1)[0]
    assert "One of: smoke, quick, paper. [default: quick]" in preset


def test_the_video_label_keeps_its_space():
    from coadapt_core.viz.video import panel_label

    assert panel_label("best", [0.53, 0.6912], 0.4512) == "best: 0.53, 0.69 | vx 0.45 m/s"
    assert panel_label("nominal", [1.0, 1.0, 2.0, 3.0], 0.5) == "nominal: 1, 1, 2, 3 | vx 0.50 m/s"


def test_surrogate_quality_ticks_are_whole_rounds(tmp_path, monkeypatch):
    """Two eligible rounds used to get ticks at 1.25 and 1.75."""
    import coadapt_core.analysis.surrogate_figure as figure

    rounds = [{"eligible": True, "objectives": {"power": {"spearman": rho}}} for rho in (0.6, 0.14)]
    run = {
        "seed": 0,
        "summary": {
            "surrogate_quality": {"by_objective": {"power": {"spearman": 0.45}}, "rounds": rounds}
        },
    }
    kept = {}

    def keep(plt, fig, path, caption):
        kept["ticks"] = [
            t
            for ax in fig.axes
            for t in ax.get_xticks()
            if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]
        ]
        plt.close(fig)
        return [(path, caption)]

    monkeypatch.setattr(figure, "save_figure", keep)
    figure.figure_surrogate_quality(
        [SimpleNamespace(run=run, terrain="flat", method="ours")], tmp_path
    )
    assert kept["ticks"] == [1.0, 2.0]
    # a run with no judged round: ticks still on whole rounds (were -0.05 ... 0.05)
    run["summary"]["surrogate_quality"]["rounds"] = []
    figure.figure_surrogate_quality(
        [SimpleNamespace(run=run, terrain="flat", method="ours")], tmp_path
    )
    assert kept["ticks"] == [1.0]


@pytest.mark.slow
def test_pybullet_workers_print_no_banner():
    """A batch large enough for worker processes: stderr holds no 'pybullet build time' (it
    came once per worker, into the progress line of `coadapt report` and `coadapt handoff`)."""
    script = (
        "import numpy as np\n"
        "from coadapt_core.cli.report import _quiet_imports\n"
        "_quiet_imports(('pybullet',))\n"
        "from coadapt_plugins.simulators.pybullet import PyBulletSimulator\n"
        "from coadapt_core.plugins import get_registry\n"
        "robot = get_registry().create('robot', 'kuafu')\n"
        "with PyBulletSimulator(robot, np.ones((2, 2)), processes=2) as sim:\n"
        "    assert len(sim.worker_pids()) == 2\n"
        "    sim.step(sim.default_joint_pos)\n"
        "print('stepped')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    assert done.returncode == 0 and "stepped" in done.stdout, done.stderr[-2000:]
    assert "pybullet build time" not in done.stderr + done.stdout
