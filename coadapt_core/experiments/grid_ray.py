"""A grid's cells as Ray tasks, self-contained: each runs in a scratch folder of its node
(`ray_cell`) and hands back its store rows and run folder, which the driver writes into its
own store and `--out` as each cell finishes (`coadapt import`'s merge rule); nodes need no
shared disk and no access to the driver's store. A cell reserves the CPUs it runs with (its
`--threads`, else 1) and a GPU when its run arguments ask for `--device cuda`. A cell lost
with its node (or its worker process) runs again, resuming from the last state it sent back
when there is one; the stream says so (`RAN_AGAIN`)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.experiments.grid_plan import CellOutcome, CellTask
from coadapt_core.results.store import ResultsStore

#: exit code in the executor's stream of a cell that was lost and runs again (not its end)
RAN_AGAIN = -3
#: how often a lost cell runs again before it counts as failed
MAX_RERUNS = 3
#: seconds between the driver's looks at its mailbox of running cells' states
POLL = 1.0


def cell_threads(argv: Sequence[str]) -> int:
    """The threads a cell's `coadapt run` arguments give it (`--threads N`), else 1."""
    value = None
    for i, token in enumerate(argv):
        if token == "--threads" and i + 1 < len(argv):
            value = argv[i + 1]
        elif token.startswith("--threads="):
            value = token.partition("=")[2]
    try:
        return max(1, int(value)) if value is not None else 1
    except ValueError:
        return 1


def cell_gpus(argv: Sequence[str]) -> int:
    """1 when the cell's run arguments put it on a GPU (`--device cuda...`), else 0."""
    for i, token in enumerate(argv):
        value = (
            argv[i + 1]
            if token == "--device" and i + 1 < len(argv)
            else (token.partition("=")[2] if token.startswith("--device=") else "")
        )
        if value.startswith("cuda"):
            return 1
    return 0


def _connect(ray: Any, workers: int, address: str | None) -> bool:
    """Join the cluster at `address` (else `$RAY_ADDRESS`) or start a local instance of
    `workers` CPUs; True when this call started Ray (and shuts it down)."""
    from coadapt_core.experiments.grid_exec import check_ray_address

    if ray.is_initialized():
        return False
    address = address or os.environ.get("RAY_ADDRESS") or None
    kwargs: dict[str, Any] = {"log_to_driver": False}
    if address in (None, "local"):
        kwargs.update(num_cpus=max(1, workers), include_dashboard=False)  # a new local instance
    else:
        if address != "auto":
            check_ray_address(address)
        kwargs["address"] = address  # joining: Ray refuses num_cpus
    try:
        ray.init(**kwargs)
    except Exception as exc:  # a bad address, a refused token, an unreachable cluster
        detail = " ".join(str(exc).split())[:300]
        raise UserError(
            f"cannot connect to Ray at '{address or 'local'}': {detail}", field="address"
        ) from None
    return True


def ray_executor(
    tasks: Sequence[CellTask],
    workers: int,
    address: str | None = None,
    *,
    store: ResultsStore,
    out_dir: str | os.PathLike | None = "runs",
    extra: Sequence[str] = (),
    state_every: float = 300.0,
) -> Iterator[tuple[CellTask, CellOutcome]]:
    """One Ray task per cell (see the module); yields each cell's outcome once its rows and
    folder are in `store` and `out_dir`, and a `RAN_AGAIN` outcome for a lost cell that was
    started again."""
    try:
        import ray
    except ImportError:
        raise UserError(
            "--executor ray needs Ray: pip install 'coadapt[ray]' (or use --executor local)",
            field="executor",
        ) from None
    started_here = _connect(ray, workers, address)
    try:
        yield from _Driver(ray, store, Path(out_dir or "runs"), list(extra), state_every).run(tasks)
    finally:
        if started_here:
            ray.shutdown()


