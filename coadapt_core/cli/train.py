"""`coadapt train` and `coadapt eval`: the universal locomotion policy.

`train` runs PPO (Algorithm 1) on K designs drawn from a design range, A agents each,
through the training runner (`coadapt_core.learning.runner.Runner`: checkpoints,
progress.jsonl, the experiment tracker, Ctrl-C, resume) with a progress bar; the trainer and
the runner it drives are built in `train_setup`, --until-walks's checks and last lines are
`until_walks`'s. `eval` (`evaluate`) rolls a policy out on one design under a fixed command
and prints survival, speed and costs. Each command's own options are declared once
(`TrainCommand`, `EvalCommand`): option, --help and docs/settings.md.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli import until_walks
from coadapt_core.cli.common import check_device_option, fail, plugin_name
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import OptionGroup, filled, given_settings, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.cli.progress import ProgressLine
from coadapt_core.cli.train_setup import (
    RECIPE_NAME,
    build_trainer,
    checkpoint_sources,
    start_runner,
    train_plugins,
)
from coadapt_core.cli.until_walks import PSEUDO_CATCH_UP
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
        "With --until-walks: training wall-clock budget, s (the checks not counted; a "
        "resumed run's count goes on from its checkpoint's; default: none, --steps alone).",
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
    pseudo_catch_up: Int = setting(
        PSEUDO_CATCH_UP,
        "With --until-walks: the pseudo-critics are not trained while the policy learns to "
        "walk; once a check walks they are fitted for this many iterations on its rollouts, "
        "the policy frozen, before OUT/walks.pt is written (0: trained all along).",
        ge=0,
    )
    quiet: Any = shared(CommonOptions)
    logger: str = setting(
        "tensorboard",
        "Experiment tracking: tensorboard (event files in OUT/logs), wandb (if installed) or none.",
    )


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


def _recipe_clause(values: dict[str, Any], task: Any, config: Any) -> str:
    """The start line's clause naming the new-robot recipe a run starts from ("" where none);
    the recipe for two legs with the reward and symmetry settings in force (the options
    given win)."""
    name = values.get("recipe")
    if not name:
        return ""
    rewards = task.rewards
    settings = (
        f"contact_match weight {rewards.weights['contact_match']:g}, tracking sigma "
        f"{rewards.tracking_sigma:g}, symmetry {'on' if config.symmetry else 'off'}; "
        if name != RECIPE_NAME
        else ""
    )
    return f", {name} ({settings}no shipped policy here; docs/training.md)"


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
        + _recipe_clause(values, task, base)
        + (
            ", pseudo-critics only (the policy stays as loaded)"
            if values["pseudo_critics_only"]
            else ""
        )
        + until_walks.announced(values),
        file=sys.stderr,
    )


def _train(values: dict[str, Any], runner: Any, robot: str) -> None:
    """Run `runner` for --steps (0: export only), with the progress bar (or, --quiet, one
    JSON line per iteration), then write model_final.pt and policy.pt; Ctrl-C: exit 130."""
    from coadapt_core.learning.runner import TrainingInterrupted

    trainer, out, quiet, steps = runner.trainer, values["out"], values["quiet"], values["steps"]
    iterations = runner.iterations_for(steps) if steps > 0 else 0
    if values["until_walks"]:
        until_walks.check_check_seconds(values, trainer)
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
                walks = until_walks.train_until_walking(values, runner, show, show_check)
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
        until_walks.walks_report(values, robot, trainer, walks, weights)
    elif iterations > 0 and not values["pseudo_critics_only"]:
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
        steps = values["steps"]
        if steps < 0 or (steps == 0 and values["resume"] is None and values["init_from"] is None):
            fail(
                "--steps must be >= 1 (or 0 with --resume or --init-from: export without "
                f"training), got {steps}"
            )
        until_walks.check_options(values)
        check_device_option(values["device"])
        apply_threads(values["threads"])  # physics and torch; never the checkpoint's
        try:
            check_logger(values["logger"])
            # the settings given: checked against their declarations (one line naming the option)
            given = overrides(train_settings_class()(**given_settings(values, settings)))
        except UserError as exc:
            fail(str(exc))
        values["resume"], values["init_from"] = checkpoint_sources(values)
        source = values["resume"] or values["init_from"]
        state = read_checkpoint(source) if source is not None else None
        # no --robot: the checkpoint's robot (a resumed nezha run is nezha's), else the default
        robot = plugin_name("robot", values["robot"] or (state["robot"] if state else None))
        plugins = train_plugins(values, robot)
        if state is not None and state["robot"] != robot:
            flag = "--resume" if values["resume"] is not None else "--init-from"
            fail(f"{flag} checkpoint was trained for robot '{state['robot']}', not '{robot}'")
        trainer = build_trainer(values, plugins, given, state)
        _train(values, start_runner(values, trainer, source, given.get("learning_rate")), robot)

    register_command(app, "train", train_command, own, settings)
