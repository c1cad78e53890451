"""`coadapt report`: Table 6/7 layouts and figures from stored results."""

from __future__ import annotations

from pathlib import Path

import typer


def _quiet_imports(modules: tuple[str, ...]) -> None:
    """Import `modules` once with the C-level output closed: a line a library prints on
    import (a simulator declares them in `quiet_imports`) would otherwise land in the middle
    of the progress line (and once per worker)."""
    import contextlib
    import importlib
    import os
    import sys

    if not modules:
        return
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = (os.dup(1), os.dup(2))
    except (OSError, ValueError):  # no real stdout/stderr (captured): nothing to protect
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            os.dup2(devnull.fileno(), 2)  # the line goes to stderr, where the progress line is
            for name in modules:
                with contextlib.suppress(ImportError):
                    importlib.import_module(name)
    finally:
        for fd, copy in zip((1, 2), saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)


def _transfer_simulator(transfer_sim: str | None) -> str:
    """The sim-to-sim column's simulator: the one given, else the installed simulator of highest
    default_rank after the default one; its import lines silenced once."""
    from coadapt_core.cli.common import choices, fail
    from coadapt_core.errors import UserError
    from coadapt_core.plugins import get_registry

    registry = get_registry()  # names and classes only: no simulator library is imported here
    if transfer_sim is None:
        try:
            transfer_sim = registry.default("simulator", exclude=(registry.default("simulator"),))
        except UserError:
            fail("the sim-to-sim column needs a second simulator installed (one more simulator plugin or extra); "
                 "pass --no-sim-to-sim or --transfer-sim NAME")
    simulators = choices("simulator")
    if transfer_sim not in simulators:
        fail(f"--transfer-sim '{transfer_sim}' is not a simulator; available: {', '.join(simulators)}")
    _quiet_imports(tuple(getattr(registry.get("simulator", transfer_sim), "quiet_imports", ())))
    return transfer_sim


def _evaluate(results, selection, *, sim_to_sim: bool, transfer_sim, transfer_agents: int, transfer_steps: int,
              common: bool, common_blocks: int, progress) -> tuple[dict | None, dict | None]:
    """The experiments that write rows the report reads: sim-to-sim transfer and the common
    yardstick (each evaluates only runs without their rows). Returns their notes."""
    from coadapt_core.analysis.report import select_runs
    from coadapt_core.results.store import LANDSCAPE_METHOD

    runs = [r for r in select_runs(results, selection)[0] if r["method"] != LANDSCAPE_METHOD]
    transfer_notes = common_notes = None
    if sim_to_sim:
        from coadapt_core.experiments.transfer import transfer_runs

        transfer_notes = transfer_runs(results, runs, simulator=transfer_sim, agents=transfer_agents,
                                       steps=transfer_steps, progress=progress)
    if common:
        from coadapt_core.experiments.yardstick import yardstick_runs

        common_notes = yardstick_runs(results, runs, blocks=common_blocks, progress=progress)
    return transfer_notes, common_notes


def register(app: typer.Typer) -> None:
    @app.command("report")
    def report_command(
        selection: str = typer.Argument(None, metavar="[RUN_OR_GRID]", help="A run id or grid id (default: every finished run)."),
        out: Path = typer.Option(Path("report"), "-o", "--out", help="Folder for the tables, figures and report.html."),
        store: str = typer.Option(None, "--store", help="Results store: a path or SQLAlchemy URL (default $COADAPT_STORE or ./coadapt.db)."),
        sim_to_sim: bool = typer.Option(True, "--sim-to-sim/--no-sim-to-sim", help="Evaluate each best design's policy on a second simulator (Table 6's last column)."),
        transfer_sim: str = typer.Option(None, help="Simulator for the sim-to-sim column (default: the installed simulator of highest default_rank after the default one)."),
        transfer_agents: int = typer.Option(8, help="Agents per design in the sim-to-sim evaluation."),
        transfer_steps: int = typer.Option(400, help="Policy steps per agent in the sim-to-sim evaluation."),
        common: bool = typer.Option(True, "--common-scenarios/--no-common-scenarios", help="Re-evaluate each run's best and nominal design with the run's own policy on one common scenario set per terrain (the methods' common yardstick)."),
        common_blocks: int = typer.Option(8, help="Blocks of 32 scenarios x 250 steps in the common scenario set."),
    ) -> None:
        """Write tables (Markdown, CSV) and figures (PNG, HTML) from a run or grid."""
        from coadapt_core.analysis.report import write_report
        from coadapt_core.cli.common import fail
        from coadapt_core.results.store import ResultsStore, resolve_store_url

        if transfer_agents < 1 or transfer_steps < 1 or common_blocks < 1:
            fail("--transfer-agents, --transfer-steps and --common-blocks must be >= 1")
        url = resolve_store_url(store)
        if url.startswith("sqlite:///") and not Path(url.removeprefix("sqlite:///")).is_file():
            # reading a store that is not there must not leave an empty one behind
            fail(f"no results store at {url.removeprefix('sqlite:///')}: run `coadapt run` or `coadapt grid` first, "
                 "or pass --store (or $COADAPT_STORE)")
        if sim_to_sim:
            transfer_sim = _transfer_simulator(transfer_sim)
        from coadapt_core.cli.progress import ProgressLine

        with ResultsStore(store) as results, ProgressLine("report", None) as line:

            def progress(done: int, total: int, what: str) -> None:
                line.update(done, what, total=total)

            notes, common_notes = _evaluate(
                results, selection, sim_to_sim=sim_to_sim, transfer_sim=transfer_sim, transfer_agents=transfer_agents,
                transfer_steps=transfer_steps, common=common, common_blocks=common_blocks, progress=progress)
            files = write_report(results, selection, out, sim2sim=sim_to_sim, transfer_simulator=transfer_sim,
                                 transfer_notes=notes, progress=progress)
        for name, path in files.items():
            print(f"{name}: {path}")
        for run_id, why in sorted((common_notes or {}).items()):
            print(f"common scenarios, run {run_id}: {why}")