class _Driver:
    """Submits the cells, takes running cells' states from the mailbox, writes what comes
    back, and starts lost cells again."""

    def __init__(
        self, ray: Any, store: ResultsStore, out: Path, extra: list[str], state_every: float
    ):
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        from coadapt_core.experiments.ray_cell import Mailbox, node_fingerprint, run_cell

        self.ray, self.store, self.out, self.extra, self.state_every = (
            ray,
            store,
            out,
            extra,
            state_every,
        )
        self.fingerprint = node_fingerprint()
        here = ray.get_runtime_context().get_node_id()
        # on the driver's node: the states it holds outlive any worker node
        self.mailbox = (
            ray.remote(num_cpus=0)(Mailbox)
            .options(scheduling_strategy=NodeAffinitySchedulingStrategy(here, soft=False))
            .remote()
        )
        self.remote = ray.remote(max_retries=0)(run_cell)
        self.pending: dict[Any, tuple[CellTask, int]] = {}
        self.attempt: dict[str, int] = {}

    def submit(self, task: CellTask, attempt: int) -> str:
        """Start the cell's attempt; returns how it starts (afresh, or resuming which run)."""
        from coadapt_core.experiments.cell import keeps_study
        from coadapt_core.experiments.cell_bundle import pack_folder
        from coadapt_core.experiments.grid_plan import unfinished_run
        from coadapt_core.experiments.ray_cell import RayCell

        argv = (
            task.argv
        )  # the cell's `coadapt run` arguments, --run-arg options and --threads included
        job = RayCell(
            task=task,
            extra=self.extra,
            fingerprint=self.fingerprint,
            attempt=attempt,
            state_every=self.state_every,
            threads=cell_threads(argv),
        )
        previous = unfinished_run(self.store, task.cell, self.out)
        how = "from the start"
        if previous is not None and not keeps_study(task.cell.method, task.cell.optimizer):
            job.resume, job.resume_files = (
                previous["id"],
                pack_folder(previous["run_dir"], keep_buffer=True),
            )
            how = f"resuming run {previous['id']} from its last state sent back"
        ref = self.remote.options(num_cpus=job.threads, num_gpus=cell_gpus(argv)).remote(
            job, self.mailbox
        )
        self.pending[ref] = (task, attempt)
        self.attempt[task.cell.key] = attempt
        return how

    def too_big(self, task: CellTask) -> str | None:
        """Why no node of the cluster as it is can ever run this cell (Ray would wait for one
        for ever), or None."""
        nodes = [n.get("Resources", {}) for n in self.ray.nodes() if n.get("Alive")]
        cpus = max((r.get("CPU", 0) for r in nodes), default=0)
        gpus = max((r.get("GPU", 0) for r in nodes), default=0)
        threads, gpu = cell_threads(task.argv), cell_gpus(task.argv)
        if threads > cpus:
            return (
                f"the cell reserves {threads} CPUs (--threads) and the largest node of the "
                f"cluster has {cpus:g}; give --threads <= {cpus:g} or add bigger nodes"
            )
        if gpu > gpus:
            return "the cell runs on a GPU (--device cuda) and no node of the cluster has one"
        return None

    def run(self, tasks: Sequence[CellTask]) -> Iterator[tuple[CellTask, CellOutcome]]:
        for task in tasks:
            reason = self.too_big(task)
            if reason is not None:
                yield task, CellOutcome(task.cell.key, 1, 0.0, None, reason)
                continue
            self.submit(task, 1)
        try:
            while self.pending:
                done, _ = self.ray.wait(list(self.pending), num_returns=1, timeout=POLL)
                self.take_states()
                if done:
                    yield from self.settle(done[0])
        except BaseException:  # Ctrl-C: each cell's task passes it on to its process
            for ref in self.pending:
                with contextlib.suppress(Exception):
                    self.ray.cancel(ref, force=False)
            raise

    def settle(self, ref: Any) -> Iterator[tuple[CellTask, CellOutcome]]:
        from ray.exceptions import RayTaskError, TaskCancelledError

        task, attempt = self.pending.pop(ref)
        key = task.cell.key
        try:
            result = self.ray.get(ref)
        except (RayTaskError, TaskCancelledError) as exc:  # raised inside the cell's task
            line = " ".join(str(exc).split())[-300:]
            yield task, CellOutcome(key, 1, 0.0, None, f"the cell's Ray task failed: {line}")
            return
        except Exception as exc:  # the node or worker died, the result was lost with it
            reason = type(exc).__name__
            if attempt > MAX_RERUNS:
                yield (
                    task,
                    CellOutcome(
                        key, 1, 0.0, None, f"lost {attempt} times ({reason}); not run again"
                    ),
                )
                return
            how = self.submit(task, attempt + 1)
            yield (
                task,
                CellOutcome(
                    key,
                    RAN_AGAIN,
                    0.0,
                    None,
                    f"lost with its node or worker ({reason}); attempt {attempt + 1} starts {how}",
                ),
            )
            return
        yield task, self.absorb(task, attempt, result)

    def absorb(self, task: CellTask, attempt: int, result: dict[str, Any]) -> CellOutcome:
        """Write a finished attempt's folder and rows here; the outcome says whether they are."""
        from coadapt_core.experiments.cell_bundle import BundleError

        outcome: CellOutcome = result["outcome"]
        self._log(task, attempt, result)
        run_id = result.get("run_id")
        if run_id is None or result.get("rows") is None:
            return outcome
        try:
            self._write(task.cell.key, run_id, result["rows"], result.get("files") or {})
        except (BundleError, UserError) as exc:
            return CellOutcome(
                outcome.cell_key,
                1,
                outcome.seconds,
                outcome.result,
                f"what the cell sent back was refused: {exc}",
            )
        return outcome

    def take_states(self) -> None:
        """Write the running cells' latest states (their current attempt's only)."""
        from coadapt_core.experiments.cell_bundle import BundleError

        try:
            items = self.ray.get(self.mailbox.take.remote())
        except Exception:
            return
        for key, attempt, run_id, rows, files in items:
            if self.attempt.get(key) != attempt:
                continue
            with contextlib.suppress(
                BundleError, UserError
            ):  # a bad state is not written; the cell goes on
                self._write(key, run_id, rows, files)

    def _write(self, key: str, run_id: Any, rows: Any, files: Any) -> None:
        from coadapt_core.experiments.cell_bundle import (
            BundleError,
            import_rows,
            retarget_state,
            write_folder,
        )
        from coadapt_core.validation import is_run_id

        if not is_run_id(run_id):
            raise BundleError(f"run id {str(run_id)[:80]!r} is not a run id", field="bundle")
        folder = write_folder(files, self.out / run_id)
        retarget_state(folder, out=str(self.out), store=self.store.url)
        import_rows(self.store, rows, run_id=run_id, folder=folder, cell=key)

    def _log(self, task: CellTask, attempt: int, result: dict[str, Any]) -> None:
        if not task.log_path:
            return
        path = Path(task.log_path)
        path.parent.mkdir(parents=True, exist_ok=True)
        where = f"# attempt {attempt} on node {result.get('host')} ({result.get('node')})"
        with path.open("a") as fh:
            if result.get("scratch") is None:  # refused before it ran
                fh.write(f"{where}: {result['outcome'].error}\n")
            else:
                fh.write(
                    f"{where}, scratch {result['scratch']} (removed)\n{result.get('log') or ''}\n"
                )
