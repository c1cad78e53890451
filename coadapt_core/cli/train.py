"""`coadapt train` and `coadapt eval`: the universal locomotion policy.

`train` runs PPO (Algorithm 1) on K designs drawn from a design range, A agents each,
through the training runner (`coadapt_core.learning.runner.Runner`: checkpoints,
progress.jsonl, the experiment tracker, Ctrl-C, resume) with a progress bar. `eval` rolls a
policy out on one design under a fixed command and prints survival, speed and costs. Each
command's own options are declared once (`TrainCommand`, `EvalCommand`): option, --help and
docs/settings.md.
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

from coadapt_core.cli.common import fail, plugin_name, resolve
from coadapt_core.cli.help import choices
from coadapt_core.cli.options import OptionGroup, filled, given_settings, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.cli.policy_source import EVAL_CHECKPOINTS, eval_checkpoint_path
from coadapt_core.cli.progress import ProgressLine
from coadapt_core.errors import UserError
from coadapt_core.settings import Float, Int, overrides, setting, settings, shared
from coadapt_core.threads import ThreadSettings, apply_threads
from coadapt_core.tracking import check_logger, make_logger


@settings
class TrainCommand:
    """`coadapt train`'s own settings (the learner's, the task's and the randomization's are
    `train_settings_class`'s); one declaration each gives the option, its help and its row
    in docs/settings.md."""

    robot: str | None = setting(None, "Robot.", plugin="robot")
    sim: str | None = setting(None, "Simulator backend.", plugin="simulator")
    terrain: str = setting("flat", "Terrain: flat, slope or random.")
    designs: str | None = setting(
        None,
        "Design range, one low:high per continuous variable, e.g. 0.5:1.5,0.5:1.5 "
        "(default: the full space; on --resume: the checkpoint's).",
    )
    steps: Int = setting(1_000_000, "Environment interactions to train for (this invocation).")
    objectives: str | None = setting(
        None,
        "Objectives whose pseudo-critics are trained, comma-separated (default: "
        "every installed objective that declares no options).",
    )
    device: str = setting("cpu", "Learner device: cpu or cuda.")
    threads: Any = shared(ThreadSettings)
    seed: Int = setting(0, "Random seed.")
    resume: Path | None = setting(
        None, "Checkpoint to resume from (networks, optimizers, normalisers, counters)."
    )
    init_from: Path | None = setting(
        None,
        "Start from this policy's weights and normalisers (fresh optimizer state); "
        "one taking fewer design values (e.g. the leg scales only, for --mixed) gets zero "
        "weights for the new ones.",
    )
    out: Path = setting(Path("runs/train"), "Output directory (checkpoints, logs, progress.jsonl).")
    mixed: bool = setting(False, "Also sample the discrete design variables (motor types).")
    reset_pseudo_critics: bool = setting(
        False,
        "With --resume or --init-from: restart the pseudo-critics from scratch "
        "(after an objective's definition changed).",
        names=("--reset-pseudo-critics",),
    )
    pseudo_critics_only: bool = setting(
        False,
        "With --resume or --init-from: train only the pseudo-critics; the policy, "
        "critic and observation normalisers stay exactly as loaded (refit a finished "
        "policy's surrogate, or give it a new objective).",
        names=("--pseudo-critics-only",),
    )
    quiet: bool = setting(False, "No progress bar; one JSON line per iteration on stdout.")
    logger: str = setting(
        "tensorboard",
        "Experiment tracking: tensorboard (event files in OUT/logs), wandb (if installed) or none.",
    )


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
    seed: Int = setting(0, "Random seed.")
    randomize: bool = setting(True, "Domain randomization (Table 2) as in training.")
    threads: Any = shared(ThreadSettings)
    as_json: bool = setting(False, "Print JSON.", names=("--json",))
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


def default_objectives() -> list[str]:
    """The objectives whose pseudo-critics `coadapt train` trains when --objectives is not
    given: every installed objective that declares no options (one with options, such as a
    weighted sum, depends on values a run chooses), in each plugin's own order."""
    from coadapt_core.plugins import get_registry

    infos = sorted(get_registry().entries["objective"].values(), key=lambda info: info.distribution)
    return [info.name for info in infos if not getattr(info.cls, "option_specs", ())]


def _objectives(text: str | None) -> list:
    text = ",".join(default_objectives()) if text is None else text
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        fail(
            "--objectives needs at least one objective name; installed: "
            + ", ".join(choices("objective"))
        )
    if len(set(names)) != len(names):
        fail(f"--objectives '{text}' names an objective twice; each pseudo-critic is trained once")
    return [resolve("objective", n)() for n in names]


