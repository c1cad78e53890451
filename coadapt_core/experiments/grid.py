"""Ablation grids (method x objective x terrain x seed): expand, skip what the store
already holds, run each cell as `coadapt run ... --json` in its own process, locally or on
Ray, and resume what a killed grid left unfinished.

A clean process per cell isolates crashes (a diverging simulation or an out-of-memory kill
takes one cell down, not the grid) and keeps both executors trivial: they only start
commands. The cell's run finds the store, grid and cell through environment variables
(`COADAPT_STORE`, `COADAPT_GRID_ID`, `COADAPT_GRID_CELL`) read by the store's recorder.
"""

from __future__ import annotations

import contextlib
import hashlib
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
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.methods import METHOD_NAMES
from coadapt_core.plugins import default_plugin
from coadapt_core.results.store import (
    ENV_GRID_CELL,
    ENV_GRID_ID,
    ENV_STORE,
    ResultsStore,
    run_folder_of,
)

EXECUTORS = ("local", "ray")
#: how a cell process starts coadapt when no command is given: the interpreter running the
#: grid (or the Ray worker), so it works without the console script on PATH
ENTRY_CODE = "import sys; from coadapt_core.cli import main; sys.exit(main(sys.argv[1:]))"


@dataclass(frozen=True)
class Cell:
    """One run of the grid."""

    method: str
    objective: str
    terrain: str
    seed: int
    preset: str
    sim: str
    optimizer: str | None = None  # None: the method's default (`coadapt_core.methods.optimizer_for`)
    robot: str | None = None  # None: `coadapt run`'s default robot (a cell made by a GridSpec always names it)

    @property
    def key(self) -> str:
        """Stable text key; what the store's `runs.cell` and `grid_cells.cell` hold (the
        robot first, when the cell names one)."""
        parts = [f"robot={self.robot}"] if self.robot else []
        parts += [
            f"method={self.method}",
            f"objective={self.objective}",
            f"terrain={self.terrain}",
            f"seed={self.seed}",
            f"preset={self.preset}",
            f"sim={self.sim}",
        ]
        if self.optimizer:
            parts.append(f"optimizer={self.optimizer}")
        return "|".join(parts)

    @property
    def slug(self) -> str:
        return self.key.replace("|", "_").replace("=", "-").replace(",", "+")

    def run_args(
        self, *, out_dir: str | None = None, resume: str | None = None, extra: Sequence[str] = (), store: str | None = None
    ) -> list[str]:
        """The `coadapt run` arguments of this cell. With `store`, the run records into it,
        and an optimizer that keeps a study (it declares a `storage` option, as BO does)
        keeps it there too."""
        args = [
            "run",
            "--method", self.method,
            "--objective", self.objective,
            "--terrain", self.terrain,
            "--seed", str(self.seed),
            "--preset", self.preset,
            "--sim", self.sim,
        ]  # fmt: skip
        if self.robot:
            args += ["--robot", self.robot]
        if self.optimizer:
            args += ["--optimizer", self.optimizer]
        if out_dir:
            args += ["--out", out_dir]
        if store:
            args += ["--store", store]
            if _keeps_study(self.method, self.optimizer):
                args += ["--bo-storage", store]
        if resume:
            args += ["--resume", resume]
        return [*args, *extra, "--json"]


def _keeps_study(method: str, optimizer: str | None) -> bool:
    """The optimizer a cell of `method` runs declares a `storage` option (a study kept in a
    database); a cell without an optimizer runs the method's default one."""
    from coadapt_core.methods import optimizer_for
    from coadapt_core.plugins import get_registry

    try:
        cls = get_registry().get("optimizer", optimizer_for(method, optimizer or ""))
    except UserError:
        return False
    return any(spec.name == "storage" for spec in getattr(cls, "option_specs", ()))


