"""A grid's plan: its cells (method x objective x terrain x seed, each one `coadapt run`),
the spec they expand from, and which cells are finished, which resume an unfinished run and
which start afresh (a stored run answers a cell when its config hash, `cell_hash`, is the
cell's)."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.experiments.cell import Cell
from coadapt_core.experiments.cell_hash import cell_config_hash, run_config_hash
from coadapt_core.methods import METHOD_NAMES
from coadapt_core.plugins import default_plugin
from coadapt_core.results.rows import run_folder_of
from coadapt_core.results.storage import ENV_GRID_CELL, ENV_GRID_ID, ENV_STORE
from coadapt_core.results.store import ResultsStore


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
    #: arguments of the stages after a cell's run (`--verify`, `--verify-budget N`): appended
    #: to every `coadapt run` like extra_args, but no part of a cell's config (its hash)
    stage_args: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        for name in ("methods", "objectives", "terrains", "seeds", "robots"):
            values = getattr(self, name)
            if not values:
                raise UserError(f"grid --{name} needs at least one value", field=name)
            if len(set(values)) != len(values):
                raise UserError(f"grid --{name} lists a value twice: {values}", field=name)
        unknown = [m for m in self.methods if m not in METHOD_NAMES]
        if unknown:
            raise UserError(
                f"unknown method '{unknown[0]}'; methods are {', '.join(METHOD_NAMES)}",
                field="methods",
            )

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
        out = asdict(self)
        if not out["stage_args"]:  # a grid without stages keeps the id it always had
            del out["stage_args"]
        return out

    @property
    def cell_args(self) -> list[str]:
        """What every cell's `coadapt run` gets after its own arguments."""
        return [*self.extra_args, *self.stage_args]

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
    ran_again: list[str] = field(
        default_factory=list
    )  # lost with their node and started again (once per loss)
    outcomes: dict[str, CellOutcome] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "grid_id": self.grid_id,
            "skipped": self.skipped,
            "finished": self.finished,
            "failed": self.failed,
            "resumed": self.resumed,
            "ran_again": self.ran_again,
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
            raise UserError(
                f"--{name} must be comma-separated integers, e.g. 0,1,2; got '{text}'", field=name
            ) from None
    return parts


# -- planning ------------------------------------------------------------------------------
def finished_run(
    store: ResultsStore, cell: Cell, spec: GridSpec | None = None
) -> dict[str, Any] | None:
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
        method=cell.method,
        objectives=cell.objective,
        terrain=cell.terrain,
        seed=cell.seed,
        preset=cell.preset,
        simulator=cell.sim,
        status="finished",
        **({"robot": cell.robot} if cell.robot else {}),
    )
    if expected is None:
        return None
    for run in reversed(candidates):
        if run_config_hash(run) == expected:
            return run
    return None


def unfinished_run(
    store: ResultsStore, cell: Cell, out_dir: str | os.PathLike | None = None
) -> dict[str, Any] | None:
    """The latest run a grid started for this cell that did not finish (killed, crashed)
    and whose run folder holds a state to continue from, so `coadapt run --resume` can
    continue it. The folder is `<out_dir>/<run id>` (or the row's own folder when it is named
    after the run id): a row with a malformed id, or whose folder lies elsewhere, is never
    resumed. A run killed before its first state file (half registered) starts afresh."""
    from coadapt_core.coadapt.state import STATE_FILE

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


def settle_abandoned(
    store: ResultsStore, spec: GridSpec, out_dir: str | os.PathLike | None
) -> list[str]:
    """Runs of this grid's cells that a killed grid left "running" without a state file to
    resume from (killed before their first one, by an older coadapt that registered a run
    before writing its state): marked failed, and their folders removed when they are inside
    `out_dir` and hold nothing but what the start wrote (config.yaml, an empty tb/). The
    cell then starts afresh. Returns the run ids settled."""
    from coadapt_core.coadapt.state import STATE_FILE

    settled = []
    for cell in spec.cells():
        for run in store.list_runs(cell=cell.key, status="running"):
            folder = run_folder_of(run)
            if folder is None or (folder / STATE_FILE).is_file():
                continue
            store.finish_run(
                run["id"],
                {
                    "run_id": run["id"],
                    "error": "killed before its first state file; the grid starts the cell again",
                },
                "failed",
            )
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
        resume = (
            previous["id"] if previous is not None else None
        )  # a checked run id, inside out_dir
        env = {ENV_STORE: store.url, ENV_GRID_ID: grid_id, ENV_GRID_CELL: cell.key}
        log_path = None if log_dir is None else str(Path(log_dir) / f"{cell.slug}.log")
        tasks.append(
            CellTask(
                cell=cell,
                argv=cell.run_args(
                    out_dir=out_dir, resume=resume, extra=spec.cell_args, store=store.url
                ),
                env=env,
                command=list(command) if command is not None else None,
                log_path=log_path,
                timeout=timeout,
                resume=resume,
            )
        )
    return tasks, skipped
