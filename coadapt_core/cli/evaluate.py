"""`coadapt eval`: roll a policy out on one design under a fixed command and print
survival, speed and costs (each objective's cost per step +- its standard error over the
agents) and `coadapt run`'s walking gate; `--video` renders agent 0. The command's settings
are declared once (`EvalCommand`): option, --help and docs/settings.md.
"""

from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import typer

from coadapt_core.cli.common import check_device_option, fail, plugin_name, resolve, simulator_for
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.cli.policy_source import EVAL_CHECKPOINTS, eval_checkpoint_path
from coadapt_core.cli.progress import ProgressLine
from coadapt_core.settings import Float, Int, setting, settings, shared
from coadapt_core.threads import apply_threads


@settings
class EvalCommand:
    """`coadapt eval`'s settings; one declaration each gives the option, its help and its row
    in docs/settings.md."""

    checkpoint: Path | None = setting(
        None,
        "Checkpoint or weights file, a `coadapt train` folder, or a `coadapt run` "
        "folder or run id under ./runs (its last policy) (default: the policy shipped for "
        "the robot and terrain).",
    )
    robot: str | None = setting(
        None,
        "Robot (default: the one the checkpoint was trained for; without --checkpoint, "
        "the installed robot of highest default_rank).",
        plugin="robot",
    )
    design: str | None = setting(None, "Design, comma-separated (default: the nominal design).")
    sim: str | None = setting(None, "Simulator backend.", plugin="simulator")
    terrain: str = setting("flat", "Terrain: flat, slope or random.")
    command: str = setting("0.5,0,0", "Velocity command vx,vy,yaw_rate (m/s, m/s, rad/s).")
    agents: Int = setting(50, "Agents (environments) on the design.")
    seconds: Float = setting(20.0, "Simulated seconds per agent.")
    device: str = setting("cpu", "Policy device: cpu or cuda.")
    seed: Any = shared(CommonOptions)
    randomize: bool = setting(True, "Domain randomization (Table 2) as in training.")
    threads: Any = shared(CommonOptions)
    as_json: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)
    video: Path | None = setting(
        None, "Render agent 0 offscreen into a .gif (or .mp4 with ffmpeg)."
    )
    objective: list[str] | None = setting(
        None,
        "Also evaluate this installed objective (repeatable, or a comma list): its "
        "cost per step and standard error over the agents, in `costs` / `costs_se` with "
        "--json.",
        plugin="objective",
        names=("--objective",),
    )


def _names(objective: list[str] | None) -> list[str]:
    """The objective names of repeated or comma-listed --objective options."""
    return [n.strip() for text in objective or [] for n in text.split(",") if n.strip()]


