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
import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common import check_device_option, fail, plugin_name, resolve, simulator_for
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.help import choices
from coadapt_core.cli.options import OptionGroup, filled, given_settings, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.cli.progress import ProgressLine
from coadapt_core.errors import UserError
from coadapt_core.settings import Float, Int, overrides, setting, settings, shared
from coadapt_core.threads import apply_threads
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
    threads: Any = shared(CommonOptions)
    seed: Any = shared(CommonOptions)
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
    until_walks: bool = setting(
        False,
        "Train until the walking gate holds at the nominal design and the four corners of the "
        "range (checked every --check-every iterations), within --steps and --max-seconds; "
        "that checkpoint is kept as OUT/walks.pt (exit 3 when a budget runs out first).",
        names=("--until-walks",),
    )
    max_seconds: Float | None = setting(
        None,
        "With --until-walks: training wall-clock budget, s (the checks not counted; "
        "default: none, --steps alone).",
        gt=0,
    )
    check_every: Int = setting(50, "With --until-walks: iterations between walking checks.", ge=1)
    check_agents: Int = setting(16, "With --until-walks: agents per design in a check.", ge=1)
    check_seconds: Float = setting(
        5.0,
        "With --until-walks: simulated seconds per design in a check (the gate judges "
        "tracking over >= 50 policy steps).",
        gt=0,
    )
    quiet: Any = shared(CommonOptions)
    logger: str = setting(
        "tensorboard",
        "Experiment tracking: tensorboard (event files in OUT/logs), wandb (if installed) or none.",
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
            "Built by `train_settings_class()`: the trainer's settings (`TrainConfig`) and the "
            "run's `task` and `randomization` sections, each an override of the checkpoint's "
            "(--resume / --init-from), else of the default."
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
            "--resume and --init-from exclude each other: resume continues a run, --init-from "
            "starts a new one from its weights"
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
            "--reset-pseudo-critics needs --resume or --init-from (a new run's pseudo-critics "
            "are fresh anyway)"
        )
    if values["pseudo_critics_only"] and resume is None and init_from is None:
        fail(
            "--pseudo-critics-only needs --resume or --init-from: the policy whose "
            "pseudo-critics are trained"
        )
    return resume, init_from


def _plugins(values: dict[str, Any], robot: str) -> tuple[Any, type, list]:
    """The robot, the simulator class (checked for --terrain) and the objectives of --objectives."""
    robot_obj = resolve("robot", robot)()
    return (
        robot_obj,
        simulator_for(plugin_name("simulator", values["sim"]), values["terrain"]),
        _objectives(values["objectives"]),
    )


