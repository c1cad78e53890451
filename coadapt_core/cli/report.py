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
    ) -> None:
        """Write tables (Markdown, CSV) and figures (PNG, HTML) from a run or grid."""
        from coadapt_core.analysis.report import write_report
        from coadapt_core.cli.common import fail
        from coadapt_core.results.store import ResultsStore

        if transfer_agents < 1 or transfer_steps < 1:
            fail("--transfer-agents and --transfer-steps must be >= 1")
        from coadapt_core.results.store import resolve_store_url

        url = resolve_store_url(store)
        if url.startswith("sqlite:///") and not Path(url.removeprefix("sqlite:///")).is_file():
            # reading a store that is not there must not leave an empty one behind
            fail(f"no results store at {url.removeprefix('sqlite:///')}: run `coadapt run` or `coadapt grid` first, "
                 "or pass --store (or $COADAPT_STORE)")
        if sim_to_sim:
            from coadapt_core.cli.common import choices
            from coadapt_core.errors import UserError
            from coadapt_core.plugins import get_registry

            registry = get_registry()  # names and classes only: no simulator library is imported here
            if transfer_sim is None:  # a second simulator: the first by default_rank after the default
                try:
                    transfer_sim = registry.default("simulator", exclude=(registry.default("simulator"),))
                except UserError:
                    fail("the sim-to-sim column needs a second simulator installed (one more simulator plugin or extra); "
                         "pass --no-sim-to-sim or --transfer-sim NAME")
            simulators = choices("simulator")
            if transfer_sim not in simulators:
                fail(f"--transfer-sim '{transfer_sim}' is not a simulator; available: {', '.join(simulators)}")
            _quiet_imports(tuple(getattr(registry.get("simulator", transfer_sim), "quiet_imports", ())))
        from coadapt_core.cli.progress import ProgressLine

        with ResultsStore(store) as results, ProgressLine("report", None) as line:

            def progress(done: int, total: int, what: str) -> None:
                line.update(done, what, total=total)

            notes = None
            if sim_to_sim:  # the transfer experiment writes its rows; the report only reads them
                from coadapt_core.analysis.report import select_runs
                from coadapt_core.experiments.transfer import transfer_runs
                from coadapt_core.results.store import LANDSCAPE_METHOD

                runs = [r for r in select_runs(results, selection)[0] if r["method"] != LANDSCAPE_METHOD]
                notes = transfer_runs(results, runs, simulator=transfer_sim, agents=transfer_agents,
                                      steps=transfer_steps, progress=progress)
            files = write_report(results, selection, out, sim2sim=sim_to_sim, transfer_simulator=transfer_sim,
                                 transfer_notes=notes, progress=progress)
        for name, path in files.items():
            print(f"{name}: {path}")
