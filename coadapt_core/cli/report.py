"""`coadapt report`: Table 6/7 layouts and figures from stored results."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import typer

from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.settings import Int, setting, settings, shared


@settings
class ReportCommand:
    """`coadapt report`'s settings."""

    selection: str | None = setting(
        None, "A run id or grid id (default: every finished run).", argument="[RUN_OR_GRID]"
    )
    out: Path = setting(
        Path("report"), "Folder for the tables, figures and report.html.", names=("-o", "--out")
    )
    store: Any = shared(CommonOptions)
    threads: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)
    sim_to_sim: bool = setting(
        True, "Evaluate each best design's policy on a second simulator (Table 6's last column)."
    )
    transfer_sim: str | None = setting(
        None,
        "Simulator for the sim-to-sim column (default: the installed simulator of "
        "highest default_rank after the default one).",
    )
    transfer_agents: Int = setting(
        16,
        "Paired scenarios per design in the sim-to-sim evaluation (the protocol `coadapt "
        "handoff` uses: block 1 of the run's seed, the run's cost rule and fall gate).",
    )
    transfer_steps: Int | None = setting(
        None,
        "Policy steps per scenario in the sim-to-sim evaluation (default: the run's own "
        "evaluation length, as `coadapt handoff`).",
    )
    common: bool = setting(
        True,
        "Re-evaluate each run's best and nominal design with the run's own policy on one common "
        "scenario set per terrain (the methods' common yardstick).",
        names=("--common-scenarios/--no-common-scenarios",),
    )
    common_blocks: Int = setting(
        8, "Blocks of 32 scenarios x 250 steps in the common scenario set."
    )
    evaluate: bool = setting(
        True,
        "Simulate the sim-to-sim and common-scenario rows a run lacks before the tables are "
        "drawn (once per run: they are stored and read back by later reports); "
        "--no-evaluate draws from the stored rows alone and simulates nothing.",
        names=("--evaluate/--no-evaluate",),
    )


def _check_out(out: Path) -> None:
    """--out is a folder the report can write (made if missing): a probe file is written and
    removed; otherwise one line, exit 2."""
    import tempfile

    from coadapt_core.cli.common import fail

    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".coadapt-probe-"):
            pass
    except OSError as exc:
        fail(
            f"--out {out}: cannot write the report there ({exc.strerror or type(exc).__name__}); "
            "give a folder you can write"
        )


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
    from coadapt_core.cli.common import fail
    from coadapt_core.cli.help import choices
    from coadapt_core.errors import UserError
    from coadapt_core.plugins import get_registry

    registry = get_registry()  # names and classes only: no simulator library is imported here
    if transfer_sim is None:
        try:
            transfer_sim = registry.default("simulator", exclude=(registry.default("simulator"),))
        except UserError:
            fail(
                "the sim-to-sim column needs a second simulator installed (one more simulator "
                "plugin or extra); pass --no-sim-to-sim or --transfer-sim NAME"
            )
    simulators = choices("simulator")
    if transfer_sim not in simulators:
        fail(
            f"--transfer-sim '{transfer_sim}' is not a simulator; available: "
            f"{', '.join(simulators)}"
        )
    _quiet_imports(tuple(getattr(registry.get("simulator", transfer_sim), "quiet_imports", ())))
    return transfer_sim


def _evaluate(
    results,
    selection,
    *,
    sim_to_sim: bool,
    transfer_sim,
    transfer_agents: int,
    transfer_steps: int | None,
    common: bool,
    common_blocks: int,
    progress,
) -> tuple[dict | None, dict | None]:
    """The experiments that write rows the report reads: sim-to-sim transfer and the common
    yardstick (each evaluates only runs without their rows). Returns their notes."""
    from coadapt_core.analysis.facts import select_runs
    from coadapt_core.results.schema import LANDSCAPE_METHOD

    runs = [r for r in select_runs(results, selection)[0] if r["method"] != LANDSCAPE_METHOD]
    _say_missing(results, runs, transfer_sim if sim_to_sim else None, common)
    transfer_notes = common_notes = None
    if sim_to_sim:
        from coadapt_core.experiments.transfer import transfer_runs

        transfer_notes = transfer_runs(
            results,
            runs,
            simulator=transfer_sim,
            agents=transfer_agents,
            steps=transfer_steps,
            progress=progress,
        )
    if common:
        from coadapt_core.experiments.yardstick import yardstick_runs

        common_notes = yardstick_runs(results, runs, blocks=common_blocks, progress=progress)
    return transfer_notes, common_notes


