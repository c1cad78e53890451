"""`coadapt handoff`: a finished run's chosen design as one folder for whoever builds it.

The folder holds the design's MJCF and URDF with their assets (from the robot plugin), the
universal policy specialised to the design as ONNX (checked against torch with onnxruntime
on recorded observations), `policy.json` (observation and action layouts, PD gains, rates,
clock, command ranges, terrain), the design sheet (`design.md`, `design.json`: parameters,
links, motors, validation, costs against the nominal design on paired scenarios per
simulator, provenance), the run's best-vs-nominal GIF, a README and `check.py`, which walks
the robot with the ONNX controller in MuJoCo without importing coadapt.

The folder is built under a temporary name beside the target and renamed when complete, so
a refused or failed handoff leaves nothing half-written.

The parts live beside it: the run's facts and provenance in `run_info`, the run resolved
(plugins, policies, the design) in `resolve`, the ONNX controller and its check in
`controller`, policy.json in `spec`, what is measured (rollout, evaluations, check.py, the
GIF) in `measure`, the README in `readme`, the design sheet in `sheet`, the model files in
`model_files`.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.errors import UserError
from coadapt_core.handoff import sheet
from coadapt_core.handoff.controller import export_controller
from coadapt_core.handoff.measure import (
    copy_or_render_video,
    evaluate_on,
    front_final_check,
    front_index,
    run_check,
    run_final_check,
)
from coadapt_core.handoff.model_files import write_model_files
from coadapt_core.handoff.readme import readme_text
from coadapt_core.handoff.resolve import ResolvedRun, judges, resolve_run
from coadapt_core.handoff.run_info import provenance, read_run
from coadapt_core.handoff.spec import FORMAT, foot_facts, policy_spec
from coadapt_core.io import jsonable
from coadapt_core.robot import joint_table
from coadapt_core.sim_to_sim import protocol_of

#: the check's forward command, m/s (clipped to the trained range)
CHECK_VX = 0.5


@dataclass
class HandoffOptions:
    design: np.ndarray | None = None  # None: the run's best design
    simulators: Sequence[str] | None = (
        None  # None: the run's simulator and every other installed one
    )
    agents: int = 16  # paired scenarios per design and simulator (the sim-to-sim protocol's)
    seconds: float | None = None  # simulated seconds per scenario (None: the run's eval_steps)
    check: bool = True  # walk the folder's check.py once it is written
    check_seconds: float = 10.0
    video: bool = True  # render a GIF when the run has none for the design
    force: bool = False  # replace an existing folder
    #: the controller handed off: the run's universal policy, or the design's specialist from
    #: `coadapt verify` ("specialist")
    policy: str = "universal"


def _evaluations(
    run: ResolvedRun,
    options: HandoffOptions,
    objectives: list[str],
    control_dt: float,
    say: Callable[[str], None],
) -> list[dict[str, Any]]:
    """The run's final check (for its best design) and fresh paired evaluations of the
    design against the nominal one on each simulator."""
    evaluations = []
    index = front_index(run.summary, run.design)
    if run.is_best and run.summary.get("best_costs"):
        evaluations.append(run_final_check(run.summary, run.config, run.sim_name))
    elif index is not None:  # another design of the run's Pareto front (--pick)
        evaluations.append(front_final_check(run.summary, run.config, run.sim_name, index))
    simulators = (
        list(options.simulators)
        if options.simulators
        else [run.sim_name] + [n for n in run.registry.names("simulator") if n != run.sim_name]
    )
    steps = None if options.seconds is None else max(1, int(round(options.seconds / control_dt)))
    protocol = protocol_of(run.config, options.agents, steps)
    for name in simulators:
        say(
            f"evaluating the design and the nominal one on {name} (sim-to-sim protocol, as "
            f"`coadapt report`'s column: {protocol.scenarios} paired scenarios x "
            f"{protocol.steps} steps; not comparable with `coadapt run` or `coadapt eval`)"
        )
        ev = evaluate_on(
            name,
            robot=run.robot,
            checkpoint=run.checkpoint,
            nominal_checkpoint=run.nominal_checkpoint,
            objectives=objectives,
            design=run.design,
            nominal=run.nominal,
            terrain=run.terrain,
            seed=run.seed,
            agents=protocol.scenarios,
            steps=protocol.steps,
            config=run.config,
        )
        evaluations.append(ev)
        say(f"  {name}: {ev.get('error') or ev.get('sim_to_sim') or _costs_text(ev)}")
    return evaluations


def _costs_text(ev: dict[str, Any]) -> str:
    """The costs of an evaluation without per-scenario costs (no protocol figures)."""
    return "; ".join(
        f"{k} {v['design']:.4g} vs nominal {v['nominal']:.4g}" for k, v in ev["objectives"].items()
    )


def _sheet_data(
    run: ResolvedRun, model: Any, spec: dict[str, Any], tools: Any, **measured: Any
) -> dict[str, Any]:
    """design.json: the design, its body (from the simulator's model `tools`), joints,
    validation, and what was measured (`evaluations`, `onnx`, `picture`, `provenance`)."""
    body = tools.link_facts(model)
    body["standing_base_height"] = float(model.standing_base_height)
    return {
        "format": FORMAT,
        "robot": run.robot.name,
        "design_text": spec["design_text"],
        "design": [float(x) for x in run.design],
        "nominal_design": [float(x) for x in run.nominal],
        "is_run_best": run.is_best,
        "pareto_front_index": front_index(run.summary, run.design),
        "policies": judges(run),
        "terrain": run.terrain,
        "parameters": sheet.design_parameters(run.space, run.design),
        "body": body,
        "robot_info": jsonable(model.info if isinstance(model.info, dict) else {}),
        "joints": joint_table(model),
        "validation": run.robot.validate(run.design).to_dict(),
        "evaluations": measured["evaluations"],
        "onnx": measured["onnx"],
        "picture": measured["picture"],
        "provenance": measured["provenance"],
    }


def _listing(
    files: dict[str, str], model_files: Any, partial: Path, video_name: str, check_by: str | None
) -> list[tuple[str, str]]:
    """The README's table of the folder's files."""
    return [
        (files["mjcf"], "the design's MJCF, from the robot plugin"),
        (files["urdf"], "the design's URDF (Pinocchio, ROS and the engines that read it)"),
        *([("assets/", "files the models reference")] if model_files.assets else []),
        ("policy.onnx", "the controller: observation in, actions and joint targets out"),
        (
            "policy.json",
            "observation and action layouts, PD gains, rates, gait clock, commands, terrain",
        ),
        ("design.md", "the design sheet (design.json: the same as data)"),
        *(
            [
                (
                    "check.py",
                    f"walks the model with the ONNX controller in {check_by} (no coadapt needed)",
                )
            ]
            if check_by
            else []
        ),
        ("reference.npz", "recorded observations and the torch policy's actions on them"),
        *(
            [(f"{video_name}.gif", "the design (left) and the nominal one (right) walking")]
            if (partial / f"{video_name}.gif").is_file()
            else []
        ),
    ]


def _model_files(run: ResolvedRun, partial: Path, say: Callable[[str], None]) -> tuple[Any, Any]:
    """The design's model and its files (with their assets) in the folder."""
    try:
        model = run.robot.build(run.design)
    except NotImplementedError:
        raise UserError(
            f"robot '{run.robot.name}' supplies no model files (its build gives no MJCF and URDF); "
            "there is nothing to hand off",
            field="robot",
        ) from None
    model_files = write_model_files(run.robot, model, partial)
    say(
        f"model: {model_files.mjcf.name}, {model_files.urdf.name}"
        + (
            f" and {len(model_files.assets)} asset files"
            if model_files.assets
            else " (no asset files referenced)"
        )
    )
    return model, model_files


def _write_folder(
    run: ResolvedRun, options: HandoffOptions, partial: Path, say: Callable[[str], None]
) -> dict[str, Any]:
    """Every file of the handoff folder into `partial`; returns design.json's data."""
    from coadapt_core.physics.model_tools import tools_for
    from coadapt_core.viz.video import VIDEO_NAME

    model, model_files = _model_files(run, partial, say)
    tools_sim, tools = tools_for(run.registry, model, prefer=run.sim_name)
    # the simulator check.py walks the model in
    check_by = tools_sim if tools.HANDOFF_CHECK else None
    walked, verification, onnx_path = export_controller(run, partial, say)
    files = {
        "mjcf": model_files.mjcf.name,
        "urdf": model_files.urdf.name,
        "onnx": onnx_path.name,
        "reference": "reference.npz",
    }
    spec = policy_spec(
        robot=run.robot,
        model=model,
        design=run.design,
        space=run.space,
        state=run.state,
        rollout=walked,
        terrain=run.terrain,
        verification=verification,
        foot=foot_facts(model, tools),
        files=files,
    )
    spec["policies"] = judges(run)
    (partial / "policy.json").write_text(json.dumps(jsonable(spec), indent=2) + "\n")
    if check_by:
        shutil.copy(tools.HANDOFF_CHECK, partial / "check.py")
    measured = _measure(run, options, partial, walked["control_dt"], say)
    sheet_data = _sheet_data(run, model, spec, tools, onnx=verification, **measured)
    if options.check and check_by:
        sheet_data["controller_check"] = _check_controller(partial, options, spec, say)
    (partial / "design.json").write_text(json.dumps(jsonable(sheet_data), indent=2) + "\n")
    (partial / "design.md").write_text(sheet.render_markdown(jsonable(sheet_data)))
    listing = _listing(files, model_files, partial, VIDEO_NAME, check_by)
    usage = tools.handoff_usage(spec["rates"], files["mjcf"]) if check_by else ""
    (partial / "README.md").write_text(readme_text(spec, jsonable(sheet_data), listing, usage))
    return sheet_data


def _measure(
    run: ResolvedRun,
    options: HandoffOptions,
    partial: Path,
    control_dt: float,
    say: Callable[[str], None],
) -> dict[str, Any]:
    """What the design sheet reports beside the design: its evaluations against the nominal
    design, its picture (the GIF, copied or rendered into `partial`) and its provenance."""
    from coadapt_core.viz.video import VIDEO_NAME

    objectives = list((run.summary.get("best_costs") or {}).keys()) or [
        str(run.config.get("objective") or "")
    ]
    evaluations = _evaluations(run, options, objectives, control_dt, say)
    policies = {"best": run.checkpoint, "nominal": run.nominal_checkpoint}
    gif_note = copy_or_render_video(
        run.run_dir,
        partial,
        run.config,
        run.summary,
        run.design,
        run.nominal,
        policies,
        run.is_best,
        options.video,
        VIDEO_NAME,
    )
    say(f"picture: {gif_note}")
    origin = provenance(
        run.run_dir,
        run.config,
        run.summary,
        robot=run.robot,
        objectives=objectives,
        seed=run.seed,
        simulator=run.sim_name,
        checkpoint=run.checkpoint,
        state=run.state,
        nominal_checkpoint=run.nominal_checkpoint if run.own_policies else None,
    )
    return {"evaluations": evaluations, "picture": gif_note, "provenance": origin}


def _check_controller(
    partial: Path, options: HandoffOptions, spec: dict[str, Any], say: Callable[[str], None]
) -> dict[str, Any]:
    """The folder's check.py run once, forward at `CHECK_VX` (within the trained range)."""
    vx = min(CHECK_VX, spec["commands"]["trained"]["vx"][1])
    check = run_check(partial, options.check_seconds, vx)
    say(
        "check.py: "
        + (
            check["error"]
            if "error" in check
            else f"survival {check['survival']:.2f}, mean forward speed "
            f"{check['vx_mean']:.3f} m/s under {vx:g} m/s for {check['seconds']:g} s"
        )
    )
    return check


# -- the folder --------------------------------------------------------------------------------
def make_handoff(
    run_dir: Path,
    out: Path,
    options: HandoffOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Write the handoff folder `out` for the run in `run_dir`; returns what was written and
    measured (the `--json` line)."""
    from coadapt_core.handoff.policy import ONNX_TOLERANCE

    options = options or HandoffOptions()
    say = progress or (lambda _line: None)
    started = time.perf_counter()
    run_dir = Path(run_dir).resolve()
    out = Path(out).absolute()
    config, summary = read_run(run_dir)
    _check_target(out, run_dir, options.force)
    run = resolve_run(run_dir, config, summary, options.design, options.policy)
    used = judges(run)
    say(f"policy: {run.policy} ({used['design']}; nominal design judged by {used['nominal']})")
    partial = out.parent / f".{out.name}.partial-{os.getpid()}"
    if partial.exists():
        shutil.rmtree(partial)
    partial.mkdir(parents=True)
    try:
        sheet_data = _write_folder(run, options, partial, say)
        if out.exists():
            shutil.rmtree(out) if out.is_dir() else out.unlink()
        partial.rename(out)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    evaluations = sheet_data["evaluations"]
    return {
        "out": str(out),
        "run_id": sheet_data["provenance"]["run_id"],
        "robot": run.robot.name,
        "design": [float(x) for x in run.design],
        "is_run_best": run.is_best,
        "pareto_front_index": sheet_data.get("pareto_front_index"),
        "max_abs_action_difference": sheet_data["onnx"]["max_abs_action_difference"],
        "tolerance": ONNX_TOLERANCE,
        "evaluations": [
            {
                k: ev.get(k)
                for k in ("simulator", "source", "error", "design_fall_rate", "nominal_fall_rate")
            }
            | {"objectives": ev.get("objectives")}
            for ev in evaluations
        ],
        "controller_check": sheet_data.get("controller_check"),
        "files": sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()),
        "seconds": time.perf_counter() - started,
    }


def _check_target(out: Path, run_dir: Path, force: bool) -> None:
    """`out` may be written: new, an empty folder, or (with --force) an earlier handoff
    folder; never the run folder, a folder holding it, or anything else that exists."""
    if out == run_dir or out in run_dir.parents:
        raise UserError(f"-o {out} is the run folder or holds it; give a new folder", field="out")
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return
    if not force:
        raise UserError(
            f"-o {out} exists; give another folder, or --force to replace an earlier handoff "
            "folder",
            field="out",
        )
    try:
        earlier = json.loads((out / "policy.json").read_text()).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        earlier = False
    if not earlier:
        raise UserError(
            f"-o {out} exists and is not a handoff folder (no policy.json of {FORMAT}); --force "
            "replaces only those",
            field="out",
        )


__all__ = ["HandoffOptions", "make_handoff"]
