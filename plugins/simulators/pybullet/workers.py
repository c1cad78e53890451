"""Worker processes for large batches: PyBullet has no batched API, so each worker owns a
slice of environments (an `Engine`) and the main process exchanges whole [k, ...] arrays
with all workers at once.

A worker is a fresh interpreter (`python -m coadapt_plugins.simulators.pybullet.workers`)
joined to the main process by a private socket pair wrapped as a
`multiprocessing.connection.Connection`. This is the `spawn` start method without its one
trap: multiprocessing's spawn and forkserver re-run the user's main script in every
child, which breaks any script that builds a simulator outside an `if __name__ ==
"__main__":` guard. A worker exits when told, and when its socket closes because the main
process is gone; `close()` (also run at interpreter exit) waits for it and kills it if
it lingers.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import weakref
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

#: seconds a worker may take to start (import, open its clients, load the robots)
START_TIMEOUT = 120.0


def _quiet_import(name: str) -> None:
    """Import `name` with this process's stderr closed (a worker's stdout is closed already);
    an error after the import is still printed."""
    import importlib

    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 2)
            with contextlib.suppress(ImportError):  # the engine's own import says what is missing
                importlib.import_module(name)
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _serve(conn: Connection) -> None:
    """Worker side: build the engine from the first message, then answer method calls."""
    specs, options = conn.recv()
    _quiet_import(
        "pybullet"
    )  # its "pybullet build time" banner, once per worker, would cut into progress lines
    from coadapt_plugins.simulators.pybullet.engine import Engine

    try:
        engine = Engine(specs, **options)
    except Exception as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    conn.send(("ok", None))
    try:
        while True:
            try:
                method, args = conn.recv()
            except (EOFError, OSError):  # the main process is gone
                break
            if method == "close":
                break
            try:
                result = getattr(engine, method)(*args)
            except Exception as exc:
                conn.send(("error", f"{type(exc).__name__}: {exc}"))
                continue
            conn.send(("ok", result))
    finally:
        engine.close()
        conn.close()


def _shutdown(procs: list[subprocess.Popen], conns: list[Connection]) -> None:
    """Ask workers to leave, then make sure they have."""
    for conn in conns:
        with contextlib.suppress(OSError, ValueError):
            conn.send(("close", ()))
    for proc in procs:
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)
    for conn in conns:
        with contextlib.suppress(OSError):
            conn.close()


class WorkerPool:
    """Slices of environments in worker processes; `call` runs one Engine method on every
    worker at once and gathers the answers."""

    def __init__(self, specs: list, slices: list[np.ndarray], options: dict[str, Any]):
        self.slices = slices
        self.procs: list[subprocess.Popen] = []
        self.conns: list[Connection] = []
        # registered first, so a failing start still cleans up what did start
        self._finalizer = weakref.finalize(self, _shutdown, self.procs, self.conns)
        env = dict(os.environ)
        env.setdefault("OMP_NUM_THREADS", "1")  # one core per worker
        for ids in slices:
            parent, child = socket.socketpair()
            try:
                proc = subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "coadapt_plugins.simulators.pybullet.workers",
                        str(child.fileno()),
                    ],
                    pass_fds=(child.fileno(),),
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.DEVNULL,  # PyBullet prints banners and warnings on stdout
                    env=env,
                )
            finally:
                child.close()
            parent.settimeout(None)
            conn = Connection(parent.detach())
            self.procs.append(proc)
            self.conns.append(conn)
            conn.send(([specs[i] for i in ids], options))
        for conn in self.conns:
            if not conn.poll(START_TIMEOUT):
                self.close()
                raise RuntimeError(f"a pybullet worker did not start within {START_TIMEOUT:.0f} s")
            self._answer(conn)

    def _answer(self, conn: Connection) -> Any:
        try:
            status, value = conn.recv()
        except (EOFError, OSError) as exc:
            self.close()
            raise RuntimeError("a pybullet worker process died (see its message above)") from exc
        if status != "ok":
            raise RuntimeError(f"pybullet worker failed: {value}")
        return value

    def call(self, method: str, per_worker_args: list[tuple]) -> list[Any]:
        for conn, args in zip(self.conns, per_worker_args, strict=True):
            conn.send((method, args))
        return [self._answer(conn) for conn in self.conns]

    def call_some(self, method: str, args_by_worker: dict[int, tuple]) -> dict[int, Any]:
        for w, args in args_by_worker.items():
            self.conns[w].send((method, args))
        return {w: self._answer(self.conns[w]) for w in args_by_worker}

    def close(self) -> None:
        self._finalizer()

    @property
    def pids(self) -> list[int]:
        return [proc.pid for proc in self.procs]


def main(argv: list[str]) -> int:
    conn = Connection(int(argv[0]))
    try:
        _serve(conn)
    except (EOFError, OSError, KeyboardInterrupt):
        return 0
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