def _simulator(sim: str, terrain: str) -> type:
    cls = resolve("simulator", sim)
    if terrain not in cls.terrains:
        fail(
            f"--terrain '{terrain}' is not supported by simulator '{sim}'; one of: {', '.join(cls.terrains)}"
        )
    return cls


def _check_device(device: str) -> None:
    import torch

    from coadapt_core.coadapt.config import check_device

    try:
        check_device(device, field="--device")
    except UserError as exc:
        fail(str(exc))
    if device.startswith("cuda") and not torch.cuda.is_available():
        fail("--device cuda requested but torch sees no CUDA device; use --device cpu")


#: older option names of `coadapt train`, still accepted
TRAIN_ALIASES: dict[str, tuple[str, ...]] = {
    "learning_rate": ("--lr",),
    "agents_per_design": ("--agents",),
    "design_resample_every": ("--resample-designs",),
    "task.commands.yaw_range": ("--yaw-range",),
    "randomization.preset": ("--randomization",),
}


def train_settings_class() -> type:
    """`coadapt train`'s settings tree: the trainer's (`TrainConfig`), the task's and the
    randomization's, each an override of the checkpoint's (--resume / --init-from) or of
    the default; the sections are those of `coadapt run` (`coadapt_core.coadapt.config`)."""
    global _TRAIN_SETTINGS
    if _TRAIN_SETTINGS is None:
        from coadapt_core.coadapt.config import (
            UNSET,
            CoadaptConfig,
            RandomizationSection,
            TaskSection,
        )
        from coadapt_core.learning.config import TrainConfig
        from coadapt_core.settings import partial, setting

        fields = CoadaptConfig.__pydantic_fields__
        doc = (
            "Built by `train_settings_class()`: the trainer's settings (`TrainConfig`) and the run's `task` and "
            "`randomization` sections, each an override of the checkpoint's (--resume / --init-from), else of the "
            "default."
        )
        _TRAIN_SETTINGS = partial(
            TrainConfig,
            "TrainCommandSettings",
            unset=UNSET,
            exclude=("device", "seed", "extra"),
            doc=doc,
            extra={
                "task": (
                    TaskSection,
                    setting(default_factory=TaskSection, help=fields["task"].description),
                ),
                "randomization": (
                    RandomizationSection,
                    setting(
                        default_factory=RandomizationSection,
                        help=fields["randomization"].description,
                    ),
                ),
            },
        )
        _TRAIN_SETTINGS.__module__ = __name__
    return _TRAIN_SETTINGS


_TRAIN_SETTINGS: type | None = None


def train_options() -> OptionGroup:
    """The options of `coadapt train`'s settings tree (`train_settings_class`), older names kept."""
    return options_of(train_settings_class(), aliases=TRAIN_ALIASES)


def _checkpoint_sources(values: dict[str, Any]) -> tuple[Path | None, Path | None]:
    """--resume and --init-from, checked against each other and the options needing one; a
    training folder stands for its newest checkpoint (model_final.pt or the last one saved)."""
    from coadapt_core.io import checkpoint_path

    resume, init_from = values["resume"], values["init_from"]
    if resume is not None and init_from is not None:
        fail(
            "--resume and --init-from exclude each other: resume continues a run, --init-from starts a new one from its weights"
        )
    try:
        resume = checkpoint_path(resume, field="--resume") if resume is not None else None
        init_from = (
            checkpoint_path(init_from, field="--init-from") if init_from is not None else None
        )
    except UserError as exc:
        fail(str(exc))
    if values["reset_pseudo_critics"] and resume is None and init_from is None:
        fail(
            "--reset-pseudo-critics needs --resume or --init-from (a new run's pseudo-critics are fresh anyway)"
        )
    if values["pseudo_critics_only"] and resume is None and init_from is None:
        fail(
            "--pseudo-critics-only needs --resume or --init-from: the policy whose pseudo-critics are trained"
        )
    return resume, init_from


def _plugins(values: dict[str, Any], robot: str) -> tuple[Any, type, list]:
    """The robot, the simulator class (checked for --terrain) and the objectives of --objectives."""
    robot_obj = resolve("robot", robot)()
    return (
        robot_obj,
        _simulator(plugin_name("simulator", values["sim"]), values["terrain"]),
        _objectives(values["objectives"]),
    )


