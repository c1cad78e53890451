"""`coadapt grid --executor ray` on a real Ray cluster of this machine whose worker nodes share
no disk with the driver: a head node (0 CPUs: no cell runs there) and two worker nodes, each
started in a mount namespace with an empty tmpfs over /tmp (the driver's test folders, its
store and --out are not there; the nodes' scratch folders are not visible to the driver) and
a PID namespace (removing a node ends every process of it). Every Ray process talks over
127.0.0.1 only, with token authentication (RAY_AUTH_MODE=token, RAY_AUTH_TOKEN)."""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import re
import secrets
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from coadapt_core.cli import main
from coadapt_core.results import ResultsStore
from tests.core.ray_cluster import FAST_HEALTH, Cluster

ROOT = Path(__file__).resolve().parents[2]

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'coadapt[ray]')")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        os.geteuid() != 0 or shutil.which("unshare") is None,
        reason="worker nodes without the driver's files need root and unshare",
    ),
]

#: a smoke run made small (about 5 s of work on one core here)
TINY = [
    "--population",
    "3",
    "--agents-per-design",
    "2",
    "--eval-steps",
    "10",
    "--train-steps",
    "64",
    "--retrain-steps",
    "32",
    "--outer-iterations",
    "1",
    "--optimizer-iterations",
    "2",
    "--bo-designs",
    "2",
    "--specialized-train-steps",
    "32",
    "--no-video",
]


@pytest.fixture(scope="module")
def cluster():
    auth = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS", "COADAPT_STORE")}
    env.update(auth, **FAST_HEALTH, RAY_USAGE_STATS_ENABLED="0", PYTHONPATH=str(ROOT))
    started = time.perf_counter()
    c = Cluster(env)
    try:
        c.add_worker()
        c.add_worker()
        c.wait_workers(2)
        print(f"cluster of a head and 2 worker nodes up in {time.perf_counter() - started:.1f} s")
        yield c
    finally:
        c.stop()


def _grid_command(root: Path, cluster: Cluster, *args: str, address: bool = True) -> list[str]:
    """`coadapt grid --executor ray` run by a driver in the cluster's network namespace (the
    cluster named by --address, else by RAY_ADDRESS in its environment)."""
    return cluster.in_net(
        [
            sys.executable,
            "-m",
            "coadapt_core",
            "grid",
            "--robots",
            "kuafu",
            "--objectives",
            "torque",
            "--terrains",
            "flat",
            "--preset",
            "smoke",
            "--sim",
            "mujoco",
            "--executor",
            "ray",
            *(["--address", cluster.address] if address else []),
            "--store",
            str(root / "g.db"),
            "--out",
            str(root / "runs"),
            *(f"--run-arg={a}" for a in TINY),
            *args,
        ]
    )


