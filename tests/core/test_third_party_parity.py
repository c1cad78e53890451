"""A third-party robot, optimizer and objective can do what a built-in can: the example
plugin's `trotter` quadruped ships a policy through the `Robot.shipped_policy` hook (trained
here with `coadapt train`, as docs/plugins.md tells an author), runs `coadapt run --preset
smoke`, takes optimizer options from YAML and the CLI, and a robot without a policy never
yields an unmarked improvement."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.conftest import EXAMPLE_PLUGIN, make_dist, run_cli

sys.path.insert(0, str(EXAMPLE_PLUGIN))

from coadapt_example.robot import Trotter

from coadapt_core.testing import RobotConformance, SimulatorConformance


class TestTrotterRobot(RobotConformance):
    @pytest.fixture
    def robot(self):
        return Trotter()


class TestTrotterOnMujoco(SimulatorConformance):
    @pytest.fixture
    def robot(self):
        return Trotter()

    @pytest.fixture
    def simulator_cls(self):
        from coadapt_core.plugins import get_registry

        return get_registry().get("simulator", "mujoco")


def test_trotter_trots_on_the_gait_clock():
    """Declared legs reach the task: diagonal pairs share a phase, the pairs alternate."""
    import torch

    from coadapt_core.task.gait import expected_stance, leg_phases

    offsets = torch.tensor([leg.phase_offset for leg in Trotter().legs()])
    stance = expected_stance(
        leg_phases(torch.linspace(0, 0.99, 50), 4, offsets)
    )  # [50, 4] FL FR RL RR
    assert torch.equal(stance[:, 0], stance[:, 3]) and torch.equal(stance[:, 1], stance[:, 2])
    assert torch.equal(stance[:, 0], ~stance[:, 1])


@pytest.fixture(scope="module")
def site_with_policy(example_plugin_site, tmp_path_factory) -> Path:
    """The installed example plugin with a policy shipped the documented way: a `coadapt
    train` export copied to `coadapt_example/policies/flat.pt` (a 2-iteration policy: it
    does not walk, which the walking gate must notice)."""
    site = tmp_path_factory.mktemp("site_with_policy")
    shutil.copytree(example_plugin_site, site, dirs_exist_ok=True)
    out = tmp_path_factory.mktemp("trotter_train")
    done = run_cli(
        "train",
        "--robot",
        "trotter",
        "--steps",
        "200",
        "--num-designs",
        "2",
        "--agents",
        "4",
        "--out",
        str(out),
        "--quiet",
        pythonpath=[site],
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    (site / "coadapt_example" / "policies").mkdir()
    shutil.copy(out / "policy.pt", site / "coadapt_example" / "policies" / "flat.pt")
    return site


@pytest.mark.slow
def test_example_robot_smoke_run_with_options_from_yaml_and_cli(site_with_policy, tmp_path):
    config = tmp_path / "run.yaml"
    config.write_text("optimizer: random-search\noptimizer_options:\n  shrink: 0.6\n")
    done = run_cli(
        "run",
        "--robot",
        "trotter",
        "--preset",
        "smoke",
        "--config",
        str(config),
        "--optimizer-option",
        "shrink=0.5",
        "--out",
        str(tmp_path / "runs"),
        "--store",
        "none",
        "--json",
        pythonpath=[site_with_policy],
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    line = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(line["best_design"]) == 2 and np.isfinite(line["improvement"])
    # a 2-iteration policy does not walk: the improvement is there, and marked
    assert line["reliable"] is False and "does not walk" in line["reliability"]
    recorded = yaml.safe_load(next((tmp_path / "runs").glob("*/config.yaml")).read_text())
    assert recorded["robot"] == "trotter"
    assert recorded["optimizer_options"] == {"shrink": 0.5}  # the CLI's, typed, over the YAML's 0.6
    summary = json.loads(next((tmp_path / "runs").glob("*/summary.json")).read_text())
    assert summary["reliable"] is False


@pytest.mark.parametrize("where", ["cli", "yaml"])
def test_bad_optimizer_option_is_one_line_exit_2(example_plugin_site, tmp_path, where):
    args = [
        "run",
        "--robot",
        "trotter",
        "--optimizer",
        "random-search",
        "--preset",
        "smoke",
        "--out",
        str(tmp_path),
    ]
    if where == "cli":
        args += ["--optimizer-option", "shrink=5"]
    else:
        (tmp_path / "c.yaml").write_text("optimizer_options: {shrink: 5}\n")
        args += ["--config", str(tmp_path / "c.yaml")]
    done = run_cli(*args, pythonpath=[example_plugin_site])
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "error: optimizer 'random-search' option 'shrink' must be a finite number "
        "in [0.01, 1], got " + ("'5'" if where == "cli" else "5")
    ]
    unknown = run_cli(
        "run",
        "--robot",
        "trotter",
        "--optimizer",
        "random-search",
        "--optimizer-option",
        "sigma=1",
        "--out",
        str(tmp_path),
        pythonpath=[example_plugin_site],
    )
    assert (
        unknown.returncode == 2 and "has no option 'sigma'; its options: shrink" in unknown.stderr
    )


def test_plugins_json_lists_declared_options(example_plugin_site):
    done = run_cli("plugins", "--json", pythonpath=[example_plugin_site])
    data = json.loads(done.stdout)
    search = next(p for p in data["plugins"]["optimizer"] if p["name"] == "random-search")
    assert search["options"] == [
        {
            "name": "shrink",
            "type": "float",
            "default": 0.7,
            "help": "box half-width factor per round",
            "choices": None,
            "minimum": 0.01,
            "maximum": 1.0,
        }
    ]
    pso = next(p for p in data["plugins"]["optimizer"] if p["name"] == "pso")
    assert [o["name"] for o in pso["options"]] == ["inertia", "c1", "c2", "max_velocity_rate"]
    assert any(p["name"] == "trotter" for p in data["plugins"]["robot"])


def test_robot_without_policy_stops_with_how_to_train_one(example_plugin_site, tmp_path):
    """No shipped policy for the terrain: the first (and only) line says so and how to get
    one; nothing is trained, no run summary is written."""
    done = run_cli(
        "run",
        "--robot",
        "trotter",
        "--terrain",
        "slope",
        "--preset",
        "smoke",
        "--out",
        str(tmp_path),
        pythonpath=[example_plugin_site],
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: robot 'trotter' ships no policy for terrain 'slope'")
    assert (
        "coadapt train --robot trotter --terrain slope" in lines[0]
        and "--checkpoint none" in lines[0]
    )
    assert not list(tmp_path.glob("*/summary.json"))


@pytest.mark.slow
def test_robot_trained_from_scratch_in_the_run_is_marked_unreliable(example_plugin_site, tmp_path):
    done = run_cli(
        "run",
        "--robot",
        "trotter",
        "--terrain",
        "slope",
        "--preset",
        "smoke",
        "--checkpoint",
        "none",
        "--population",
        "2",
        "--outer-iterations",
        "1",
        "--optimizer-iterations",
        "1",
        "--out",
        str(tmp_path),
        "--store",
        "none",
        "--json",
        pythonpath=[example_plugin_site],
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stderr.splitlines()[0].startswith(
        "note: no starting policy (--checkpoint none): robot 'trotter'"
    )
    line = json.loads(done.stdout.strip().splitlines()[-1])
    assert line["reliable"] is False and "does not walk" in line["reliability"]


def test_failed_plugin_is_named_where_it_would_have_been_used(tmp_path):
    site = make_dist(
        tmp_path / "site",
        "coadapt-quadbot",
        "[coadapt]\ncoadapt-quadbot = quadbot_plugin\n",
        {"quadbot_plugin": "import no_such_dependency_xyz\n"},
    )
    done = run_cli("run", "--robot", "quadbot", "--out", str(tmp_path / "runs"), pythonpath=[site])
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    error = [line for line in lines if line.startswith("error:")]
    assert len(error) == 1
    assert "unknown robot 'quadbot'" in error[0]
    assert (
        "plugin 'coadapt-quadbot' (distribution coadapt-quadbot) failed to load: "
        "ModuleNotFoundError" in error[0]
    )
    assert "no_such_dependency_xyz" in error[0]


@pytest.mark.slow
def test_eval_takes_the_robot_from_the_checkpoint(site_with_policy):
    policy = site_with_policy / "coadapt_example" / "policies" / "flat.pt"
    done = run_cli(
        "eval",
        "--checkpoint",
        str(policy),
        "--agents",
        "2",
        "--seconds",
        "0.4",
        "--json",
        pythonpath=[site_with_policy],
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["robot"] == "trotter" and result["design"] == [1.0, 1.0]  # no --robot given
    assert "survival" in result


def test_report_rows_mark_runs_below_the_walking_gate(tmp_path):
    from coadapt_core.analysis.report import write_report
    from tests.core.test_report import SqliteRecorder, read_csv, record_run

    rec = SqliteRecorder(tmp_path / "r.db")
    ids = [record_run(rec, "ours", seed) for seed in (0, 1)]
    summary = rec.store.get_run(ids[1])["summary"]
    rec.finish(
        ids[1],
        {
            **summary,
            "reliable": False,
            "reliability": "the policy does not walk (survival 0.40 < 0.8)",
        },
    )
    files = write_report(rec.store, None, tmp_path / "rep", sim2sim=False)
    row = read_csv(files["table6.csv"])[0]
    assert int(row["unreliable_runs"]) == 1 and "survival 0.40" in row["reliability"]
    assert "UNRELIABLE (1 of 2 runs: the policy does not walk)" in files["table6.md"].read_text()
    assert "UNRELIABLE (1 of 2 runs" in files["report.html"].read_text()


def test_option_text_from_the_cli_is_typed_in_the_config():
    """'--optimizer-option inertia=0.5' and YAML 'inertia: 0.5' make the same config (and
    the same grid config hash); a legacy key is an alias."""
    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.experiments.cell_hash import config_hash

    cli = make_config("smoke", None, {"optimizer_options": {"inertia": "0.5"}})
    legacy = make_config("smoke", None, {"inertia": 0.5})
    assert cli.optimizer_options == legacy.optimizer_options == {"inertia": 0.5}
    assert config_hash(cli.to_dict()) == config_hash(legacy.to_dict())


def test_validation_report_to_dict_is_json_even_with_numpy_values():
    """`coadapt robot show --json` writes `to_dict()`: numpy bools and floats from a plugin's
    checks must not crash it (the suite also asks plugins for plain values)."""
    from coadapt_core.robot import Finding, ValidationReport

    report = ValidationReport(
        np.array([1.0, 1.0]),
        [
            Finding("a", np.bool_(True), "m", np.float32(0.5), np.float64(1.0)),
            Finding("b", np.bool_(False), "n"),
        ],
    )
    data = json.loads(json.dumps(report.to_dict()))
    assert data["feasible"] is False and data["findings"][0] == {
        "check": "a",
        "ok": True,
        "message": "m",
        "value": 0.5,
        "limit": 1.0,
    }


@pytest.mark.slow
def test_grid_over_two_robots_reports_one_row_per_robot(site_with_policy, tmp_path):
    """`coadapt grid --robots kuafu,trotter ... --preset smoke` then `coadapt report`: one
    row per robot, never averaged together; the cell key names the robot, and each run
    records the policy its robot ships (name and SHA-256)."""
    import hashlib

    from coadapt_core.results.store import ResultsStore

    store = tmp_path / "grid.db"
    done = run_cli(
        "grid",
        "--robots",
        "kuafu,trotter",
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
        "--workers",
        "2",
        "--store",
        str(store),
        "--run-arg=--population=2",
        "--run-arg=--outer-iterations=1",
        "--run-arg=--optimizer-iterations=1",
        "--run-arg=--no-video",
        "--out",
        str(tmp_path / "runs"),
        "--json",
        pythonpath=[site_with_policy],
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    grid = json.loads(done.stdout.strip().splitlines()[-1])
    assert sorted(k.split("|")[0] for k in grid["finished"]) == ["robot=kuafu", "robot=trotter"]
    report = run_cli(
        "report",
        grid["grid_id"],
        "--store",
        str(store),
        "--no-sim-to-sim",
        "-o",
        str(tmp_path / "rep"),
        pythonpath=[site_with_policy],
        timeout=300,
    )
    assert report.returncode == 0, report.stderr[-2000:]
    import csv

    with open(tmp_path / "rep" / "table6.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted((r["robot"], r["runs"]) for r in rows) == [("kuafu", "1"), ("trotter", "1")]
    shipped = site_with_policy / "coadapt_example" / "policies" / "flat.pt"
    trotter = next(r for r in rows if r["robot"] == "trotter")
    assert trotter["policy"] == f"flat.pt ({hashlib.sha256(shipped.read_bytes()).hexdigest()[:12]})"
    with ResultsStore(store) as results:
        runs = {r["robot"]: r for r in results.list_runs(grid_id=grid["grid_id"])}
    assert runs["kuafu"]["config"]["policy"]["source"] == "shipped"
    assert (
        runs["kuafu"]["config"]["policy"]["file"] == "flat.pt"
        and len(runs["kuafu"]["config"]["policy"]["sha256"]) == 64
    )
    assert runs["trotter"]["cell"].startswith("robot=trotter|")


@pytest.mark.slow
def test_eval_evaluates_a_plugin_objective_with_its_standard_error(site_with_policy):
    """`coadapt eval --objective joint-speed --json`: the example plugin's objective, its cost
    per step and standard error over the agents; a built-in asked for the same way matches
    the built-in column."""
    policy = site_with_policy / "coadapt_example" / "policies" / "flat.pt"
    done = run_cli(
        "eval",
        "--checkpoint",
        str(policy),
        "--agents",
        "4",
        "--seconds",
        "0.4",
        "--json",
        "--objective",
        "joint-speed",
        "--objective",
        "torque",
        pythonpath=[site_with_policy],
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert list(result["costs"]) == ["joint-speed", "torque"]
    assert np.isfinite(result["costs"]["joint-speed"]) and result["costs"]["joint-speed"] > 0
    assert (
        np.isfinite(result["costs_se"]["joint-speed"]) and result["costs_se"]["joint-speed"] > 0
    )  # 4 agents differ
    assert result["costs"]["torque"] == pytest.approx(result["torque_cost"])
    assert result["costs_se"]["torque"] == pytest.approx(result["torque_cost_se"])


def test_eval_of_an_unknown_objective_is_one_line(example_plugin_site):
    done = run_cli(
        "eval",
        "--robot",
        "trotter",
        "--objective",
        "joint-sped",
        "--json",
        pythonpath=[example_plugin_site],
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert (
        len(lines) == 1
        and "unknown objective 'joint-sped'" in lines[0]
        and "joint-speed" in lines[0]
    )