@dataclass
class GridSpec:
    """What to run. Every combination of the lists is one cell."""

    methods: list[str]
    objectives: list[str]
    terrains: list[str]
    seeds: list[int]
    preset: str = "quick"
    #: default: the installed simulator of highest `default_rank` (docs/plugins.md)
    sim: str = field(default_factory=lambda: default_plugin("simulator"))
    optimizer: str | None = None
    extra_args: list[str] = field(default_factory=list)  # appended to every `coadapt run`
    #: default: the installed robot of highest `default_rank`; every cell names its robot
    robots: list[str] = field(default_factory=lambda: [default_plugin("robot")])

    def __post_init__(self) -> None:
        for name in ("methods", "objectives", "terrains", "seeds", "robots"):
            values = getattr(self, name)
            if not values:
                raise UserError(f"grid --{name} needs at least one value", field=name)
            if len(set(values)) != len(values):
                raise UserError(f"grid --{name} lists a value twice: {values}", field=name)
        unknown = [m for m in self.methods if m not in METHOD_NAMES]
        if unknown:
            raise UserError(f"unknown method '{unknown[0]}'; methods are {', '.join(METHOD_NAMES)}", field="methods")

    def cells(self) -> list[Cell]:
        return [
            Cell(m, o, t, int(s), self.preset, self.sim, self.optimizer, r)
            for r in self.robots
            for o in self.objectives
            for t in self.terrains
            for m in self.methods
            for s in self.seeds
        ]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GridSpec:
        return cls(**data)

    @property
    def grid_id(self) -> str:
        """Deterministic: the same grid command names the same grid, so re-running it resumes."""
        digest = hashlib.sha1(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()[:10]
        return f"grid-{digest}"


@dataclass
class CellTask:
    """What an executor runs: one process."""

    cell: Cell
    argv: list[str]  # `coadapt` arguments
    env: dict[str, str]  # added to the environment
    command: list[str] | None  # program prefix; None = this interpreter running coadapt's CLI
    log_path: str | None
    timeout: float | None = None
    resume: str | None = None


@dataclass
class CellOutcome:
    cell_key: str
    returncode: int
    seconds: float
    result: dict[str, Any] | None  # the JSON line `coadapt run --json` printed last
    error: str | None  # last lines of stderr when the cell failed


@dataclass
class GridReport:
    grid_id: str
    skipped: list[str] = field(default_factory=list)  # finished before this invocation
    finished: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    resumed: list[str] = field(default_factory=list)
    outcomes: dict[str, CellOutcome] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "grid_id": self.grid_id,
            "skipped": self.skipped,
            "finished": self.finished,
            "failed": self.failed,
            "resumed": self.resumed,
            "errors": {k: o.error for k, o in self.outcomes.items() if o.returncode != 0},
        }


def parse_list(text: str, name: str, *, integers: bool = False) -> list[Any]:
    parts = [p.strip() for p in str(text).split(",") if p.strip()]
    if not parts:
        raise UserError(f"--{name} needs a comma-separated list, got '{text}'", field=name)
    if integers:
        try:
            return [int(p) for p in parts]
        except ValueError:
            raise UserError(f"--{name} must be comma-separated integers, e.g. 0,1,2; got '{text}'", field=name) from None
    return parts


# -- planning ------------------------------------------------------------------------------
#: config keys that say where or how a run is stored or executed, not what it computes
CONFIG_HASH_IGNORES = frozenset({"out", "store", "run_id", "run_dir", "device", "design_space", "grid_id", "grid_cell",
                                 "bo_storage", "logger"})