def test_grid_on_a_cluster_without_a_shared_disk(cluster, tmp_path, capsys):
    started = time.perf_counter()
    done = subprocess.run(
        _grid_command(
            tmp_path, cluster, "--methods", "ours,no-surrogate", "--seeds", "0,1", "--json"
        ),
        env=cluster.env,
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    grid_seconds = time.perf_counter() - started
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(summary["finished"]) == 4 and not summary["failed"] and not summary["ran_again"]
    store = ResultsStore(tmp_path / "g.db")
    runs = store.list_runs(grid_id=summary["grid_id"])
    assert len(runs) == 4 and {r["status"] for r in runs} == {"finished"}
    assert {c["status"] for c in store.cells(summary["grid_id"]).values()} == {"finished"}
    _check_run_folders(store, runs, tmp_path)
    logs = sorted((tmp_path / "runs" / "grid-logs" / summary["grid_id"]).glob("*.log"))
    assert len(logs) == 4 and all("attempt 1 on node 127.0.0.1" in p.read_text() for p in logs)
    scratch = re.findall(r"scratch (\S+) \(removed\)", "".join(p.read_text() for p in logs))
    assert len(set(scratch)) == 4 and not any(Path(s).exists() for s in scratch)
    assert cluster.scratch_left() == 0  # removed on the nodes too
    print(f"4-cell grid on 2 worker nodes: {grid_seconds:.1f} s; {len(runs)} runs in its store")
    _check_report(summary["grid_id"], tmp_path, capsys)
    _check_handoff(runs[0]["id"], tmp_path, capsys)


def _check_run_folders(store: ResultsStore, runs: list[dict], tmp_path: Path) -> None:
    """Each run's folder under the driver's --out, its rows naming it; the evaluation buffer
    stays behind on the node."""
    for run in runs:
        folder = tmp_path / "runs" / run["id"]
        assert Path(run["run_dir"]) == folder.resolve()
        assert (folder / "summary.json").is_file() and (folder / "state.json").is_file()
        assert (folder / "config.yaml").is_file() and (folder / "evaluations.jsonl").is_file()
        assert not list(folder.glob("buffer-*.npz"))  # the evaluation buffer stays behind
        (checkpoint,) = store.checkpoints(run["id"])
        assert Path(checkpoint["path"]).parent == folder.resolve() / "checkpoints"
        assert Path(checkpoint["path"]).is_file()
        state = json.loads((folder / "state.json").read_text())
        assert state["config"]["store"] == store.url and state["config"]["out"] == str(
            tmp_path / "runs"
        )
        assert store.count_evaluations(run["id"], "real") > 0


def _check_report(grid_id: str, tmp_path: Path, capsys) -> None:
    """The report (sim-to-sim and common-scenario rows) from the driver alone."""
    started = time.perf_counter()
    assert (
        main(
            [
                "report",
                grid_id,
                "--store",
                str(tmp_path / "g.db"),
                "-o",
                str(tmp_path / "report"),
                "--transfer-agents",
                "2",
                "--transfer-steps",
                "20",
                "--common-blocks",
                "1",
            ]
        )
        == 0
    ), capsys.readouterr().err
    print(f"report: {time.perf_counter() - started:.1f} s")
    with (tmp_path / "report" / "table6.csv").open() as fh:
        rows = {r["method"]: r for r in csv.DictReader(fh)}
    assert set(rows) == {"ours", "no-surrogate"}
    for (
        row
    ) in rows.values():  # each method's two runs, moved to PyBullet and on the common scenarios
        assert (
            row["runs"] == "2"
            and row["sim2sim_improvement_n"] == "2"
            and row["common_improvement_n"] == "2"
        )
        assert math.isfinite(float(row["sim2sim_improvement"])) and math.isfinite(
            float(row["common_improvement"])
        )
        print(
            f"{row['method']}: improvement {float(row['improvement']):.3f} +- "
            f"{float(row['improvement_se']):.3f}, "
            f"sim-to-sim {float(row['sim2sim_improvement']):.3f}, common "
            f"{float(row['common_improvement']):.3f} "
            f"+- {float(row['common_improvement_se']):.3f}"
        )


def _check_handoff(run_id: str, tmp_path: Path, capsys) -> None:
    """A handoff of one of the grid's runs from the driver alone."""
    assert (
        main(
            [
                "handoff",
                run_id,
                "--runs-dir",
                str(tmp_path / "runs"),
                "-o",
                str(tmp_path / "handoff"),
                "--sim",
                "mujoco",
                "--agents",
                "2",
                "--seconds",
                "0.1",
                "--no-check",
                "--no-video",
            ]
        )
        == 0
    ), capsys.readouterr().err
    assert (tmp_path / "handoff" / "design.json").is_file()


def test_a_cell_lost_with_its_node_runs_again_from_its_last_state(cluster, tmp_path):
    longer = [
        "--run-arg=--outer-iterations",
        "--run-arg=2",
    ]  # the state sent back after outer 0 holds evaluations
    grid = subprocess.Popen(
        _grid_command(
            tmp_path,
            cluster,
            "--methods",
            "ours",
            "--seeds",
            "0,1",
            "--json",
            "--state-every",
            "1",
            *longer,
            address=False,
        ),
        env={**cluster.env, "RAY_ADDRESS": cluster.address},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    started = time.perf_counter()
    try:
        lost, sent = _remove_a_busy_node(cluster, tmp_path, grid)
        out, err = grid.communicate(timeout=600)
    finally:
        if grid.poll() is None:
            grid.kill()
        if len(cluster.workers) < 2:
            cluster.add_worker()  # two worker nodes for whichever test runs next
    seconds = time.perf_counter() - started
    assert grid.returncode == 0, err[-3000:]
    summary = json.loads(out.strip().splitlines()[-1])
    assert (
        len(summary["finished"]) == 2 and not summary["failed"] and summary["ran_again"] == [lost]
    )
    (line,) = [ln for ln in err.splitlines() if ln.startswith("ran again")]
    assert (
        line.startswith(f"ran again {lost}: lost with its node")
        and f"resuming run {sent['id']}" in line
    )
    store = ResultsStore(tmp_path / "g.db")
    runs = {r["cell"]: r for r in store.list_runs(grid_id=summary["grid_id"])}
    assert len(runs) == 2 and {r["status"] for r in runs.values()} == {"finished"}
    assert runs[lost]["id"] == sent["id"]  # the same run, continued from the state it had sent
    assert store.cells(summary["grid_id"])[lost]["attempts"] == 2
    # nothing lost or done twice: the resumed run evaluated as many designs as the other cell's
    counts = {cell: store.count_evaluations(r["id"]) for cell, r in runs.items()}
    assert (
        counts[lost]
        == next(c for cell, c in counts.items() if cell != lost)
        > sent["evaluations"]
        > 0
    )
    log = next(
        (tmp_path / "runs" / "grid-logs" / summary["grid_id"]).glob(
            "*seed-0*" if "seed=0" in lost else "*seed-1*"
        )
    ).read_text()
    assert "# attempt 2 on node 127.0.0.1" in log
    print(
        f"2-cell grid, {lost} lost with its node after {sent['evaluations']} evaluations had been "
        "sent back, "
        f"resumed elsewhere: {seconds:.1f} s; evaluations per run {sorted(counts.values())}"
    )


def _remove_a_busy_node(cluster: Cluster, root: Path, grid: subprocess.Popen) -> tuple[str, dict]:
    """Once a running cell has sent back a state with evaluations in it, remove the node it
    runs on; returns (its cell, what the driver held of its run then)."""
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and grid.poll() is None:
        time.sleep(0.2)
        if not (root / "g.db").is_file():
            continue
        with contextlib.suppress(Exception), ResultsStore(root / "g.db") as store:
            for run in store.list_runs(status="running"):
                held = store.count_evaluations(run["id"])
                if held and (root / "runs" / run["id"] / "state.json").is_file():
                    node = cluster.node_running(run["cell"])
                    if node is not None:
                        cluster.remove_worker(node)
                        cluster.add_worker()  # a fresh node joins, as an autoscaler would bring one
                        return run["cell"], {"id": run["id"], "evaluations": held}
    raise AssertionError("no running cell sent back a state before the grid ended")


def test_a_cell_no_node_can_hold_fails_in_one_line(cluster, tmp_path):
    done = subprocess.run(
        _grid_command(tmp_path, cluster, "--methods", "ours", "--seeds", "0", "--threads", "2"),
        env=cluster.env,
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert done.returncode == 1
    assert (
        "the cell reserves 2 CPUs (--threads) and the largest node of the cluster has 1; give "
        "--threads <= 1" in " ".join(done.stderr.split())
    )
    assert not ResultsStore(tmp_path / "g.db").list_runs()  # nothing ran


def _spec_grid(cluster: Cluster, tmp_path: Path, robot: str, env: dict) -> dict:
    """A one-cell grid over `robot` (from scratch: --checkpoint none) on the cluster."""
    argv = _grid_command(tmp_path, cluster, "--methods", "ours", "--seeds", "0", "--json")
    argv[argv.index("kuafu")] = robot
    done = subprocess.run(
        [*argv, "--run-arg=--checkpoint=none"],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    return {"done": done, "summary": json.loads(done.stdout.strip().splitlines()[-1])}


def test_a_grid_over_a_spec_robot_runs_on_the_cluster(cluster, tmp_path):
    """nezha, the robot that is only a spec and a model file, runs as a grid cell on a node
    that shares no disk with the driver; its rows reach the driver's store."""
    result = _spec_grid(cluster, tmp_path, "nezha", cluster.env)
    done, summary = result["done"], result["summary"]
    assert done.returncode == 0, done.stderr[-3000:]
    assert len(summary["finished"]) == 1 and not summary["failed"]
    store = ResultsStore(tmp_path / "g.db")
    (run,) = store.list_runs(grid_id=summary["grid_id"])
    assert run["robot"] == "nezha" and run["status"] == "finished"
    assert store.count_evaluations(run["id"], "real") > 0


def test_a_node_without_a_users_spec_robot_refuses_its_cell(cluster, tmp_path):
    """A spec robot found on the driver's COADAPT_ROBOT_PATH is part of its plugin set: a node
    that cannot read that folder refuses the cell in one line naming the robot."""
    robots = tmp_path / "robots"
    shutil.copytree(
        ROOT / "plugins" / "robots" / "specs" / "nezha",
        robots / "mine",
        ignore=shutil.ignore_patterns("policies", "README.md"),
    )
    spec = robots / "mine" / "robot.yaml"
    spec.write_text(spec.read_text().replace("name: nezha", "name: mine"))
    env = {**cluster.env, "COADAPT_ROBOT_PATH": str(robots)}
    result = _spec_grid(cluster, tmp_path, "mine", env)
    done, summary = result["done"], result["summary"]
    assert done.returncode == 1 and not summary["finished"] and len(summary["failed"]) == 1
    text = " ".join(done.stderr.split())
    assert "refused the cell: plugins differ (only on the driver: robot:mine=coadapt " in text
    assert not ResultsStore(tmp_path / "g.db").list_runs()


def test_grid_verify_brings_a_cells_verification_rows_and_specialists_back(cluster, tmp_path):
    """`coadapt grid --verify` on Ray: the cell's `coadapt run --verify` verifies its run in
    the node's scratch folder; the verification rows reach the driver's store through the
    cell's export, and the specialists' checkpoints come back in its run folder."""
    done = subprocess.run(
        _grid_command(
            tmp_path, cluster, "--methods", "ours", "--seeds", "0", "--json", "--verify",
            "--verify-budget", "100",
        ),
        env=cluster.env,
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(summary["finished"]) == 1 and not summary["failed"]
    store = ResultsStore(tmp_path / "g.db")
    (run,) = store.list_runs(grid_id=summary["grid_id"])
    (row,) = store.verifications([run["id"]])
    assert (row["role"], row["budget"]) == ("best", 100)
    assert row["verdict"] in ("holds", "grows", "shrinks", "does not hold")
    folder = tmp_path / "runs" / run["id"] / "verify" / "b100-s0"
    assert (folder / "checkpoints" / "specialist-best.pt").is_file()
    assert (folder / "checkpoints" / "specialist-nominal.pt").is_file()
    result = json.loads((folder / "verification.json").read_text())
    assert result["designs"][0]["verdict"] == row["verdict"]
