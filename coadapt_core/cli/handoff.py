"""`coadapt handoff`: a finished run's design as a folder for whoever builds the robot."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import typer

from coadapt_core.cli.common import fail

DESIGN_HELP = ("Design values, comma-separated in the order of the run's design space (default: the run's best "
               "design).")


def register(app: typer.Typer) -> None:
    @app.command("handoff")
    def handoff_command(
        run: str = typer.Argument(..., help="Run folder, or a run id under --runs-dir."),
        out: Path = typer.Option(None, "-o", "--out", help="Folder to write (default: ./handoff-<run id>)."),
        design: str = typer.Option(None, "--design", help=DESIGN_HELP),
        sim: list[str] = typer.Option(None, "--sim", help="Simulator to evaluate the design and the nominal one on; "
                                      "repeatable (default: the run's and every other installed one)."),
        agents: int = typer.Option(16, "--agents", help="Paired scenarios per design and simulator."),
        seconds: float = typer.Option(4.0, "--seconds", help="Simulated seconds per scenario."),
        check: bool = typer.Option(True, "--check/--no-check", help="Walk the folder's check.py once written (10 s at 0.5 m/s)."),
        video: bool = typer.Option(True, "--video/--no-video", help="Render a GIF when the run has none of this design."),
        force: bool = typer.Option(False, "--force", help="Replace an earlier handoff folder at --out."),
        runs_dir: Path = typer.Option(Path("runs"), "--runs-dir", help="Where run ids are looked up."),
        as_json: bool = typer.Option(False, "--json", help="Print what was written as JSON on the last line."),
    ) -> None:
        """Write the design's URDF and MJCF, its controller as ONNX (checked against torch),
        policy.json, the design sheet (design.md, design.json), the GIF, a README and check.py."""
        from coadapt_core.handoff.policy import DEPLOY_EXTRA, missing_deploy_modules

        missing = missing_deploy_modules()
        if missing:
            fail(f"coadapt handoff needs {', '.join(missing)}: pip install '{DEPLOY_EXTRA}' (or pip install -e '.[deploy]')")
        if agents < 1:
            fail(f"--agents must be >= 1, got {agents}")
        if not seconds > 0:
            fail(f"--seconds must be > 0, got {seconds}")
        from coadapt_core.handoff.folder import HandoffOptions, find_run, make_handoff, read_run

        run_dir = find_run(run, runs_dir)
        values = None
        if design is not None:
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
        from coadapt_core.cli.report import _quiet_imports
        from coadapt_core.plugins import get_registry

        registry = get_registry()
        for name in sim or registry.names("simulator"):  # a library's import-time banner is not a result
            _quiet_imports(tuple(getattr(registry.get("simulator", name), "quiet_imports", ())))
        target = out if out is not None else Path(f"handoff-{run_dir.name}")
        options = HandoffOptions(design=values, simulators=sim or None, agents=agents, seconds=seconds, check=check,
                                 video=video, force=force)
        result = make_handoff(run_dir, target, options, progress=lambda line: print(line, file=sys.stderr))
        print(f"wrote {result['out']} ({len(result['files'])} files) in {result['seconds']:.1f} s", file=sys.stderr)
        if as_json:
            print(json.dumps(result))