def _eval_checks(
    agents: int,
    seconds: float,
    video: Path | None,
    device: str,
    objective: list[str] | None,
    command: str,
) -> list[float]:
    """`coadapt eval`'s option checks (one line, exit 2, before any rollout); the command's
    three values."""
    if agents < 1:
        fail(f"--agents must be >= 1, got {agents}")
    if not (0 < seconds <= 3600):
        fail(f"--seconds must lie in (0, 3600], got {seconds}")
    if video is not None and video.suffix.lower() not in (".gif", ".mp4"):
        fail(f"--video '{video}' must end in .gif or .mp4")
    if video is not None and video.suffix.lower() == ".mp4" and shutil.which("ffmpeg") is None:
        fail(
            "--video .mp4 needs ffmpeg on PATH, which is not installed; write a .gif instead"
        )  # before the rollout
    check_device_option(device)
    for name in _names(objective):
        resolve("objective", name)  # unknown: one line listing the installed ones
    try:
        values = [float(v) for v in command.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        fail(f"--command '{command}' must be three numbers vx,vy,yaw_rate, e.g. 0.5,0,0")
    return values


def _eval_robot(checkpoint: Path | None) -> str:
    """The robot a checkpoint records; without one, the default robot."""
    if checkpoint is not None and checkpoint.is_file():
        from coadapt_core.learning.checkpoints import read_checkpoint

        try:
            return str(read_checkpoint(checkpoint)["robot"])
        except Exception as exc:
            fail(
                f"--checkpoint {checkpoint} is not a coadapt checkpoint "
                f"({type(exc).__name__}: {exc})"
            )
    from coadapt_core.plugins import get_registry

    installed = get_registry().names("robot")
    if checkpoint is not None and len(installed) != 1:
        fail(f"--checkpoint {checkpoint} does not exist; give {EVAL_CHECKPOINTS}")
    return plugin_name(
        "robot", None
    )  # the default robot (highest default_rank), as every command takes


def _shipped(robot_obj: Any, robot: str, terrain: str, design_values: Any) -> Path:
    """The policy the robot ships for the terrain and the design's space, or one line, exit 2."""
    from coadapt_core.learning import shipped_checkpoint

    mixed = robot_obj.design_space_for(design_values).is_mixed
    checkpoint = shipped_checkpoint(robot_obj, terrain, mixed=mixed)
    if checkpoint is None:
        space = "mixed" if mixed else "continuous"
        fail(
            f"robot '{robot}' ships no policy for terrain '{terrain}' and the {space} design "
            f"space; pass --checkpoint (e.g. one `coadapt train --robot {robot} --terrain "
            f"{terrain}` wrote)"
        )
    return checkpoint


def _measures() -> dict[str, str]:
    """Row labels that say which measure a figure is: an objective's summary key that is not
    a `_cost` (tracking's `tracking_error`: P_cmd per step) and the walking gate's ratio."""
    from coadapt_core.coadapt.reliability import RATIO_MEANS
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    out = {"tracking_ratio": RATIO_MEANS}
    for name in registry.names("objective"):
        cls = registry.get("objective", name)
        key, text = getattr(cls, "summary_key", ""), getattr(cls, "description", "")
        if key and not key.endswith("_cost"):
            symbol = text.split(" = ")[0] if " = " in text else f"{name} cost"
            out[key] = f"{symbol} per step (eval), {getattr(cls, 'unit', '')}".rstrip(", ")
    return out


def _eval_table(result: dict[str, Any], title: str, agents: int, seconds: float) -> None:
    """`coadapt eval`'s result as a table, each objective's cost in its declared unit."""
    from rich.console import Console
    from rich.table import Table

    from coadapt_core.plugins import get_registry

    table = Table(title=f"coadapt eval: {title}")  # eval's costs: this command's protocol
    table.add_column("metric")
    table.add_column("value", justify="right")
    costs, costs_se = result.pop("costs", {}), result.pop("costs_se", {})
    walking, gate = result.pop("walking", None), result.pop("walking_gate", None)
    measures = _measures()
    for key, value in result.items():
        label = (
            f"{key} (eval)" if key.endswith(("_cost", "_cost_se")) else key
        )  # every cost says its protocol
        measure = measures.get(key.removesuffix("_se"))  # a tracking figure says its measure
        if measure:
            label = f"{key}: {'SE of ' if key.endswith('_se') else ''}{measure}"
        table.add_row(label, f"{value:.4g}" if isinstance(value, float) else str(value))
    for name, value in costs.items():
        table.add_row(f"{name} cost (eval, per step)", f"{value:.4g} +- {costs_se[name]:.2g} SE")
    Console().print(table)
    units = []  # each `<objective>_cost` in the objective's declared unit
    for key in result:
        name = key.removesuffix("_cost")
        if key.endswith("_cost") and name in get_registry().names("objective"):
            unit = getattr(get_registry().get("objective", name), "unit", "")
            units += [f"{name} {unit}"] if unit else []
    Console().print(
        f"costs: mean per step over {agents} agents of {seconds:g} s under this one command "
        "(`coadapt eval` protocol: not comparable with `coadapt run` or `coadapt landscape`, "
        "whose scenarios draw their commands)" + (f"; units: {', '.join(units)}" if units else "")
    )
    if gate is not None:  # `coadapt run`'s walking gate on this evaluation (coadapt/reliability.py)
        from rich.markup import escape

        Console().print(f"walking gate: {'[bold red]' if walking is False else ''}{escape(gate)}")


def _eval_video(robot_obj: Any, design_values: Any, trajectory: Any, video: Path) -> None:
    from coadapt_core.viz.video import write_rollout_video

    backend, errors = write_rollout_video(robot_obj, design_values, trajectory, video)
    if backend is None:
        fail(
            "offscreen rendering is unavailable here (" + "; ".join(errors) + "); no video written",
            code=1,
        )
    print(
        f"wrote {video} ({len(trajectory['frames'][::2])} frames, MUJOCO_GL={backend})",
        file=sys.stderr,
    )


def register(app: typer.Typer) -> None:
    evaluation = options_of(EvalCommand)

    def eval_command(**values: Any) -> None:
        """Roll out a policy on one design and report survival, speed and costs."""
        o = SimpleNamespace(**filled(values, evaluation))
        velocity = _eval_checks(o.agents, o.seconds, o.video, o.device, o.objective, o.command)
        apply_threads(o.threads)
        checkpoint = eval_checkpoint_path(o.checkpoint)
        robot = o.robot if o.robot is not None else _eval_robot(checkpoint)
        robot_obj = resolve("robot", robot)()
        sim = plugin_name("simulator", o.sim)
        sim_cls = simulator_for(sim, o.terrain)
        from coadapt_core.cli.robot import parse_design

        design = parse_design(robot_obj, o.design)
        checkpoint = (
            checkpoint if checkpoint is not None else _shipped(robot_obj, robot, o.terrain, design)
        )
        from coadapt_core.experiments.evaluate import evaluate_checkpoint

        with ProgressLine("eval", None, unit=" steps", enabled=not (o.as_json or o.quiet)) as bar:
            result = evaluate_checkpoint(
                checkpoint,
                robot_obj,
                sim_cls,
                design,
                terrain=o.terrain,
                command=velocity,
                agents=o.agents,
                seconds=o.seconds,
                device=o.device,
                seed=o.seed,
                randomize=o.randomize,
                record=o.video is not None,
                progress=bar.update,
                objectives=_names(o.objective),
            )
        trajectory = result.pop("_trajectory", None)
        if o.as_json:
            print(json.dumps(result))
        else:
            _eval_table(
                result,
                f"{robot} design {design.tolist()} on {sim}/{o.terrain}, command {velocity}",
                o.agents,
                o.seconds,
            )
        if o.video is not None:
            _eval_video(robot_obj, design, trajectory, o.video)

    register_command(app, "eval", eval_command, evaluation)