def _say_missing(results, runs: list, transfer_sim: str | None, common: bool) -> None:
    """One line before anything is simulated: which runs lack which stored rows (they are
    evaluated now, once, and stored), or that every row is stored and nothing is simulated."""
    import sys

    from coadapt_core.experiments.transfer import transfer_rows
    from coadapt_core.experiments.yardstick import yardstick_rows

    missing = []
    if transfer_sim is not None:
        lack = [
            r["id"]
            for r in runs
            if r.get("simulator") != transfer_sim
            and len(transfer_rows(results, r["id"], transfer_sim)) < 2
        ]
        missing += [f"sim-to-sim on {transfer_sim}: {', '.join(lack)}"] if lack else []
    if common:
        lack = [r["id"] for r in runs if len(yardstick_rows(results, r["id"])) < 2]
        missing += [f"common scenarios: {', '.join(lack)}"] if lack else []
    if missing:
        print(
            "report: simulating the rows these runs lack, once (stored: later reports read them "
            f"back; --no-evaluate skips them): {'; '.join(missing)}",
            file=sys.stderr,
        )
    elif runs and (transfer_sim is not None or common):
        print(
            "report: every run's sim-to-sim and common-scenario rows are stored; nothing is "
            "simulated",
            file=sys.stderr,
        )


def register(app: typer.Typer) -> None:
    options = options_of(ReportCommand)

    def report_command(**values: Any) -> None:
        """Write tables (Markdown, CSV) and figures (PNG, HTML) from a run or grid."""
        from coadapt_core.cli.common import fail

        o = SimpleNamespace(**filled(values, options))
        if o.transfer_agents < 1 or (o.transfer_steps or 1) < 1 or o.common_blocks < 1:
            fail("--transfer-agents, --transfer-steps and --common-blocks must be >= 1")
        # after the checks, so that a refusal answers at once
        from coadapt_core.analysis.report import write_report
        from coadapt_core.results.storage import resolve_store_url
        from coadapt_core.results.store import ResultsStore

        url = resolve_store_url(o.store)
        if url.startswith("sqlite:///") and not Path(url.removeprefix("sqlite:///")).is_file():
            # reading a store that is not there must not leave an empty one behind
            fail(
                f"no results store at {url.removeprefix('sqlite:///')}: run `coadapt run` or "
                "`coadapt grid` first, or pass --store (or $COADAPT_STORE)"
            )
        _check_out(
            o.out
        )  # before anything is evaluated (the sim-to-sim and common columns take minutes)
        if o.sim_to_sim:
            o.transfer_sim = _transfer_simulator(o.transfer_sim)
        if o.threads is not None:  # the sim-to-sim and common-scenario rows it simulates
            from coadapt_core.threads import apply_threads

            apply_threads(o.threads)
        from coadapt_core.cli.progress import ProgressLine

        with (
            ResultsStore(o.store) as results,
            ProgressLine("report", None, enabled=not o.quiet) as line,
        ):

            def progress(done: int, total: int, what: str) -> None:
                line.update(done, what, total=total)

            notes, common_notes = _evaluate(
                results,
                o.selection,
                sim_to_sim=o.sim_to_sim and o.evaluate,
                transfer_sim=o.transfer_sim,
                transfer_agents=o.transfer_agents,
                transfer_steps=o.transfer_steps,
                common=o.common and o.evaluate,
                common_blocks=o.common_blocks,
                progress=progress,
            )
            files = write_report(
                results,
                o.selection,
                o.out,
                sim2sim=o.sim_to_sim,
                transfer_simulator=o.transfer_sim,
                transfer_notes=notes,
                progress=progress,
            )
        for name, path in files.items():
            print(f"{name}: {path}")
        for run_id, why in sorted((common_notes or {}).items()):
            print(f"common scenarios, run {run_id}: {why}")

    register_command(app, "report", report_command, options)
