"""`coadapt handoff`: a finished run's design as a folder for whoever builds the robot."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common import fail
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.settings import Float, Int, setting, settings, shared


@settings
class HandoffCommand:
    """`coadapt handoff`'s settings."""

    run: str = setting(help="Run folder, or a run id under --runs-dir.", argument="run")
    out: Path | None = setting(
        None, "Folder to write (default: ./handoff-<run id>).", names=("-o", "--out")
    )
    design: str | None = setting(
        None,
        "Design values, comma-separated in the order of the run's design space (default: "
        "the run's best design).",
    )
    pick: str | None = setting(
        None,
        "A design of a multi-objective run's Pareto front instead of the one it returns: "
        "its index N (0-based, in the order `coadapt run` printed the front, by the first cost; "
        "0 is the returned design), or 'knee' (the design nearest the ideal point, each "
        "objective scaled to the front's range).",
    )
    sim: list[str] | None = setting(
        None,
        "Simulator to evaluate the design and the nominal one on; repeatable (default: "
        "the run's and every other installed one).",
        names=("--sim",),
    )
    agents: Int = setting(
        16,
        "Paired scenarios per design and simulator (the sim-to-sim protocol of `coadapt "
        "report`'s column: same scenarios, cost rule and fall gate).",
    )
    seconds: Float | None = setting(
        None,
        "Simulated seconds per scenario (default: the run's own evaluation length, as "
        "`coadapt report`'s sim-to-sim column).",
    )
    policy: str = setting(
        "universal",
        "The controller handed off: universal (the run's policy) or specialist (the design's "
        "specialist from `coadapt verify`, the nominal design judged by its own).",
    )
    check: bool = setting(True, "Walk the folder's check.py once written (10 s at 0.5 m/s).")
    video: bool = setting(True, "Render a GIF when the run has none of this design.")
    force: bool = setting(False, "Replace an earlier handoff folder at --out.", names=("--force",))
    runs_dir: Path = setting(Path("runs"), "Where run ids are looked up.")
    threads: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)
    as_json: Any = shared(CommonOptions)


def _picked(run_dir: Path, pick: str) -> Any:
    """The design `--pick` names in the run's stored Pareto front (its summary's)."""
    import numpy as np

    from coadapt_core.handoff.run_info import read_run
    from coadapt_core.pareto import pick_index

    _, summary = read_run(run_dir)
    front = summary.get("pareto_front")
    if not isinstance(front, dict) or not front.get("designs") or not front.get("costs"):
        fail(
            f"--pick: run {run_dir.name} has no Pareto front (one objective); leave out --pick to "
            "hand off its best design, or give --design"
        )
    names = list(front["costs"][0])
    costs = np.array([[float(c[n]) for n in names] for c in front["costs"]], dtype=float)
    try:
        index = pick_index(pick, costs)
    except ValueError as exc:
        fail(f"--pick: {exc}")
    return np.asarray(front["designs"][index], dtype=float)


def _quiet_simulators(sim: list[str] | None) -> None:
    """The simulators' import-time banners silenced (a library's banner is not a result)."""
    from coadapt_core.cli.report import _quiet_imports
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    for name in sim or registry.names("simulator"):
        _quiet_imports(tuple(getattr(registry.get("simulator", name), "quiet_imports", ())))


def _quiet(line: str) -> None:
    """--quiet: the progress lines are not printed."""


def register(app: typer.Typer) -> None:
    declared = options_of(HandoffCommand)

    def handoff_command(**values: Any) -> None:
        """Write the design's URDF and MJCF, its controller as ONNX (checked against torch),
        policy.json, the design sheet (design.md, design.json), the GIF, a README and check.py."""
        o = filled(values, declared)  # a bad value is refused before torch loads
        from coadapt_core.handoff.policy import DEPLOY_EXTRA, missing_deploy_modules

        run, out, design, sim, agents, seconds = (
            o["run"],
            o["out"],
            o["design"],
            o["sim"],
            o["agents"],
            o["seconds"],
        )
        missing = missing_deploy_modules()
        if missing:
            fail(
                f"coadapt handoff needs {', '.join(missing)}: pip install '{DEPLOY_EXTRA}' (or pip "
                "install -e '.[deploy]')"
            )
        if agents < 1:
            fail(f"--agents must be >= 1, got {agents}")
        if o["policy"] not in ("universal", "specialist"):
            fail(f"--policy must be universal or specialist, got '{o['policy']}'")
        if seconds is not None and not seconds > 0:
            fail(f"--seconds must be > 0, got {seconds}")
        from coadapt_core.handoff.folder import HandoffOptions, make_handoff
        from coadapt_core.handoff.run_info import find_run, read_run

        run_dir = find_run(run, o["runs_dir"])
        values = None
        if o["pick"] is not None:
            if design is not None:
                fail("--pick and --design both name a design; give one")
            values = _picked(run_dir, o["pick"])
        elif design is not None:
            from coadapt_core.cli.robot import parse_design
            from coadapt_core.plugins import get_registry

            config, _ = read_run(run_dir)
            registry = get_registry()
            robot = registry.create("robot", config.get("robot") or registry.default("robot"))
            values = parse_design(robot, design)
        if sim:
            from coadapt_core.cli.common import resolve

            for name in sim:
                resolve("simulator", name)
        _quiet_simulators(sim)
        target = out if out is not None else Path(f"handoff-{run_dir.name}")
        options = HandoffOptions(
            design=values,
            simulators=sim or None,
            agents=agents,
            seconds=seconds,
            check=o["check"],
            video=o["video"],
            force=o["force"],
            policy=o["policy"],
        )
        from coadapt_core.threads import apply_threads

        apply_threads(o["threads"])  # both engines' physics and torch, as `coadapt run`'s
        result = make_handoff(
            run_dir,
            target,
            options,
            progress=_quiet if o["quiet"] else lambda line: print(line, file=sys.stderr),
        )
        print(
            f"wrote {result['out']} ({len(result['files'])} files) in {result['seconds']:.1f} s",
            file=sys.stderr,
        )
        if o["as_json"]:
            print(json.dumps(result))

    register_command(app, "handoff", handoff_command, declared)
