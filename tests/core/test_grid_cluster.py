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
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from coadapt_core.cli import main
from coadapt_core.results import ResultsStore

ROOT = Path(__file__).resolve().parents[2]

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'coadapt[ray]')")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        os.geteuid() != 0 or shutil.which("unshare") is None,
        reason="worker nodes without the driver's files need root and unshare",
    ),
]

RAY = str(Path(sys.executable).parent / "ray")
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
#: node death noticed within about 2 s (Ray's default is 15 s)
FAST_HEALTH = {
    "RAY_health_check_period_ms": "500",
    "RAY_health_check_failure_threshold": "4",
    "RAY_health_check_timeout_ms": "500",
}
MB100 = str(100 * 1024**2)


def _children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            out += [int(c) for c in (task / "children").read_text().split()]
    return out


def _session_of(pid: int) -> int | None:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[3])
    except (OSError, ValueError, IndexError):
        return None


class Cluster:
    """A network namespace with only 127.0.0.1 (its holder process), the head node and the
    worker nodes in it; every process id here was started by this test."""

    def __init__(self, env: dict[str, str]):
        self.env = env
        self.holder = subprocess.Popen(
            ["unshare", "--net", "sh", "-c", "ip link set lo up && exec sleep 100000"],
            start_new_session=True,
        )
        deadline = time.monotonic() + 10
        while (
            "UP"
            not in subprocess.run(
                self.in_net(["ip", "-o", "link", "show", "lo"]), capture_output=True, text=True
            ).stdout
        ):
            assert time.monotonic() < deadline, (
                "loopback did not come up in the test's network namespace"
            )
            time.sleep(0.05)
        self.port = 6379
        self.address = f"127.0.0.1:{self.port}"
        self.temp = tempfile.mkdtemp(prefix="cr-", dir="/tmp")  # short: Ray's socket paths
        self.head = subprocess.Popen(
            self.in_net(
                [
                    RAY,
                    "start",
                    "--head",
                    "--block",
                    "--node-ip-address",
                    "127.0.0.1",
                    "--port",
                    str(self.port),
                    "--num-cpus",
                    "0",
                    "--include-dashboard",
                    "false",
                    "--disable-usage-stats",
                    "--temp-dir",
                    self.temp,
                    "--object-store-memory",
                    MB100,
                    "--include-log-monitor",
                    "false",
                ]
            ),
            env=env,
            start_new_session=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        self.workers: dict[
            int, subprocess.Popen
        ] = {}  # the node's first process (PID namespace) -> unshare
        self.keep: str | None = (
            None  # where a node's mount namespace holds the code while /tmp is emptied
        )

    def in_net(self, argv: list[str]) -> list[str]:
        return ["nsenter", f"--net=/proc/{self.holder.pid}/ns/net", *argv]

    def add_worker(self) -> int:
        """A worker node of 1 CPU with an empty /tmp (it cannot read the driver's files) and its
        own PID namespace; returns its first process's id."""
        start = (
            f"{self.keep_code()}exec {RAY} start --address {self.address} --block "
            "--node-ip-address 127.0.0.1 --num-cpus 1 --disable-usage-stats "
            f"--object-store-memory {MB100} "
            "--include-log-monitor false"
        )
        proc = subprocess.Popen(
            self.in_net(
                ["unshare", "--mount", "--pid", "--fork", "--mount-proc", "sh", "-c", start]
            ),
            env=self.env,
            start_new_session=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 10
        while not _children(proc.pid):
            assert time.monotonic() < deadline, "the worker node's namespace did not start"
            time.sleep(0.05)
        (first,) = _children(proc.pid)
        self.workers[first] = proc
        return first

    def keep_code(self) -> str:
        """The shell lines that empty the node's /tmp but bind the code back where it lies under
        /tmp (a checkout or virtualenv there, as in a CI clone): a worker node runs the driver's
        code, as on a real cluster, and reads none of its data (the test's folders, store,
        --out)."""
        code = [
            p for p in {str(ROOT), os.path.realpath(sys.prefix)} if Path(p).is_relative_to("/tmp")
        ]
        code = sorted(
            p for p in code if not any(p != q and Path(p).is_relative_to(q) for q in code)
        )
        if code and self.keep is None:
            self.keep = tempfile.mkdtemp(prefix="coadapt-keep-", dir="/dev/shm")
        lines = [
            f"mkdir -p {self.keep}/{i} && mount --bind {p} {self.keep}/{i}"
            for i, p in enumerate(code)
        ]
        lines.append("mount -t tmpfs tmpfs /tmp")
        lines += [f"mkdir -p {p} && mount --bind {self.keep}/{i} {p}" for i, p in enumerate(code)]
        return "".join(f"{line} && " for line in lines)

    def remove_worker(self, first: int) -> None:
        """The node and every process on it end at once (its PID namespace's first process)."""
        with contextlib.suppress(OSError):
            os.kill(first, signal.SIGKILL)
        self.workers.pop(first).wait(timeout=30)

    def node_running(self, cell: str) -> int | None:
        """The worker node (its first process) where a process of this grid cell runs."""
        spaces = {os.readlink(f"/proc/{first}/ns/pid"): first for first in self.workers}
        for proc in Path("/proc").glob("[0-9]*"):
            with contextlib.suppress(OSError):
                if f"COADAPT_GRID_CELL={cell}".encode() in (proc / "environ").read_bytes().split(
                    b"\0"
                ):
                    space = spaces.get(os.readlink(proc / "ns" / "pid"))
                    if space is not None:
                        return space
        return None

    def scratch_left(self) -> int:
        """Cells' scratch folders left on the worker nodes (read through each node's own /tmp)."""
        from coadapt_core.experiments.ray_cell import SCRATCH_PREFIX

        return sum(
            len(list(Path(f"/proc/{first}/root/tmp").glob(f"{SCRATCH_PREFIX}*")))
            for first in self.workers
        )

    def wait_workers(self, count: int, timeout: float = 60.0) -> None:
        script = (
            "import ray, sys, time\n"
            f"ray.init(address='{self.address}', log_to_driver=False)\n"
            f"deadline = time.monotonic() + {timeout}\n"
            "while sum(n['Alive'] and n['Resources'].get('CPU', 0) > 0 for n in ray.nodes()) < "
            f"{count} and time.monotonic() < deadline:\n"
            "    time.sleep(0.3)\n"
            "print(sum(n['Alive'] and n['Resources'].get('CPU', 0) > 0 for n in ray.nodes()))\n"
        )
        done = subprocess.run(
            self.in_net([sys.executable, "-c", script]),
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout + 30,
        )
        assert done.stdout.strip().endswith(str(count)), done.stderr[-2000:]

    def stop(self) -> None:
        for first in list(self.workers):
            self.remove_worker(first)
        for proc in Path("/proc").glob(
            "[0-9]*"
        ):  # the head's processes: all in the session it started
            if proc.name.isdigit() and _session_of(int(proc.name)) == self.head.pid:
                with contextlib.suppress(OSError):
                    os.kill(int(proc.name), signal.SIGKILL)
        self.head.wait(timeout=30)
        self.holder.kill()
        self.holder.wait(timeout=30)
        shutil.rmtree(self.temp, ignore_errors=True)
        if self.keep:  # empty here: the binds were made in the nodes' own mount namespaces
            for folder in sorted(Path(self.keep).glob("*")):
                with contextlib.suppress(OSError):
                    folder.rmdir()
            with contextlib.suppress(OSError):
                os.rmdir(self.keep)


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
    for run in runs:  # each run's folder under the driver's --out, its rows naming it
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
    logs = sorted((tmp_path / "runs" / "grid-logs" / summary["grid_id"]).glob("*.log"))
    assert len(logs) == 4 and all("attempt 1 on node 127.0.0.1" in p.read_text() for p in logs)
    scratch = re.findall(r"scratch (\S+) \(removed\)", "".join(p.read_text() for p in logs))
    assert len(set(scratch)) == 4 and not any(Path(s).exists() for s in scratch)
    assert cluster.scratch_left() == 0  # removed on the nodes too
    print(
        f"4-cell grid on 2 worker nodes: {grid_seconds:.1f} s; {len(runs)} runs in the driver's "
        "store"
    )

    # the report (sim-to-sim and common-scenario rows) and a handoff from the driver alone
    started = time.perf_counter()
    assert (
        main(
            [
                "report",
                summary["grid_id"],
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
    run_id = runs[0]["id"]
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