def config_hash(config: dict[str, Any]) -> str:
    """A short hash of a resolved run config (preset, YAML and options applied), without the
    keys that do not change what the run computes (`CONFIG_HASH_IGNORES`)."""
    kept = {k: v for k, v in sorted(config.items()) if k not in CONFIG_HASH_IGNORES}
    return hashlib.sha1(json.dumps(kept, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _extra_overrides(extra: Sequence[str]) -> dict[str, Any] | None:
    """`coadapt run` options given as grid --run-arg (`--population 3`, `--no-mixed`,
    `--train-epochs 3`) as config overrides (keys of the settings tree, dotted for a section);
    None when one of them is not a config option (the hash is then unknown)."""
    from coadapt_core.coadapt.config import CoadaptConfig
    from coadapt_core.settings import leaves

    settings = {leaf.param: leaf for leaf in leaves(CoadaptConfig) if leaf.extra.get("cli", True)}
    out: dict[str, Any] = {}
    items = list(extra)
    i = 0
    while i < len(items):
        token = items[i]
        if not token.startswith("--"):
            return None
        name, eq, value = token[2:].partition("=")
        param = name.replace("-", "_")
        negated = settings.get(param[3:]) if param.startswith("no_") else None
        leaf = settings.get(param)
        if not eq and negated is not None and negated.kind == "bool":
            out[negated.key] = False
        elif not eq and leaf is not None and leaf.kind == "bool":
            out[leaf.key] = True
        elif leaf is not None and leaf.key != "preset":
            if not eq:
                i += 1
                if i >= len(items):
                    return None
                value = items[i]
            out[leaf.key] = value
        else:
            return None
        i += 1
    return out


def cell_config_hash(cell: Cell, extra: Sequence[str] = ()) -> str | None:
    """The config hash `coadapt run` will record for this cell, or None when it cannot be
    known here (an --run-arg option that is not a config field, a config that does not validate)."""
    from coadapt_core.coadapt.config import make_config

    overrides = _extra_overrides(extra)
    if overrides is None:
        return None
    overrides.update(method=cell.method, objective=cell.objective, terrain=cell.terrain, seed=cell.seed, sim=cell.sim)
    if cell.robot:
        overrides["robot"] = cell.robot
    if cell.optimizer:
        overrides["optimizer"] = cell.optimizer
    try:
        return config_hash(make_config(cell.preset, None, overrides).to_dict())
    except (UserError, TypeError, ValueError):
        return None


def run_config_hash(run: dict[str, Any]) -> str | None:
    """The config hash of a stored run (its recorded config, resolved again), or None."""
    from coadapt_core.coadapt.config import config_from_dict

    config = run.get("config")
    if not isinstance(config, dict) or not config:
        return None
    try:
        return config_hash(config_from_dict(config).to_dict())
    except (UserError, TypeError, ValueError):
        return None


def finished_run(store: ResultsStore, cell: Cell, spec: GridSpec | None = None) -> dict[str, Any] | None:
    """A finished run that answers this cell: launched for it by this very grid (same grid
    id: the same command line), or any other run whose whole resolved config matches the
    cell's (`config_hash`: method, objective, terrain, seed, preset values, --run-arg options).
    A hand-made run with another population, or a cell of a grid with other --run-arg
    options, is not reused: the cell runs."""
    grid_id = spec.grid_id if spec is not None else None
    expected = cell_config_hash(cell, spec.extra_args if spec is not None else ())
    extra = list(spec.extra_args) if spec is not None else []
    by_cell = store.list_runs(cell=cell.key, status="finished")
    for run in reversed(by_cell):
        if grid_id is not None and run.get("grid_id") == grid_id:
            return run
        other = store.get_grid(run["grid_id"]) if run.get("grid_id") else None
        other_spec = other.get("spec") if isinstance(other, dict) else None
        if isinstance(other_spec, dict) and list(other_spec.get("extra_args") or []) == extra:
            return run  # another grid ran this cell with the same command line
    candidates = by_cell + store.list_runs(
        method=cell.method, objectives=cell.objective, terrain=cell.terrain, seed=cell.seed, preset=cell.preset,
        simulator=cell.sim, status="finished", **({"robot": cell.robot} if cell.robot else {}),
    )
    if expected is None:
        return None
    for run in reversed(candidates):
        if run_config_hash(run) == expected:
            return run
    return None


def unfinished_run(store: ResultsStore, cell: Cell, out_dir: str | os.PathLike | None = None) -> dict[str, Any] | None:
    """The latest run a grid started for this cell that did not finish (killed, crashed)
    and whose run folder holds a state to continue from, so `coadapt run --resume` can
    continue it. The folder is `<out_dir>/<run id>` (or the row's own folder when it is named
    after the run id): a row with a malformed id, or whose folder lies elsewhere, is never
    resumed. A run killed before its first state file (half registered) starts afresh."""
    from coadapt_core.coadapt.loop import STATE_FILE

    for run in reversed(store.list_runs(cell=cell.key)):
        if run["status"] == "finished":
            return None
        folder = run_folder_of(run)
        if folder is None:
            return None  # not a folder this grid may touch: start afresh
        if out_dir is not None and folder.parent != Path(out_dir).resolve():
            return None
        if not (folder / STATE_FILE).is_file():
            return None  # nothing to resume from; start afresh
        return {**run, "run_dir": str(folder)}
    return None


def settle_abandoned(store: ResultsStore, spec: GridSpec, out_dir: str | os.PathLike | None) -> list[str]:
    """Runs of this grid's cells that a killed grid left "running" without a state file to
    resume from (killed before their first one, by an older coadapt that registered a run
    before writing its state): marked failed, and their folders removed when they are inside
    `out_dir` and hold nothing but what the start wrote (config.yaml, an empty tb/). The
    cell then starts afresh. Returns the run ids settled."""
    from coadapt_core.coadapt.loop import STATE_FILE

    settled = []
    for cell in spec.cells():
        for run in store.list_runs(cell=cell.key, status="running"):
            folder = run_folder_of(run)
            if folder is None or (folder / STATE_FILE).is_file():
                continue
            store.finish_run(run["id"], {"run_id": run["id"], "error": "killed before its first state file; the "
                                         "grid starts the cell again"}, "failed")
            settled.append(run["id"])
            if out_dir is None or folder.parent != Path(out_dir).resolve() or not folder.is_dir():
                continue
            leftovers = [p for p in folder.rglob("*") if p.is_file() and p.name != "config.yaml"]
            if not leftovers:
                import shutil

                shutil.rmtree(folder, ignore_errors=True)
    return settled


def plan_grid(
    store: ResultsStore,
    spec: GridSpec,
    *,
    out_dir: str | None = None,
    command: Sequence[str] | None = None,
    timeout: float | None = None,
    log_dir: str | os.PathLike | None = None,
) -> tuple[list[CellTask], list[Cell]]:
    """(tasks to run, cells already finished)."""
    grid_id = spec.grid_id
    tasks: list[CellTask] = []
    skipped: list[Cell] = []
    for cell in spec.cells():
        if finished_run(store, cell, spec) is not None:
            skipped.append(cell)
            continue
        previous = unfinished_run(store, cell, out_dir)
        resume = previous["id"] if previous is not None else None  # a checked run id, inside out_dir
        env = {ENV_STORE: store.url, ENV_GRID_ID: grid_id, ENV_GRID_CELL: cell.key}
        log_path = None if log_dir is None else str(Path(log_dir) / f"{cell.slug}.log")
        tasks.append(
            CellTask(
                cell=cell,
                argv=cell.run_args(out_dir=out_dir, resume=resume, extra=spec.extra_args, store=store.url),
                env=env,
                command=list(command) if command is not None else None,
                log_path=log_path,
                timeout=timeout,
                resume=resume,
            )
        )
    return tasks, skipped


# -- executing one cell -----------------------------------------------------------------------
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


def execute_cell(task: CellTask) -> CellOutcome:
    """Run one cell's process to the end (module level, so Ray can ship it to a worker)."""
    prefix = task.command if task.command is not None else [sys.executable, "-c", ENTRY_CODE]
    env = {**os.environ, **task.env}
    start = time.perf_counter()
    if _STOPPING.is_set():
        return CellOutcome(task.cell.key, NOT_STARTED, 0.0, None, "not started: the grid was interrupted")
    try:
        proc = subprocess.Popen([*prefix, *task.argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
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
            shown = [*task.command, *task.argv] if task.command is not None else [sys.executable, "-m", "coadapt_core", *task.argv]
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
def local_executor(tasks: Sequence[CellTask], workers: int) -> Iterator[tuple[CellTask, CellOutcome]]:
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
    *, executor: str, workers: int | None, timeout: float | None, address: str | None, connect_timeout: float = 5.0
) -> None:
    """One-line `UserError` for a bad executor, worker count, cell timeout, or a Ray address
    that does not answer within `connect_timeout` seconds (checked before anything starts)."""
    if executor not in EXECUTORS:
        raise UserError(f"--executor '{executor}' is not one of {', '.join(EXECUTORS)}", field="executor")
    if workers is not None and workers < 1:
        raise UserError(f"--workers must be >= 1, got {workers}", field="workers")
    if timeout is not None and not (math.isfinite(timeout) and timeout > 0):
        raise UserError(f"--timeout must be a number of seconds > 0, got {timeout}", field="timeout")
    if executor == "ray" and address and address not in ("auto", "local"):
        check_ray_address(address, connect_timeout)


def check_ray_address(address: str, connect_timeout: float = 10.0) -> None:
    """The Ray head at `address` (host:port, or ray://host:port) accepts a TCP connection;
    otherwise one line instead of Ray's own minutes of retries."""
    import socket

    target = address.split("://", 1)[1] if "://" in address else address
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise UserError(f"--address '{address}' is not host:port (e.g. 10.0.0.5:6379 or ray://head:10001)", field="address")
    from concurrent.futures import ThreadPoolExecutor
    from concurrent.futures import TimeoutError as Timeout

    def connect() -> None:
        with socket.create_connection((host, int(port)), timeout=connect_timeout):
            pass

    pool = ThreadPoolExecutor(max_workers=1)  # name resolution has no timeout of its own
    try:
        pool.submit(connect).result(timeout=connect_timeout + 1)
    except Timeout:
        raise UserError(f"cannot reach a Ray cluster at --address '{address}' (no answer in {connect_timeout:g} s); "
                        "check the head node's host and port, or use --executor local", field="address") from None
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise UserError(f"cannot reach a Ray cluster at --address '{address}' ({reason}); check the head node's "
                        "host and port, or use --executor local", field="address") from None
    finally:
        pool.shutdown(wait=False)


def ray_executor(
    tasks: Sequence[CellTask], workers: int, address: str | None = None
) -> Iterator[tuple[CellTask, CellOutcome]]:
    """One Ray task (1 CPU) per cell: on a cluster at `address`, else a local Ray instance
    with `workers` CPUs. Cells on other nodes need a store they can reach (PostgreSQL, or
    SQLite on a shared filesystem)."""
    try:
        import ray
    except ImportError:
        raise UserError(
            "--executor ray needs Ray: pip install 'coadapt[ray]' (or use --executor local)", field="executor"
        ) from None
    started_here = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address:
            kwargs["address"] = address
        else:
            kwargs["num_cpus"] = max(1, workers)
        try:
            ray.init(**kwargs)
        except Exception as exc:  # a bad address or an unreachable cluster
            raise UserError(f"cannot connect to Ray at '{address or 'local'}': {exc}", field="address") from None
        started_here = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(execute_cell)
        pending = {remote.remote(t): t for t in tasks}
        try:
            yield from _ray_results(ray, pending)
        except BaseException:  # Ctrl-C: each cell's task passes it on to its process
            for ref in pending:
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=False)
            raise
    finally:
        if started_here:
            ray.shutdown()


def _ray_results(ray: Any, pending: dict[Any, CellTask]) -> Iterator[tuple[CellTask, CellOutcome]]:
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        ref = done[0]
        task = pending.pop(ref)
        try:
            outcome = ray.get(ref)
        except Exception as exc:  # the worker died (node lost, OOM kill)
            outcome = CellOutcome(task.cell.key, 1, 0.0, None, f"ray task failed: {exc}")
        yield task, outcome


Executor = Callable[[Sequence[CellTask], int], Iterator[tuple[CellTask, CellOutcome]]]


def default_workers() -> int:
    """One cell per core: a cell's learner and physics keep a core busy on their own."""
    return max(1, os.cpu_count() or 1)


def run_grid(
    spec: GridSpec,
    store: ResultsStore,
    *,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    out_dir: str | None = "runs",
    command: Sequence[str] | None = None,
    timeout: float | None = None,
    log_dir: str | os.PathLike | None = None,
    on_event: Callable[[str, Cell, CellOutcome | None], None] | None = None,
) -> GridReport:
    """Run every cell the store does not already hold as finished; returns what happened.
    `on_event(kind, cell, outcome)` reports "skipped", "started", "finished", "failed"."""
    check_grid_options(executor=executor, workers=workers, timeout=timeout, address=address)
    workers = workers or default_workers()
    grid_id = spec.grid_id
    store.save_grid(grid_id, spec.to_dict())
    if log_dir is None and out_dir is not None:
        log_dir = Path(out_dir) / "grid-logs" / grid_id
    settle_abandoned(store, spec, out_dir)
    tasks, skipped = plan_grid(store, spec, out_dir=out_dir, command=command, timeout=timeout, log_dir=log_dir)
    report = GridReport(grid_id)
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
    if not tasks:
        return report
    # threads per cell: share the cores between the cells running at once
    threads = str(max(1, (os.cpu_count() or 1) // min(workers, len(tasks))))
    for task in tasks:
        task.env.setdefault("OMP_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", threads))
        if min(workers, len(tasks)) > 1 and "GOMP_SPINCOUNT" not in os.environ:
            # cells started together share the cores: their OpenMP workers sleep when idle
            # instead of spinning (coadapt_core.launch.omp_wait_settings)
            task.env.setdefault("OMP_WAIT_POLICY", os.environ.get("OMP_WAIT_POLICY", "PASSIVE"))
    if executor == "local":
        stream = local_executor(tasks, workers)
    else:
        stream = ray_executor(tasks, workers, address)
    try:
        _collect(store, grid_id, stream, report, on_event)
    except BaseException as exc:  # Ctrl-C: the running cells were told (`stop_cells`)
        if hasattr(stream, "close"):
            stream.close()
        for task in tasks:
            if task.cell.key in report.outcomes:
                continue
            started = store.list_runs(cell=task.cell.key)
            run = started[-1] if started else None
            if run is not None and run["status"] == "running" and run.get("grid_id") == grid_id:
                store.set_status(run["id"], "interrupted")  # killed before it could say so
            store.set_cell(grid_id, task.cell.key, status="interrupted", run_id=run["id"] if run else None,
                           error="the grid was interrupted")
        if isinstance(exc, KeyboardInterrupt):
            raise GridInterrupted(report) from None
        raise
    return report


class GridInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped the grid: `report` says what had finished; running the same grid
    again skips those and resumes the rest."""

    def __init__(self, report: GridReport):
        super().__init__(report.grid_id)
        self.report = report


def _collect(store: ResultsStore, grid_id: str, stream: Iterator[tuple[CellTask, CellOutcome]], report: GridReport,
             on_event: Callable[[str, Cell, CellOutcome | None], None] | None) -> None:
    for task, outcome in stream:
        key = task.cell.key
        report.outcomes[key] = outcome
        run_id = (outcome.result or {}).get("run_id")
        if run_id is None:
            started = store.list_runs(cell=key)
            run_id = started[-1]["id"] if started else None
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
