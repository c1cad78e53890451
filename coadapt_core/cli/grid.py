"""`coadapt grid`: ablation grids (robot x method x objective x terrain x seed)."""

from __future__ import annotations

import json
import shlex
from typing import Any

import typer

from coadapt_core.cli.common import ctrl_c_once, interrupted, invocation
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import options_of, settings_from
from coadapt_core.cli.options import register as register_command
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.methods import METHOD_NAMES
from coadapt_core.physics.terrain import TERRAINS
from coadapt_core.plugins import default_plugin, get_registry
from coadapt_core.settings import Float, Int, setting, settings, shared


@settings
class GridSettings:
    """Every setting of `coadapt grid`: each field is an option (`--run-arg` aside); the
    settings it shares with `coadapt run` are `CoadaptConfig`'s own declarations."""

    methods: str = setting(",".join(METHOD_NAMES), "Comma list of methods.")
    objectives: str = setting(
        default_factory=lambda: ",".join(get_registry().defaults("objective")),
        help="Comma list of objectives (one cell each).",
    )
    terrains: str = setting(",".join(TERRAINS), "Comma list of terrains.")
    seeds: str = setting("0,1,2", "Comma list of integer seeds.")
    preset: str = setting("quick", "`coadapt run` preset for every cell.")
    sim: Any = shared(CoadaptConfig)
    robots: str = setting(
        default_factory=lambda: default_plugin("robot"),
        plugin="robot",
        aliases=("--robot",),
        help="Comma list of robots (one cell each; the cell key names it).",
    )
    optimizer: str | None = setting(None, "Optimizer for every cell (default: each method's own).")
    executor: str = setting("local", "local (process pool on this machine) or ray.")
    address: str | None = setting(
        None,
        "Ray cluster address, e.g. 10.0.0.5:6379 (default: $RAY_ADDRESS, else a "
        "local Ray instance).",
    )
    state_every: Float = setting(
        300.0,
        "Ray: seconds between a running cell's last state sent back to the driver, "
        "from which it resumes if its node is lost (0: never; it then starts over).",
        names=("--state-every",),
        ge=0,
    )
    workers: Int | None = setting(
        None,
        "Cells at once (default: as many as fit, cells at once x --threads <= "
        "cores; on Ray: the number of cores).",
    )
    threads: Int | None = setting(
        None,
        "CPU threads per cell, physics and torch: each cell's `coadapt run --threads` "
        "(default: locally the cores divided among the cells at once; on Ray 1).",
        ge=1,
    )
    store: Any = shared(CommonOptions)
    out: str = setting("runs", "Folder for run folders and cell logs.")
    timeout: Float | None = setting(None, "Seconds before a cell is killed (default: none).")
    dry_run: bool = setting(
        False,
        "Print the plan (skip / resume / new / refuse per cell) and run nothing; exit 2 "
        "when a cell would be refused.",
        names=("--dry-run",),
    )
    as_json: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)
    verify: bool = setting(
        False,
        "Each cell's run ends with `coadapt verify` (`coadapt run --verify`): specialists at its "
        "best and nominal designs; the rows come back with the cell's.",
        names=("--verify",),
    )
    verify_budget: Int | None = setting(
        None, "--verify: interactions per specialist (default: the preset's)."
    )
    run_arg: list[str] | None = setting(
        None,
        "Extra argument passed to every `coadapt run` (repeatable), e.g. --run-arg=--device=cuda.",
        names=("--run-arg",),
    )


def _check_cells(
    app: typer.Typer, spec, out: str, store_url: str, *, dry_run: bool = False
) -> dict[str, str]:
    """Run `coadapt run <cell's arguments> --check` in this process for every cell: a bad
    objective, terrain, preset, simulator, optimizer, --run-arg or a robot without a policy
    for the cell is one line naming the cell before anything starts, not a failed cell after
    others ran. With `dry_run`: {cell key: why `coadapt run` refuses it} for the plan."""
    import contextlib
    import io

    from coadapt_core.cli.common import fail, run_app

    checked: dict[tuple, str | None] = {}
    refused: dict[str, str] = {}
    for cell in spec.cells():
        argv = [
            a
            for a in cell.run_args(out_dir=out, extra=spec.cell_args, store=store_url)
            if a != "--json"
        ]
        key = tuple(
            a for a, b in zip(argv, ["", *argv[:-1]], strict=True) if b != "--seed"
        )  # seeds share a verdict
        if key not in checked:
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = run_app(app, [*argv, "--check"])
            lines = [line for line in err.getvalue().splitlines() if line.strip()]
            checked[key] = None if code == 0 else (lines[-1] if lines else f"exit code {code}")
        if checked[key] is not None:
            message = checked[key].removeprefix("error: ").removeprefix("error (coadapt run): ")
            if not dry_run:
                fail(f"grid cell {cell.key}: {message}; nothing was started")
            refused[cell.key] = message
    return refused


def _spec(s: GridSettings, run_arg: list[str] | None) -> Any:
    from coadapt_core.experiments.grid_plan import GridSpec, parse_list

    return GridSpec(
        methods=parse_list(s.methods, "methods"),
        objectives=parse_list(s.objectives, "objectives"),
        terrains=parse_list(s.terrains, "terrains"),
        seeds=parse_list(s.seeds, "seeds", integers=True),
        preset=s.preset,
        sim=s.sim,
        optimizer=s.optimizer,
        extra_args=list(run_arg or []),
        robots=parse_list(s.robots, "robots"),
        stage_args=(["--verify"] if s.verify else [])
        + (["--verify-budget", str(s.verify_budget)] if s.verify and s.verify_budget else []),
    )


