"""One grid cell as a Ray task on whichever node Ray picks: `coadapt run ... --json` in a
scratch folder of that node (removed when the task returns), recording into a scratch SQLite
store there; what the driver needs comes back through Ray as plain data (`cell_bundle`): the
outcome, the store rows of the run and its run folder (the evaluation buffer left out).

While the run goes on, its last saved state (the run folder with its buffer, sent at most
every `state_every` seconds, when the state file changed) goes to the driver's mailbox actor,
so a cell lost with its node resumes from it elsewhere. A node whose coadapt version, source
or plugin set differs from the driver's refuses the cell in one line."""

from __future__ import annotations

import shutil
import tempfile
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from coadapt_core.experiments.cell import Cell
from coadapt_core.experiments.cell_bundle import (
    STATE_NAME,
    export_rows,
    pack_folder,
    retarget_state,
    write_folder,
)
from coadapt_core.experiments.grid_plan import CellOutcome, CellTask

#: where a cell's run records and writes on its node, relative to its scratch folder (the
#: run's state keeps these relative names, so it resumes in any other scratch folder)
SCRATCH_STORE = "sqlite:///cell.db"
SCRATCH_RUNS = "runs"
SCRATCH_PREFIX = "coadapt-cell-"
#: exit code of a cell a node refused (another coadapt or plugin set than the driver's)
REFUSED = 3
#: the last bytes of a cell's log that come back to the driver
LOG_TAIL = 1024 * 1024


@dataclass
class RayCell:
    """What the driver sends a node for one cell (plain data)."""

    task: CellTask
    extra: list[str]  # the grid's --run-arg options
    fingerprint: dict[str, Any]  # the driver's `node_fingerprint()`
    attempt: int = 1
    resume: str | None = None  # run id whose folder `resume_files` holds
    resume_files: dict[str, bytes] = field(default_factory=dict)
    state_every: float = 300.0  # seconds between states sent back; 0: none
    threads: int = 1


def node_fingerprint() -> dict[str, Any]:
    """What must match between the driver and a node: coadapt's version and every plugin
    (kind, name, distribution and version). Not the git commit of a source checkout: a shared
    checkout moves under a running grid, and installed packages have none."""
    from importlib import metadata

    from coadapt_core.plugins import get_registry

    try:
        version = metadata.version("coadapt")
    except metadata.PackageNotFoundError:
        version = "unknown"
    plugins = sorted(
        f"{p.kind}:{p.name}={p.distribution} {p.version}" for p in get_registry().all()
    )
    return {"coadapt": version, "plugins": plugins}


def fingerprint_difference(driver: dict[str, Any], node: dict[str, Any]) -> str | None:
    """One phrase naming what differs (None when nothing does)."""
    if driver.get("coadapt") != node.get("coadapt"):
        return f"coadapt {node.get('coadapt')} here, {driver.get('coadapt')} on the driver"
    mine, theirs = set(node.get("plugins") or []), set(driver.get("plugins") or [])
    if mine != theirs:
        extra, missing = sorted(mine - theirs), sorted(theirs - mine)
        parts = ([f"only here: {', '.join(extra[:3])}"] if extra else []) + (
            [f"only on the driver: {', '.join(missing[:3])}"] if missing else []
        )
        return "plugins differ (" + "; ".join(parts) + ")"
    return None


def run_cell(job: RayCell, mailbox: Any = None) -> dict[str, Any]:
    """The Ray task: refuse on another coadapt, else run the cell in a scratch folder and
    return {"outcome", "run_id", "rows", "files", "log", "node", "scratch"}."""
    import ray

    node = ray.get_runtime_context().get_node_id() if ray.is_initialized() else "local"
    host = _host()
    differs = fingerprint_difference(job.fingerprint, node_fingerprint())
    key = job.task.cell.key
    if differs:
        error = (
            f"node {host} refused the cell: {differs}; install the driver's coadapt and "
            "plugins on every node (docs/cluster.md)"
        )
        return {"outcome": CellOutcome(key, REFUSED, 0.0, None, error), "node": node, "host": host}
    scratch = Path(tempfile.mkdtemp(prefix=SCRATCH_PREFIX))
    try:
        return {
            **_run_in(scratch, job, mailbox),
            "node": node,
            "host": host,
            "scratch": str(scratch),
        }
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _host() -> str:
    import ray

    try:
        return ray.util.get_node_ip_address()
    except Exception:  # outside Ray (a unit test)
        return "localhost"


