"""Worker processes for large batches: PyBullet has no batched API, so each worker owns a
slice of environments (an `Engine`) and the main process exchanges whole [k, ...] arrays
with all workers at once over pipes.

Workers start with the `spawn` method (safe with torch and threads in the parent), exit
when told, when their pipe closes (the parent died) and, being daemonic, when the parent
interpreter exits.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import weakref
from multiprocessing.connection import Connection
from typing import Any

import numpy as np


def _worker_main(conn: Connection, specs: list, options: dict[str, Any]) -> None:
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
            except (EOFError, OSError):  # the parent is gone
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


def _shutdown(procs: list, conns: list[Connection]) -> None:
    """Ask workers to leave, then make sure they have."""
    for conn in conns:
        with contextlib.suppress(OSError, ValueError, BrokenPipeError):
            conn.send(("close", ()))
    for proc in procs:
        proc.join(timeout=5)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=5)
    for conn in conns:
        with contextlib.suppress(OSError):
            conn.close()


class WorkerPool:
    """Slices of environments in worker processes; `call` runs one Engine method on every
    worker at once and gathers the answers."""

    def __init__(self, specs: list, slices: list[np.ndarray], options: dict[str, Any]):
        ctx = mp.get_context("spawn")
        self.slices = slices
        self.procs: list = []
        self.conns: list[Connection] = []
        # registered first, so a failing start still cleans up what did start
        self._finalizer = weakref.finalize(self, _shutdown, self.procs, self.conns)
        for ids in slices:
            parent, child = ctx.Pipe()
            proc = ctx.Process(
                target=_worker_main, args=(child, [specs[i] for i in ids], options), daemon=True,
                name="coadapt-pybullet-worker",
            )
            proc.start()
            child.close()
            self.procs.append(proc)
            self.conns.append(parent)
        for conn in self.conns:
            self._answer(conn)

    @staticmethod
    def _answer(conn: Connection) -> Any:
        try:
            status, value = conn.recv()
        except (EOFError, OSError) as exc:
            raise RuntimeError("a pybullet worker process died") from exc
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
    def alive(self) -> list[bool]:
        return [proc.is_alive() for proc in self.procs]