def _print_plan(results: Any, spec: Any, out: str, refused: dict[str, str]) -> None:
    """--dry-run: each cell skipped (finished), resumed, new or refused (`coadapt run` would
    refuse it, e.g. its robot has no policy: the grid would not start), and the counts;
    exit 2 when a cell is refused."""
    from coadapt_core.experiments.grid_plan import plan_grid

    tasks, skipped = plan_grid(results, spec, out_dir=out)
    for cell in skipped:
        print(f"skip    {cell.key}")
    for task in tasks:
        if task.cell.key in refused:
            print(f"refuse  {task.cell.key}: {refused[task.cell.key]}")
            continue
        print(
            f"{'resume' if task.resume else 'new':7} {task.cell.key}"
            + (f" (run {task.resume})" if task.resume else "")
        )
    runnable = [t for t in tasks if t.cell.key not in refused]
    print(
        f"grid {spec.grid_id}: {len(skipped)} finished, {len(runnable)} to run"
        + (
            f", {len(tasks) - len(runnable)} refused (the grid would not start)"
            if len(runnable) < len(tasks)
            else ""
        )
    )
    if len(runnable) < len(tasks):
        raise typer.Exit(2)


def _short(key: str) -> str:
    """A cell key as the progress line shows it: robot/method/objective/terrain/s<seed>."""
    fields = dict(part.split("=", 1) for part in key.split("|"))
    robot = f"{fields['robot']}/" if "robot" in fields else ""
    return f"{robot}{fields['method']}/{fields['objective']}/{fields['terrain']}/s{fields['seed']}"


def _run(s: GridSettings, spec: Any, results: Any, command_line: str) -> Any:
    """Run the grid's cells with a progress line (failed cells said as they fail); Ctrl-C
    says how many finished and how to continue."""
    from rich.console import Console

    from coadapt_core.cli.progress import ProgressLine
    from coadapt_core.experiments.grid import run_grid
    from coadapt_core.experiments.grid_exec import default_workers

    console = Console(stderr=True)
    counts = {"finished": 0, "failed": 0, "skipped": 0}
    started: list[str] = []  # cells handed to the executor, in the order it starts them
    done: set[str] = set()
    width = s.workers or default_workers()
    with ProgressLine("grid", None, unit=" cells", enabled=not s.quiet) as line:

        def on_event(kind, cell, outcome):
            if kind == "rerun":  # a Ray cell lost with its node
                console.print(
                    f"[yellow]ran again[/yellow] {cell.key}: {outcome.error}", soft_wrap=True
                )
                return
            if kind == "started":
                started.append(cell.key)
                line.total = len(started)  # shown from the first finished cell on
                return
            counts[kind] += 1
            if kind == "skipped":
                return
            done.add(cell.key)
            running = [k for k in started if k not in done][:width]
            line.update(
                len(done),
                f"failed {counts['failed']}, skipped {counts['skipped']}; running "
                + (", ".join(_short(k) for k in running) or "-"),
            )
            if kind == "failed":
                console.print(f"[red]failed[/red] {cell.key}: {outcome.error}")

        try:
            with ctrl_c_once():
                return run_grid(
                    spec,
                    results,
                    executor=s.executor,
                    workers=s.workers,
                    threads=s.threads,
                    address=s.address,
                    out_dir=s.out,
                    timeout=s.timeout,
                    on_event=on_event,
                    state_every=s.state_every,
                )
        except KeyboardInterrupt as exc:
            line.close()
            stopped = getattr(exc, "report", None)
            done_cells = len(stopped.finished) + len(stopped.skipped) if stopped is not None else 0
            results.close()
            interrupted(
                f"grid {spec.grid_id} stopped ({done_cells} cells finished; the running cells keep "
                "their last state and resume, the rest start)",
                command_line,
            )


def register(app: typer.Typer) -> None:
    options = options_of(GridSettings)

    def grid_command(**values: Any) -> None:
        """Run an ablation grid locally or on a Ray cluster, skipping cells the store holds
        as finished and resuming cells a killed grid left unfinished."""
        from rich.console import Console

        from coadapt_core.experiments.grid_exec import check_grid_options
        from coadapt_core.results.store import ResultsStore

        command_line = shlex.join(
            ["coadapt", *invocation()]
        )  # before the cells' checks run `coadapt run`
        s = settings_from(GridSettings, values, options)
        spec = _spec(s, s.run_arg)
        check_grid_options(
            executor=s.executor, workers=s.workers, timeout=s.timeout, address=s.address
        )
        results = ResultsStore(s.store)
        from coadapt_core.cli import app as coadapt  # the whole command line, `coadapt run` in it

        refused = _check_cells(
            coadapt, spec, s.out, results.url, dry_run=s.dry_run
        )  # every cell, before any starts
        if s.dry_run:
            _print_plan(results, spec, s.out, refused)
            return
        report = _run(s, spec, results, command_line)
        results.close()
        Console(stderr=True).print(
            f"grid {report.grid_id}: {len(report.finished)} finished, {len(report.skipped)} "
            f"skipped (already finished), {len(report.resumed)} resumed, {len(report.failed)} "
            "failed"
            + (
                f", {len(report.ran_again)} ran again ({', '.join(sorted(set(report.ran_again)))})"
                if report.ran_again
                else ""
            )
        )
        if s.as_json:
            print(json.dumps(report.to_dict()))
        if report.failed:
            raise typer.Exit(1)

    register_command(app, "grid", grid_command, options)