def _run_in(scratch: Path, job: RayCell, mailbox: Any) -> dict[str, Any]:
    from coadapt_core.experiments.grid_exec import execute_cell
    from coadapt_core.results.storage import ENV_STORE
    from coadapt_core.results.store import ResultsStore

    runs = scratch / SCRATCH_RUNS
    runs.mkdir()
    resume = None
    if job.resume and job.resume_files:
        folder = write_folder(job.resume_files, runs / _checked_id(job.resume))
        retarget_state(folder, out=SCRATCH_RUNS, store=SCRATCH_STORE)
        resume = job.resume
    cell: Cell = job.task.cell
    argv = cell.run_args(out_dir=SCRATCH_RUNS, resume=resume, extra=job.extra, store=SCRATCH_STORE)
    if any(a == "--threads" or a.startswith("--threads=") for a in job.task.argv):
        argv += ["--threads", str(job.threads)]  # the grid's threads per cell, as it reserved them
    env = {**job.task.env, ENV_STORE: SCRATCH_STORE, "OMP_NUM_THREADS": str(job.threads)}
    log = scratch / "cell.log"
    task = replace(job.task, argv=argv, env=env, log_path=str(log), resume=resume)
    stop = threading.Event()
    sender = None
    if mailbox is not None and job.state_every > 0:
        sender = threading.Thread(
            target=_send_states, args=(scratch, job, mailbox, stop), daemon=True
        )
        sender.start()
    try:
        outcome = execute_cell(task, cwd=scratch)  # the run's relative store and runs folder
    finally:
        stop.set()
        if sender is not None:
            sender.join(timeout=60)
    run_id = _run_id(runs, outcome)
    rows = files = None
    if run_id is not None:
        with ResultsStore(f"sqlite:///{scratch / 'cell.db'}") as store:
            rows = export_rows(store, [run_id]) if store.has_run(run_id) else None
        files = pack_folder(runs / run_id)
    text = log.read_bytes()[-LOG_TAIL:].decode("utf-8", "replace") if log.is_file() else ""
    return {"outcome": outcome, "run_id": run_id, "rows": rows, "files": files, "log": text}


def _checked_id(run_id: str) -> str:
    from coadapt_core.experiments.cell_bundle import BundleError
    from coadapt_core.validation import is_run_id

    if not is_run_id(run_id):
        raise BundleError(f"resume run id {str(run_id)[:80]!r} is not a run id", field="bundle")
    return run_id


def _run_id(runs: Path, outcome: CellOutcome) -> str | None:
    """The run the cell made: the one folder under its scratch runs folder (the JSON line
    names it too)."""
    from coadapt_core.validation import is_run_id

    named = (outcome.result or {}).get("run_id")
    folders = [
        p.name for p in runs.iterdir() if p.is_dir() and not p.is_symlink() and is_run_id(p.name)
    ]
    if isinstance(named, str) and named in folders:
        return named
    return folders[0] if len(folders) == 1 else None


def snapshot(scratch: Path) -> tuple[str, dict[str, str], dict[str, bytes]] | None:
    """(run id, rows, files with the buffer) of the running cell at its last saved state, or
    None when there is none yet or it moved on while it was read (taken again later)."""
    from coadapt_core.results.store import ResultsStore

    runs = scratch / SCRATCH_RUNS
    found = (
        [p for p in runs.iterdir() if p.is_dir() and (p / STATE_NAME).is_file()]
        if runs.is_dir()
        else []
    )
    if len(found) != 1:
        return None
    folder = found[0]
    before = (folder / STATE_NAME).read_bytes()
    files = pack_folder(folder, keep_buffer=True)
    if (folder / STATE_NAME).read_bytes() != before or files.get(STATE_NAME) != before:
        return None  # a new state was written meanwhile
    with ResultsStore(f"sqlite:///{scratch / 'cell.db'}") as store:
        if not store.has_run(folder.name):
            return None
        rows = export_rows(store, [folder.name])
    return folder.name, rows, files


def _send_states(scratch: Path, job: RayCell, mailbox: Any, stop: threading.Event) -> None:
    """Every `state_every` seconds: the run's state, when it changed since the last one sent,
    to the mailbox (waiting for the driver's mailbox to hold it)."""
    import ray

    last = None
    while not stop.wait(job.state_every):
        try:
            taken = snapshot(scratch)
            if taken is None or taken[2][STATE_NAME] == last:
                continue
            run_id, rows, files = taken
            ray.get(mailbox.put.remote(job.task.cell.key, job.attempt, run_id, rows, files))
            last = files[STATE_NAME]
        except Exception:
            continue


class Mailbox:
    """A Ray actor on the driver's node: running cells' states wait here until the driver
    takes them (`take`)."""

    def __init__(self) -> None:
        self.items: list[tuple[str, int, str, dict[str, str], dict[str, bytes]]] = []

    def put(
        self, key: str, attempt: int, run_id: str, rows: dict[str, str], files: dict[str, bytes]
    ) -> None:
        self.items = [i for i in self.items if i[0] != key]  # only the latest state of a cell
        self.items.append((key, attempt, run_id, rows, files))

    def take(self) -> list[tuple[str, int, str, dict[str, str], dict[str, bytes]]]:
        items, self.items = self.items, []
        return items