def _build_trainer(
    values: dict[str, Any],
    plugins: tuple[Any, type, list],
    given: dict[str, Any],
    state: dict | None,
) -> Any:
    """The trainer `coadapt train` runs: the checkpoint's settings (the defaults of a new
    run) with the options given, on the design range asked for (on --resume: the
    checkpoint's)."""
    from coadapt_core.coadapt.learner_overrides import resolve_learner
    from coadapt_core.design_space import DesignSpace
    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.trainer import Trainer
    from coadapt_core.task import TaskConfig

    robot_obj, sim_cls, objectives = plugins
    try:
        learner = resolve_learner(
            state, given, given.pop("task", {}), given.pop("randomization", {})
        )
    except UserError as exc:
        fail(str(exc))
    base = learner.get("train_config") or (
        TrainConfig.from_dict(state["train_config"]) if state else TrainConfig()
    )
    task = learner.get("task_config") or (
        TaskConfig.from_dict(state["task_config"]) if state else TaskConfig()
    )
    base.device, base.seed = values["device"], values["seed"]
    if values["designs"] is not None:
        space = robot_obj.design_space(values["mixed"]).parse_ranges(values["designs"])
    elif state is not None and values["resume"] is not None:
        space = DesignSpace.from_dict(state["design_space"])
    else:
        space = robot_obj.design_space(values["mixed"])
    return Trainer(
        robot_obj,
        sim_cls,
        objectives,
        terrain=values["terrain"],
        design_space=space,
        train_config=base,
        task_config=task,
        randomization=learner.get("randomization"),
        num_threads=values["threads"],
    )


def _start_runner(
    values: dict[str, Any], trainer: Any, source: Path | None, learning_rate: float | None
) -> Any:
    """The runner of `coadapt train` over `trainer`, started where the options say: resumed,
    initialised from a policy, pseudo-critics reset or alone, the learning rate given."""
    from coadapt_core.learning.runner import Runner

    runner = Runner(trainer, values["out"], catch_ctrl_c=True)
    if values["resume"] is not None:
        runner.resume(values["resume"])
    elif values["init_from"] is not None:
        taken = runner.init_from(values["init_from"])
        if taken is not None:
            print(
                f"widened {values['init_from']}'s design input from {taken} to {trainer.design_space.dim} values "
                "(zero weights for the new ones)",
                file=sys.stderr,
            )
    try:
        runner.restrict(
            reset_pseudo_critics=values["reset_pseudo_critics"],
            pseudo_critics_only=values["pseudo_critics_only"],
        )
    except UserError as exc:
        fail(str(exc))
    if (
        learning_rate is not None and source is not None
    ):  # --lr wins over the rate the checkpoint reached
        runner.set_learning_rate(learning_rate)
    trainer.set_designs(trainer.sample_designs())
    return runner


def _announce(values: dict[str, Any], robot: str, trainer: Any, iterations: int) -> None:
    base, task, sim = (
        trainer.config,
        trainer.task_config,
        getattr(trainer.simulator_cls, "name", "?"),
    )
    print(
        f"training {robot} on {sim}/{values['terrain']}: {base.num_designs} designs x {base.agents_per_design} agents = "
        f"{trainer.env.num_envs} envs, {iterations} iterations of {trainer.samples_per_iteration} samples, "
        f"range {trainer.design_space.describe()}, device {values['device']}, {trainer.num_threads} threads, randomization "
        f"{base.extra.get('randomization', 'table2')}, yaw {task.commands.yaw_range[0]:g}:{task.commands.yaw_range[1]:g} rad/s"
        + (
            ", pseudo-critics only (the policy stays as loaded)"
            if values["pseudo_critics_only"]
            else ""
        ),
        file=sys.stderr,
    )


