"""A Ray cluster on this machine for the grid's cluster tests: a network namespace with only
127.0.0.1, a head node (0 CPUs) and worker nodes, each in a mount namespace with an empty
tmpfs over /tmp (no disk shared with the driver) and a PID namespace (removing a node ends
every process of it)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RAY = str(Path(sys.executable).parent / "ray")
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
