"""Running a grid's cells: each cell one `coadapt run ... --json` process, on a local pool
(the Ray executor is `grid_ray`), with Ctrl-C passed on to the running cells; and the checks
of the executor options made before anything starts."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shlex
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from coadapt_core.errors import UserError, did_you_mean
from coadapt_core.experiments.grid_plan import CellOutcome, CellTask

EXECUTORS = ("local", "ray")
#: how a cell process starts coadapt when no command is given: the interpreter running the
#: grid (or the Ray worker) on `python -m coadapt_core`, the console script's twin, so no
#: script on PATH is needed and nothing here imports the CLI
ENTRY = ("-m", "coadapt_core")

#: cell processes running in this process, and whether the grid is stopping (Ctrl-C): then
#: no further cell starts, and `stop_cells` passes the interrupt on to those running
_LIVE: set[subprocess.Popen] = set()
_LIVE_LOCK = threading.Lock()
_STOPPING = threading.Event()
#: exit code of a cell that was not started because the grid was stopping
NOT_STARTED = -2


def stop_cells(grace: float = 60.0) -> None:
    """Ctrl-C for the running cells: each gets SIGINT (a cell run records itself interrupted,
    keeps its last state and exits), and is killed if still running after `grace` seconds;
    cells not yet started never start."""
    import signal

    _STOPPING.set()
    with _LIVE_LOCK:
        live = list(_LIVE)
    for proc in live:
        with contextlib.suppress(OSError):
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + grace
    for proc in live:
        try:
            proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()


def execute_cell(task: CellTask, cwd: str | os.PathLike | None = None) -> CellOutcome:
    """Run one cell's process to the end, in the folder `cwd` (default: this process's)."""
    prefix = task.command if task.command is not None else [sys.executable, *ENTRY]
    env = {**os.environ, **task.env}
    start = time.perf_counter()
    if _STOPPING.is_set():
        return CellOutcome(
            task.cell.key, NOT_STARTED, 0.0, None, "not started: the grid was interrupted"
        )
    try:
        proc = subprocess.Popen(
            [*prefix, *task.argv],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=cwd,
        )
    except OSError as exc:
        proc = None
        returncode, stdout, stderr = 127, "", f"cannot start {prefix[0]}: {exc}"
    if proc is not None:
        with _LIVE_LOCK:
            _LIVE.add(proc)
        try:
            stdout, stderr = proc.communicate(timeout=task.timeout)
            returncode = proc.returncode
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, stderr = proc.communicate()
            returncode = 124
            stderr = (stderr or "") + f"\ncell timed out after {task.timeout:g} s"
        except BaseException:  # interrupted here (a Ray task cancelled): the cell stops too
            import signal

            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
            raise
        finally:
            with _LIVE_LOCK:
                _LIVE.discard(proc)
    seconds = time.perf_counter() - start
    if task.log_path:
        path = Path(task.log_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("a") as fh:
            # a command that runs as it stands (this interpreter starts coadapt as a module)
            shown = (
                [*task.command, *task.argv]
                if task.command is not None
                else [sys.executable, "-m", "coadapt_core", *task.argv]
            )
            fh.write(f"$ {shlex.join(shown)}\n{stdout}\n--- stderr ---\n{stderr}\n")
    result = None
    for line in reversed(stdout.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                result = json.loads(line)
            except json.JSONDecodeError:
                result = None
            break
    error = None
    if returncode != 0:
        tail = [ln for ln in stderr.strip().splitlines() if ln.strip()][-5:]
        error = " | ".join(tail) or f"exit code {returncode}"
    return CellOutcome(task.cell.key, returncode, seconds, result, error)


# -- executors -----------------------------------------------------------------------------
def local_executor(
    tasks: Sequence[CellTask], workers: int
) -> Iterator[tuple[CellTask, CellOutcome]]:
    """A pool of `workers` cell processes on this machine (threads only wait on them). An
    interrupt (Ctrl-C) is passed on to the running cells (`stop_cells`) before it propagates."""
    _STOPPING.clear()
    pool = ThreadPoolExecutor(max_workers=max(1, workers))
    try:
        futures = {pool.submit(execute_cell, t): t for t in tasks}
        for future in as_completed(futures):
            yield futures[future], future.result()
    except BaseException:
        stop_cells()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def check_grid_options(
    *,
    executor: str,
    workers: int | None,
    timeout: float | None,
    address: str | None,
    connect_timeout: float = 5.0,
) -> None:
    """One-line `UserError` for a bad executor, worker count, cell timeout, or a Ray address
    that does not answer within `connect_timeout` seconds (checked before anything starts)."""
    if executor not in EXECUTORS:
        raise UserError(
            f"--executor '{executor}' is not one of {', '.join(EXECUTORS)}"
            f"{did_you_mean(executor, EXECUTORS)}",
            field="executor",
        )
    if workers is not None and workers < 1:
        raise UserError(f"--workers must be >= 1, got {workers}", field="workers")
    if timeout is not None and not (math.isfinite(timeout) and timeout > 0):
        raise UserError(
            f"--timeout must be a number of seconds > 0, got {timeout}", field="timeout"
        )
    if executor == "ray" and address and address not in ("auto", "local"):
        check_ray_address(address, connect_timeout)


def check_ray_address(address: str, connect_timeout: float = 10.0) -> None:
    """The Ray head at `address` (host:port, or ray://host:port) accepts a TCP connection;
    otherwise one line instead of Ray's own minutes of retries."""
    import socket

    target = address.split("://", 1)[1] if "://" in address else address
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise UserError(
            f"--address '{address}' is not host:port (e.g. 10.0.0.5:6379 or ray://head:10001)",
            field="address",
        )
    from concurrent.futures import ThreadPoolExecutor
    from concurrent.futures import TimeoutError as Timeout

    def connect() -> None:
        with socket.create_connection((host, int(port)), timeout=connect_timeout):
            pass

    pool = ThreadPoolExecutor(max_workers=1)  # name resolution has no timeout of its own
    try:
        pool.submit(connect).result(timeout=connect_timeout + 1)
    except Timeout:
        raise UserError(
            f"cannot reach a Ray cluster at --address '{address}' "
            f"(no answer in {connect_timeout:g} s); check the head node's host and port, "
            "or use --executor local",
            field="address",
        ) from None
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise UserError(
            f"cannot reach a Ray cluster at --address '{address}' ({reason}); "
            "check the head node's host and port, or use --executor local",
            field="address",
        ) from None
    finally:
        pool.shutdown(wait=False)


Executor = Callable[[Sequence[CellTask], int], Iterator[tuple[CellTask, CellOutcome]]]


def default_workers() -> int:
    """One cell per core: a cell's learner and physics keep a core busy on their own."""
    return max(1, os.cpu_count() or 1)