def fresh_train_config(robot: Any, terrain: str, mixed: bool) -> tuple[Any, bool]:
    """The train config a new `coadapt train` starts from, and whether it is the recipe:
    TrainConfig's defaults where the robot ships a policy for this terrain and design space
    (Kuafu's were trained so), else the new-robot recipe (`NEW_ROBOT_RECIPE`, measured in
    docs/training.md "Time to walk"); options given on the command line apply over either."""
    from coadapt_core.learning.config import TrainConfig, new_robot_config

    recipe = robot.shipped_policy(terrain, mixed) is None
    return (new_robot_config() if recipe else TrainConfig()), recipe


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
    from coadapt_core.task.config import TaskConfig

    robot_obj, sim_cls, objectives = plugins
    fresh, values["recipe"] = (
        (None, False)
        if state
        else fresh_train_config(robot_obj, values["terrain"], values["mixed"])
    )
    try:
        learner = resolve_learner(
            state, given, given.pop("task", {}), given.pop("randomization", {}), fresh
        )
    except UserError as exc:
        fail(str(exc))
    base = learner.get("train_config") or (
        TrainConfig.from_dict(state["train_config"]) if state else fresh
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
                f"widened {values['init_from']}'s design input from {taken} to "
                f"{trainer.design_space.dim} values (zero weights for the new ones)",
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
    yaw = task.commands.yaw_range
    print(
        f"training {robot} on {sim}/{values['terrain']}: {base.num_designs} designs x "
        f"{base.agents_per_design} agents = {trainer.env.num_envs} envs, {iterations} "
        f"iterations of {trainer.samples_per_iteration} samples, range "
        f"{trainer.design_space.describe()}, device {values['device']}, "
        f"{trainer.num_threads} threads, randomization "
        f"{base.extra.get('randomization', 'table2')}, yaw {yaw[0]:g}:{yaw[1]:g} rad/s"
        + (
            ", the new-robot recipe (no shipped policy here; docs/training.md)"
            if values.get("recipe")
            else ""
        )
        + (
            ", pseudo-critics only (the policy stays as loaded)"
            if values["pseudo_critics_only"]
            else ""
        )
        + (
            f", until it walks: the walking gate at the nominal design and the four corners "
            f"every {values['check_every']} iterations ({values['check_agents']} agents x "
            f"{values['check_seconds']:g} s each), within {values['steps']:,} interactions"
            + (
                f" and {values['max_seconds']:g} s of training"
                if values["max_seconds"] is not None
                else ""
            )
            if values["until_walks"]
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
    if values["until_walks"]:
        _check_check_seconds(values, trainer)
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
    # the last iteration's statistics and (--until-walks) the last check, as the line shows them
    shown: dict[str, Any] = {}
    walks = None
    with ProgressLine("train", iterations, unit=" it", enabled=not quiet) as bar:

        def redraw() -> None:
            stats = shown["stats"]
            bar.update(
                stats.iteration - first,
                f"{stats.collect_steps_per_s:,.0f} steps/s  reward "
                f"{stats.mean_reward:.4f}  vx {stats.vx:.2f}/{stats.command_vx:.2f} m/s  "
                f"velocity error/step {stats.tracking_error:.3f} m/s  "
                f"ep {stats.episode_length_s:.1f} s"
                + (f"  {shown['check']}" if "check" in shown else ""),
            )

        def show(stats) -> None:
            if quiet:
                print(json.dumps(stats.to_dict()), flush=True)
            shown["stats"] = stats
            redraw()

        def show_check(text: str) -> None:
            shown["check"] = text
            redraw()

        try:
            if values["until_walks"]:
                walks = _until_walks(values, runner, show, show_check)
            else:
                runner.run(iterations, show)
        except TrainingInterrupted as stop:
            runner.close()
            print(
                f"interrupted: wrote {stop.checkpoint} after iteration {stop.iteration}; "
                f"continue with coadapt train --resume {stop.checkpoint} --out {out}",
                file=sys.stderr,
            )
            raise typer.Exit(130) from None
    final, weights = runner.finish()
    print(
        f"wrote {final} and {weights} ({weights.stat().st_size / 1e6:.1f} MB) after "
        f"{trainer.total_steps} steps",
        file=sys.stderr,
    )
    if walks is not None:
        _walks_report(values, robot, trainer, walks, weights)
    elif iterations > 0 and not values["pseudo_critics_only"]:
        _verdict(values, trainer, final, quiet)


#: `coadapt train --until-walks`'s exit status when a budget ran out before a check walked
EXIT_NOT_WALKING = 3


def _until_walks(values: dict[str, Any], runner: Any, show: Any, show_check: Any) -> Any:
    """Train until a check walks or a budget runs out (`train_until_walks`): each check's
    checkpoint is OUT/check.pt, its row appended to OUT/checks.jsonl (and, with --quiet,
    printed as {"walking_check": row}); the one that walks becomes OUT/walks.pt."""
    from coadapt_core.experiments.walking_check import check_text, check_walking, train_until_walks
    from coadapt_core.learning.runner import TrainingInterrupted

    trainer, out = runner.trainer, runner.out

    def check() -> dict[str, Any]:
        try:
            return check_walking(
                trainer,
                out / "check.pt",
                agents=values["check_agents"],
                seconds=values["check_seconds"],
                seed=values["seed"],
                device=values["device"],
            )
        except KeyboardInterrupt:  # Ctrl-C during a check: as during an iteration
            raise TrainingInterrupted(runner.checkpoint(), trainer.iteration) from None

    def on_check(row: dict[str, Any]) -> None:
        with (out / "checks.jsonl").open("a") as log:
            log.write(json.dumps(row) + "\n")
        if values["quiet"]:
            print(json.dumps({"walking_check": row}), flush=True)
        show_check(check_text(row))
        if row["walking"]:
            (out / "check.pt").replace(out / "walks.pt")

    return train_until_walks(
        runner,
        steps=values["steps"],
        check=check,
        check_every=values["check_every"],
        max_seconds=values["max_seconds"],
        on_iteration=show,
        on_check=on_check,
    )


def _walks_report(
    values: dict[str, Any], robot: str, trainer: Any, walks: Any, weights: Path
) -> None:
    """--until-walks's last lines: walked (the time and interactions it took, where the
    checkpoint is and how to ship it), or which budget ran out (exit `EXIT_NOT_WALKING`)."""
    from coadapt_core.experiments.walking_check import check_text

    out, quiet = values["out"], values["quiet"]
    last = walks.checks[-1] if walks.checks else None
    took = (
        f"{walks.interactions:,} interactions and {walks.train_seconds:.0f} s of training "
        f"(the {len(walks.checks)} check{'s' if len(walks.checks) != 1 else ''} took "
        f"{walks.check_seconds:.0f} s more)"
    )
    if quiet:
        summary = {
            "walked": walks.walked,
            "interactions": walks.interactions,
            "train_seconds": round(walks.train_seconds, 2),
            "check_seconds": round(walks.check_seconds, 2),
            "budget": walks.budget,
            "checkpoint": str(out / "walks.pt") if walks.walked else None,
            "last_check": last,
        }
        print(json.dumps({"until_walks": summary}), flush=True)
    if walks.walked:
        policies = f"{values['terrain']}-mixed.pt" if values["mixed"] else f"{values['terrain']}.pt"
        print(
            f"walks at the nominal design and the four corners after {took}: "
            f"{check_text(last)}. Kept: {out / 'walks.pt'} (the checkpoint) and {weights} (its "
            f"weights). Ship it as {robot}'s policy: copy {weights} to policies/{policies} in "
            f"the robot's folder (a spec robot: {robot}/policies/{policies} beside robot.yaml); "
            f"confirm with coadapt eval --robot {robot} --checkpoint {out / 'walks.pt'} "
            "--agents 50 --seconds 20",
            file=sys.stderr,
        )
        return
    budget = (
        f"the wall-clock budget (--max-seconds {values['max_seconds']:g})"
        if walks.budget == "seconds"
        else f"the interaction budget (--steps {values['steps']})"
    )
    print(
        f"not walking yet: {budget} ran out after {took}; "
        + (f"last {check_text(last)}" if last else "no check ran")
        + f". Go on with coadapt train --robot {robot} --terrain {values['terrain']}"
        + (" --mixed" if values["mixed"] else "")
        + f" --resume {out / 'model_final.pt'} --until-walks --out {out}",
        file=sys.stderr,
    )
    raise typer.Exit(EXIT_NOT_WALKING)


def _check_until_walks(values: dict[str, Any]) -> None:
    """--until-walks's options, checked against the others (one line, exit 2)."""
    if not values["until_walks"]:
        if values["max_seconds"] is not None:
            fail("--max-seconds is the wall-clock budget of --until-walks; give --until-walks too")
        return
    if values["pseudo_critics_only"]:
        fail("--until-walks trains the policy; --pseudo-critics-only keeps it as loaded")
    if values["steps"] <= 0:
        fail(f"--steps with --until-walks is the interaction budget, >= 1, got {values['steps']}")


def _check_check_seconds(values: dict[str, Any], trainer: Any) -> None:
    """--check-seconds long enough for the walking gate to judge tracking (`MIN_JUDGED_STEPS`
    policy steps of the trainer's simulator): over fewer a check never says "walks"."""
    from coadapt_core.coadapt.reliability import MIN_JUDGED_STEPS

    dt = float(trainer.env.dt)
    if round(values["check_seconds"] / dt) < MIN_JUDGED_STEPS:
        fail(
            f"check_seconds must be >= {MIN_JUDGED_STEPS * dt:g} with --until-walks (the "
            f"walking gate judges tracking over >= {MIN_JUDGED_STEPS} policy steps of "
            f"{dt:g} s), got {values['check_seconds']:g}"
        )


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
        f"walking gate at design {v['design']} ({v['agents']} agents x {v['seconds']:g} s, "
        f"vx command {v['vx_command']:g} m/s, vx {v['vx_mean']:.2f} m/s): {v['walking_gate']}",
        file=sys.stderr,
    )
    if quiet:
        print(json.dumps({"walking_gate": v}), flush=True)


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
                "--steps must be >= 1 (or 0 with --resume or --init-from: export without "
                f"training), got {steps}"
            )
        _check_until_walks(values)
        check_device_option(values["device"])
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
