"""Only a third-party objective installed (the example plugin's `joint-speed`), beside the
built-in robot and its physics: `train`, `eval`, `landscape` and `run` work, taking it as
their objective, because the core names no built-in objective and takes its defaults from
the plugins' declarations (issue 27). Tiny sizes: seconds each."""

from __future__ import annotations

import json
import sys

import pytest

from coadapt_core.plugins import BUILTIN_DISTRIBUTION, load_registry
from tests.conftest import EXAMPLE_PLUGIN

sys.path.insert(0, str(EXAMPLE_PLUGIN))

import coadapt_example


@pytest.fixture
def objective_only(monkeypatch):
    """The process-wide registry with the built-ins' robot, simulators and optimizers, and
    the example plugin's objective as the only objective."""
    import coadapt_core.plugins as plugins

    registry = (
        load_registry()
    )  # the example is found by its entry point once built beside its sources
    if "joint-speed" not in registry.entries["objective"]:
        registry = load_registry(extra_plugins=[(coadapt_example, "coadapt-example")])
    assert not registry.broken, registry.broken
    registry.entries["objective"] = {
        name: info
        for name, info in registry.entries["objective"].items()
        if info.distribution != BUILTIN_DISTRIBUTION
    }
    assert registry.names("objective") == ["joint-speed"]
    monkeypatch.setattr(plugins, "_REGISTRY", registry)
    monkeypatch.delenv("COADAPT_STORE", raising=False)
    return registry


def _json_line(text: str) -> dict:
    return json.loads(text.strip().splitlines()[-1])


def test_run(objective_only, tmp_path, capsys):
    from coadapt_core.cli import main

    code = main(
        [
            "run",
            "--preset",
            "smoke",
            "--population",
            "2",
            "--outer-iterations",
            "1",
            "--optimizer-iterations",
            "1",
            "--agents-per-design",
            "1",
            "--eval-steps",
            "2",
            "--train-steps",
            "10",
            "--retrain-steps",
            "10",
            "--store",
            "none",
            "--out",
            str(tmp_path),
            "--no-video",
            "--json",
        ]
    )
    out = capsys.readouterr()
    assert code == 0, out.err[-2000:]
    line = _json_line(out.out)
    assert line["run_id"] and line["best_design"]
    (folder,) = [p for p in tmp_path.iterdir() if (p / "summary.json").is_file()]
    summary = json.loads((folder / "summary.json").read_text())
    assert (
        list(summary["best_costs"]) == ["joint-speed"] and summary["best_costs"]["joint-speed"] > 0
    )
    assert "objective: joint-speed" in (folder / "config.yaml").read_text()


def test_landscape(objective_only, tmp_path, capsys):
    from coadapt_core.cli import main

    code = main(
        [
            "landscape",
            "--grid",
            "2",
            "--agents",
            "1",
            "--steps",
            "2",
            "--store",
            str(tmp_path / "l.db"),
            "--json",
        ]
    )
    out = capsys.readouterr()
    assert code == 0, out.err[-2000:]
    summary = _json_line(out.out)
    assert summary["run_id"].startswith(tuple("0123456789")) and "joint-speed" in summary["run_id"]
    assert summary["best_cost"] > 0 and summary["nominal_cost"] > 0


def test_train(objective_only, tmp_path, capsys):
    from coadapt_core.cli import main
    from coadapt_core.learning.checkpoints import read_checkpoint

    code = main(
        [
            "train",
            "--steps",
            "64",
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
            str(tmp_path / "t"),
            "--quiet",
        ]
    )
    out = capsys.readouterr()
    assert code == 0, out.err[-2000:]
    assert read_checkpoint(tmp_path / "t" / "model_final.pt")["objectives"] == ["joint-speed"]


def test_eval(objective_only, capsys):
    from coadapt_core.cli import main

    code = main(
        [
            "eval",
            "--robot",
            "kuafu",
            "--agents",
            "2",
            "--seconds",
            "0.2",
            "--objective",
            "joint-speed",
            "--json",
        ]
    )
    out = capsys.readouterr()
    assert code == 0, out.err[-2000:]
    result = _json_line(out.out)
    assert result["costs"]["joint-speed"] > 0 and "survival" in result
    assert not {"tracking_error", "power_cost", "torque_cost"} & set(
        result
    )  # no built-in objective to report


def test_eval_checkpoint_reports_only_installed_objectives(objective_only):
    """The evaluation behind `coadapt eval` (and the run's video): with no objective that
    declares a `summary_key`, only the ones asked for are reported."""
    from coadapt_core.experiments.evaluate import evaluate_checkpoint

    robot = objective_only.get("robot", "kuafu")()
    sim = objective_only.get("simulator", objective_only.default("simulator"))
    result = evaluate_checkpoint(
        robot.shipped_policy("flat", False),
        robot,
        sim,
        robot.nominal_design(),
        terrain="flat",
        command=[0.5, 0.0, 0.0],
        agents=2,
        seconds=0.2,
        objectives=["joint-speed"],
    )
    assert list(result["costs"]) == ["joint-speed"] and result["costs"]["joint-speed"] > 0
    assert not {"tracking_error", "power_cost", "torque_cost"} & set(result)
