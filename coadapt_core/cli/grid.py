"""`coadapt grid`: ablation grids (robot x method x objective x terrain x seed)."""

from __future__ import annotations

import json
import shlex

import typer

from coadapt_core.cli.common import ctrl_c_once, default_help, interrupted, invocation, plugin_name
from coadapt_core.methods import METHOD_NAMES


def _check_cells(app: typer.Typer, spec, out: str, store_url: str) -> None:
    """Run `coadapt run <cell's arguments> --check` in this process for every cell: a bad
    objective, terrain, preset, simulator, optimizer or --run-arg is one line naming the cell
    before anything starts, not a failed cell after others ran."""
    import contextlib
    import io

    from coadapt_core.cli.common import fail, run_app

    checked: dict[tuple, str | None] = {}
    for cell in spec.cells():
        argv = [a for a in cell.run_args(out_dir=out, extra=spec.extra_args, store=store_url) if a != "--json"]
        key = tuple(a for a, b in zip(argv, ["", *argv[:-1]], strict=True) if b != "--seed")  # seeds share a verdict
        if key not in checked:
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = run_app(app, [*argv, "--check"])
            lines = [line for line in err.getvalue().splitlines() if line.strip()]
            checked[key] = None if code == 0 else (lines[-1] if lines else f"exit code {code}")
        if checked[key] is not None:
            message = checked[key].removeprefix("error: ").removeprefix("error (coadapt run): ")
            fail(f"grid cell {cell.key}: {message}; nothing was started")


def register(app: typer.Typer) -> None:
    @app.command("grid")
    def grid_command(
        methods: str = typer.Option(",".join(METHOD_NAMES), help="Comma list of methods."),
        objectives: str = typer.Option("tracking,power,torque", help="Comma list of objectives (one cell each)."),
        terrains: str = typer.Option("flat,slope,random", help="Comma list of terrains."),
        seeds: str = typer.Option("0,1,2", help="Comma list of integer seeds."),
        preset: str = typer.Option("quick", help="`coadapt run` preset for every cell."),
        sim: str = typer.Option(None, help=default_help("simulator", "Simulator for every cell.")),
        robots: str = typer.Option(None, "--robots", "--robot", help=default_help("robot", "Comma list of robots (one cell each; the cell key names it).")),
        optimizer: str = typer.Option(None, help="Optimizer for every cell (default: each method's own)."),
        executor: str = typer.Option("local", help="local (process pool on this machine) or ray."),
        address: str = typer.Option(None, help="Ray cluster address (default: start a local Ray instance)."),
        workers: int = typer.Option(None, help="Cells at once (default: the number of cores)."),
        store: str = typer.Option(None, "--store", help="Results store: a path or SQLAlchemy URL (default $COADAPT_STORE or ./coadapt.db)."),
        out: str = typer.Option("runs", "--out", help="Folder for run folders and cell logs."),
        timeout: float = typer.Option(None, help="Seconds before a cell is killed (default: none)."),
        dry_run: bool = typer.Option(False, "--dry-run", help="Print the plan (skip / resume / new per cell) and run nothing."),
        as_json: bool = typer.Option(False, "--json", help="Print a JSON summary as the last line."),
        run_arg: list[str] = typer.Option(None, "--run-arg", help="Extra argument passed to every `coadapt run` (repeatable), e.g. --run-arg=--device=cuda."),
    ) -> None:
        """Run an ablation grid locally or on a Ray cluster, skipping cells the store holds
        as finished and resuming cells a killed grid left unfinished."""
        from rich.console import Console

        from coadapt_core.experiments.grid import (
            GridSpec,
            check_grid_options,
            parse_list,
            plan_grid,
            run_grid,
        )
        from coadapt_core.results.store import ResultsStore

        command_line = shlex.join(["coadapt", *invocation()])  # before the cells' checks run `coadapt run`
        spec = GridSpec(
            methods=parse_list(methods, "methods"),
            objectives=parse_list(objectives, "objectives"),
            terrains=parse_list(terrains, "terrains"),
            seeds=parse_list(seeds, "seeds", integers=True),
            preset=preset,
            sim=plugin_name("simulator", sim),
            optimizer=optimizer,
            extra_args=list(run_arg or []),
            robots=parse_list(robots, "robots") if robots else [plugin_name("robot", None)],
        )
        check_grid_options(executor=executor, workers=workers, timeout=timeout, address=address)
        results = ResultsStore(store)
        _check_cells(app, spec, out, results.url)  # every cell's arguments, before any cell starts
        console = Console(stderr=True)
        if dry_run:
            tasks, skipped = plan_grid(results, spec, out_dir=out)
            for cell in skipped:
                print(f"skip    {cell.key}")
            for task in tasks:
                print(f"{'resume' if task.resume else 'new':7} {task.cell.key}" + (f" (run {task.resume})" if task.resume else ""))
            print(f"grid {spec.grid_id}: {len(skipped)} finished, {len(tasks)} to run")
            return
        counts = {"finished": 0, "failed": 0, "skipped": 0}
        started: list[str] = []  # cells handed to the executor, in the order it starts them
        done: set[str] = set()
        from coadapt_core.cli.progress import ProgressLine
        from coadapt_core.experiments.grid import default_workers

        width = workers or default_workers()

        def short(key: str) -> str:
            fields = dict(part.split("=", 1) for part in key.split("|"))
            robot = f"{fields['robot']}/" if "robot" in fields else ""
            return f"{robot}{fields['method']}/{fields['objective']}/{fields['terrain']}/s{fields['seed']}"

        with ProgressLine("grid", None, unit=" cells") as line:

            def on_event(kind, cell, outcome):
                if kind == "started":
                    started.append(cell.key)
                    line.total = len(started)  # shown from the first finished cell on
                    return
                counts[kind] += 1
                if kind == "skipped":
                    return
                done.add(cell.key)
                running = [k for k in started if k not in done][:width]
                line.update(len(done), f"failed {counts['failed']}, skipped {counts['skipped']}; running "
                            + (", ".join(short(k) for k in running) or "-"))
                if kind == "failed":
                    console.print(f"[red]failed[/red] {cell.key}: {outcome.error}")

            try:
                with ctrl_c_once():
                    report = run_grid(
                        spec, results, executor=executor, workers=workers, address=address, out_dir=out,
                        timeout=timeout, on_event=on_event,
                    )
            except KeyboardInterrupt as exc:
                line.close()
                stopped = getattr(exc, "report", None)
                done_cells = len(stopped.finished) + len(stopped.skipped) if stopped is not None else 0
                results.close()
                interrupted(f"grid {spec.grid_id} stopped ({done_cells} cells finished; the running cells keep their "
                            "last state and resume, the rest start)",
                            command_line)
        results.close()
        console.print(
            f"grid {report.grid_id}: {len(report.finished)} finished, {len(report.skipped)} skipped "
            f"(already finished), {len(report.resumed)} resumed, {len(report.failed)} failed"
        )
        if as_json:
            print(json.dumps(report.to_dict()))
        if report.failed:
            raise typer.Exit(1)