def _train(values: dict[str, Any], runner: Any, robot: str) -> None:
    """Run `runner` for --steps (0: export only), with the progress bar (or, --quiet, one
    JSON line per iteration), then write model_final.pt and policy.pt; Ctrl-C: exit 130."""
    from coadapt_core.learning.runner import TrainingInterrupted

    trainer, out, quiet, steps = runner.trainer, values["out"], values["quiet"], values["steps"]
    iterations = runner.iterations_for(steps) if steps > 0 else 0
    runner.out.mkdir(parents=True, exist_ok=True)
    runner.tracker = make_logger(
        values["logger"],
        out / "logs",
        name=f"train-{robot}-{values['terrain']}",
        config={
            "robot": robot,
            "sim": getattr(trainer.simulator_cls, "name", "?"),
            "terrain": values["terrain"],
            **trainer.config.__dict__,
        },
    )
    _announce(values, robot, trainer, iterations)
    first = trainer.iteration
    with ProgressLine("train", iterations, unit=" it", enabled=not quiet) as bar:

        def show(stats) -> None:
            if quiet:
                print(json.dumps(stats.to_dict()), flush=True)
            bar.update(
                stats.iteration - first,
                f"{stats.collect_steps_per_s:,.0f} steps/s  reward "
                f"{stats.mean_reward:.4f}  vx {stats.vx:.2f}/{stats.command_vx:.2f} m/s  "
                f"err {stats.tracking_error:.3f} m/s  ep {stats.episode_length_s:.1f} s",
            )

        try:
            runner.run(iterations, show)
        except TrainingInterrupted as stop:
            runner.close()
            print(
                f"interrupted: wrote {stop.checkpoint} after iteration {stop.iteration}; continue with "
                f"coadapt train --resume {stop.checkpoint} --out {out}",
                file=sys.stderr,
            )
            raise typer.Exit(130) from None
    final, weights = runner.finish()
    print(
        f"wrote {final} and {weights} ({weights.stat().st_size / 1e6:.1f} MB) after {trainer.total_steps} steps",
        file=sys.stderr,
    )
    if iterations > 0 and not values["pseudo_critics_only"]:
        _verdict(values, trainer, final, quiet)


def _verdict(values: dict[str, Any], trainer: Any, checkpoint: Path, quiet: bool) -> None:
    """`coadapt run`'s walking gate on the policy just written (`training_verdict`): a line
    on stderr, and with --quiet a last JSON line {"walking_gate": {...}} on stdout."""
    from coadapt_core.experiments.evaluate import training_verdict

    v = training_verdict(
        checkpoint,
        trainer.robot,
        trainer.simulator_cls,
        trainer.design_space,
        terrain=values["terrain"],
        device=values["device"],
        seed=values["seed"],
    )
    print(
        f"walking gate at design {v['design']} ({v['agents']} agents x {v['seconds']:g} s, vx command "
        f"{v['vx_command']:g} m/s, vx {v['vx_mean']:.2f} m/s): {v['walking_gate']}",
        file=sys.stderr,
    )
    if quiet:
        print(json.dumps({"walking_gate": v}), flush=True)


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
    _check_device(device)
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
                f"--checkpoint {checkpoint} is not a coadapt checkpoint ({type(exc).__name__}: {exc})"
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
            f"robot '{robot}' ships no policy for terrain '{terrain}' and the {space} design space; "
            f"pass --checkpoint (e.g. one `coadapt train --robot {robot} --terrain {terrain}` wrote)"
        )
    return checkpoint


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
    for key, value in result.items():
        label = (
            f"{key} (eval)" if key.endswith(("_cost", "_cost_se")) else key
        )  # every cost says its protocol
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
    settings, own = train_options(), options_of(TrainCommand)

    def train_command(**values: Any) -> None:
        """Train the universal policy pi(a|o, xi) with its critic and pseudo-critics (PPO)."""
        from coadapt_core.learning.checkpoints import read_checkpoint

        values = filled(values, own)
        robot = plugin_name("robot", values["robot"])
        steps = values["steps"]
        if steps < 0 or (steps == 0 and values["resume"] is None and values["init_from"] is None):
            fail(
                f"--steps must be >= 1 (or 0 with --resume or --init-from: export without training), got {steps}"
            )
        _check_device(values["device"])
        apply_threads(values["threads"])  # physics and torch; never the checkpoint's
        try:
            check_logger(values["logger"])
            # the settings given: checked against their declarations (one line naming the option)
            given = overrides(train_settings_class()(**given_settings(values, settings)))
        except UserError as exc:
            fail(str(exc))
        plugins = _plugins(values, robot)
        values["resume"], values["init_from"] = _checkpoint_sources(values)
        source = values["resume"] or values["init_from"]
        state = read_checkpoint(source) if source is not None else None
        if state is not None and state["robot"] != robot:
            flag = "--resume" if values["resume"] is not None else "--init-from"
            fail(f"{flag} checkpoint was trained for robot '{state['robot']}', not '{robot}'")
        trainer = _build_trainer(values, plugins, given, state)
        _train(values, _start_runner(values, trainer, source, given.get("learning_rate")), robot)

    register_command(app, "train", train_command, own, settings)
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
        sim_cls = _simulator(sim, o.terrain)
        from coadapt_core.cli.robot import parse_design

        design = parse_design(robot_obj, o.design)
        checkpoint = (
            checkpoint if checkpoint is not None else _shipped(robot_obj, robot, o.terrain, design)
        )
        from coadapt_core.experiments.evaluate import evaluate_checkpoint

        with ProgressLine("eval", None, unit=" steps", enabled=not o.as_json) as bar:
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
