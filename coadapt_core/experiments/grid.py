"""Ablation grids (method x objective x terrain x seed): expand, skip what the store
already holds, run each cell as `coadapt run ... --json` in its own process, locally or on
Ray, and resume what a killed grid left unfinished.

A clean process per cell isolates crashes (a diverging simulation or an out-of-memory kill
takes one cell down, not the grid) and keeps both executors trivial: they only start
commands. The cell's run finds the store, grid and cell through environment variables
(`COADAPT_STORE`, `COADAPT_GRID_ID`, `COADAPT_GRID_CELL`) read by the store's recorder.

The parts live beside it: the plan (cells, spec, config hashes, what is finished or
resumed) in `grid_plan`, the executors in `grid_exec`; their names are imported here too.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from coadapt_core.errors import UserError
from coadapt_core.experiments.cell import Cell
from coadapt_core.experiments.grid_exec import (
    check_grid_options,
    default_workers,
    local_executor,
)
from coadapt_core.experiments.grid_plan import (
    CellOutcome,
    CellTask,
    GridReport,
    GridSpec,
    finished_run,
    plan_grid,
    settle_abandoned,
)
from coadapt_core.experiments.grid_ray import RAN_AGAIN, ray_executor
from coadapt_core.results.store import ResultsStore
from coadapt_core.threads import check_threads, share_cores, usable_cpus

__all__ = ["GridInterrupted", "run_grid"]


def run_grid(
    spec: GridSpec,
    store: ResultsStore,
    *,
    executor: str = "local",
    workers: int | None = None,
    threads: int | None = None,
    address: str | None = None,
    out_dir: str | None = "runs",
    command: Sequence[str] | None = None,
    timeout: float | None = None,
    log_dir: str | os.PathLike | None = None,
    on_event: Callable[[str, Cell, CellOutcome | None], None] | None = None,
    state_every: float = 300.0,
) -> GridReport:
    """Run every cell the store does not already hold as finished; returns what happened.
    `threads`: CPU threads per cell (each cell's `coadapt run --threads`); locally the cells
    at once x threads per cell fit the CPUs this process may use (`share_cores`).
    `on_event(kind, cell, outcome)` reports "skipped", "started", "finished", "failed" and
    "rerun" (a Ray cell lost with its node started again). A Ray cell runs in a scratch folder
    of its node and sends back its rows and run folder (`grid_ray`); a running one sends its
    last state every `state_every` seconds, so a rerun resumes from it."""
    check_grid_options(executor=executor, workers=workers, timeout=timeout, address=address)
    if threads is not None:
        check_threads(threads, "threads")
    if any(arg == "--threads" or arg.startswith("--threads=") for arg in spec.extra_args):
        raise UserError(
            "--run-arg=--threads: give the threads per cell as `coadapt grid --threads N` "
            "(the grid divides the cores among the cells by it)",
            field="run_arg",
        )
    grid_id = spec.grid_id
    store.save_grid(grid_id, spec.to_dict())
    if log_dir is None and out_dir is not None:
        log_dir = Path(out_dir) / "grid-logs" / grid_id
    settle_abandoned(store, spec, out_dir)
    tasks, skipped = plan_grid(
        store, spec, out_dir=out_dir, command=command, timeout=timeout, log_dir=log_dir
    )
    report = GridReport(grid_id)
    _record_plan(store, spec, skipped, tasks, report, on_event)
    if not tasks:
        return report
    workers = _give_threads(tasks, executor, workers, threads)
    if executor == "local":
        stream = local_executor(tasks, workers)
    else:
        stream = ray_executor(
            tasks,
            workers,
            address,
            store=store,
            out_dir=out_dir,
            extra=spec.cell_args,
            state_every=state_every,
        )
    try:
        _collect(store, grid_id, stream, report, on_event)
    except BaseException as exc:  # Ctrl-C: the running cells were told (`stop_cells`)
        if hasattr(stream, "close"):
            stream.close()
        _mark_interrupted(store, grid_id, tasks, report)
        if isinstance(exc, KeyboardInterrupt):
            raise GridInterrupted(report) from None
        raise
    return report


def _record_plan(
    store: ResultsStore,
    spec: GridSpec,
    skipped: Sequence[Cell],
    tasks: Sequence[CellTask],
    report: GridReport,
    on_event: Callable[[str, Cell, CellOutcome | None], None] | None,
) -> None:
    """Mark the skipped cells finished (with the run that answers them) and the cells to run
    running, in the store and the report."""
    grid_id = spec.grid_id
    for cell in skipped:
        run = finished_run(store, cell, spec)
        store.set_cell(grid_id, cell.key, status="finished", run_id=run["id"] if run else None)
        report.skipped.append(cell.key)
        if on_event:
            on_event("skipped", cell, None)
    for task in tasks:
        store.set_cell(grid_id, task.cell.key, status="running", run_id=task.resume, attempt=True)
        if task.resume:
            report.resumed.append(task.cell.key)
        if on_event:
            on_event("started", task.cell, None)


def _give_threads(
    tasks: Sequence[CellTask], executor: str, workers: int | None, threads: int | None
) -> int:
    """Give every cell its threads (`--threads`, OMP_NUM_THREADS and, when cells run
    together, the passive OpenMP wait); returns the cells to run at once."""
    if executor == "local":  # the cores shared by the cells at once: cells x threads <= cores
        workers, threads = share_cores(usable_cpus(), len(tasks), workers, threads)
    else:  # a Ray cell reserves its threads on a node of the cluster
        workers, threads = workers or default_workers(), threads or 1
    for task in tasks:
        # not in the cell's config hash: any split resumes it
        task.argv += ["--threads", str(threads)]
        task.env.setdefault("OMP_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", str(threads)))
        if min(workers, len(tasks)) > 1 and "GOMP_SPINCOUNT" not in os.environ:
            # cells started together share the cores: their OpenMP workers sleep when idle
            # instead of spinning (coadapt_core.launch.omp_wait_settings)
            task.env.setdefault("OMP_WAIT_POLICY", os.environ.get("OMP_WAIT_POLICY", "PASSIVE"))
    return workers


def _mark_interrupted(
    store: ResultsStore, grid_id: str, tasks: Sequence[CellTask], report: GridReport
) -> None:
    """The cells without an outcome when the grid stopped: interrupted, and their runs too."""
    for task in tasks:
        if task.cell.key in report.outcomes:
            continue
        started = store.list_runs(cell=task.cell.key)
        run = started[-1] if started else None
        if run is not None and run["status"] == "running" and run.get("grid_id") == grid_id:
            store.set_status(run["id"], "interrupted")  # killed before it could say so
        store.set_cell(
            grid_id,
            task.cell.key,
            status="interrupted",
            run_id=run["id"] if run else None,
            error="the grid was interrupted",
        )


class GridInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped the grid: `report` says what had finished; running the same grid
    again skips those and resumes the rest."""

    def __init__(self, report: GridReport):
        super().__init__(report.grid_id)
        self.report = report


def _collect(
    store: ResultsStore,
    grid_id: str,
    stream: Iterator[tuple[CellTask, CellOutcome]],
    report: GridReport,
    on_event: Callable[[str, Cell, CellOutcome | None], None] | None,
) -> None:
    for task, outcome in stream:
        key = task.cell.key
        if outcome.returncode == RAN_AGAIN:  # lost with its node: started again, not over
            report.ran_again.append(key)
            store.set_cell(grid_id, key, status="running", attempt=True, error=outcome.error)
            if on_event:
                on_event("rerun", task.cell, outcome)
            continue
        report.outcomes[key] = outcome
        run_id = (outcome.result or {}).get("run_id")
        if run_id is None:
            started = store.list_runs(cell=key)
            run_id = started[-1]["id"] if started else None
        if outcome.returncode == 0 and not (
            run_id and store.has_run(run_id) and store.get_run(run_id)["status"] == "finished"
        ):
            # finished only once its rows are in this store (a Ray cell's are written here)
            outcome = CellOutcome(
                key,
                1,
                outcome.seconds,
                outcome.result,
                f"the cell's run {run_id} is not in the store {store.url} as finished",
            )
            report.outcomes[key] = outcome
        if outcome.returncode == 0:
            store.set_cell(grid_id, key, status="finished", run_id=run_id)
            report.finished.append(key)
        else:
            store.set_cell(grid_id, key, status="failed", run_id=run_id, error=outcome.error)
            if run_id is not None:
                run = store.get_run(run_id)
                if run["status"] == "running":  # the process died without saying so
                    store.set_status(run_id, "interrupted")
            report.failed.append(key)
        if on_event:
            on_event("finished" if outcome.returncode == 0 else "failed", task.cell, outcome)
