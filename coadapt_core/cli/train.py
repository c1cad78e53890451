"""`coadapt train` and `coadapt eval`: the universal locomotion policy.

`train` runs PPO (Algorithm 1) on K designs drawn from a design range, A agents each, with
a progress bar, CSV scalars (TorchRL's CSVLogger; TensorBoard when installed), periodic
checkpoints and resume. `eval` rolls a policy out on one design under a fixed command and
prints survival, speed and costs.
"""

from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core import tracking
from coadapt_core.cli.common import (
    choice_help,
    default_help,
    fail,
    given_settings,
    plugin_name,
    resolve,
    settings_options,
    with_options,
)
from coadapt_core.cli.progress import ProgressLine
from coadapt_core.errors import UserError
from coadapt_core.settings import overrides
from coadapt_core.tracking import check_logger, make_logger

#: the objectives whose pseudo-critics `coadapt train` trains by default (paper section 4)
DEFAULT_OBJECTIVES = "tracking,power,torque"


def _objectives(text: str) -> list:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        fail("--objectives needs at least one objective name, e.g. tracking,power,torque")
    if len(set(names)) != len(names):
        fail(f"--objectives '{text}' names an objective twice; each pseudo-critic is trained once")
    return [resolve("objective", n)() for n in names]


def _simulator(sim: str, terrain: str) -> type:
    cls = resolve("simulator", sim)
    if terrain not in cls.terrains:
        fail(f"--terrain '{terrain}' is not supported by simulator '{sim}'; one of: {', '.join(cls.terrains)}")
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


class _Interrupted(Exception):
    """Ctrl-C was pressed: `coadapt train` stops after the iteration under way."""


def _catch_ctrl_c() -> dict:
    """The first Ctrl-C (SIGINT) only asks `train` to stop at the end of the iteration under
    way and write a checkpoint; a second one interrupts at once. Returns the flag holder and
    a `restore` callable putting the previous handler back."""
    import signal
    import threading

    state: dict[str, Any] = {"requested": False, "restore": lambda: None}
    if threading.current_thread() is not threading.main_thread():
        return state
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum, frame) -> None:
        if state["requested"]:
            raise KeyboardInterrupt
        state["requested"] = True
        print("\nCtrl-C: stopping after this iteration and writing a checkpoint (Ctrl-C again: stop now, "
              "without one)", file=sys.stderr, flush=True)

    signal.signal(signal.SIGINT, handler)
    state["restore"] = lambda: signal.signal(signal.SIGINT, previous)
    return state


#: older option names of `coadapt train`, still accepted
TRAIN_ALIASES: dict[str, tuple[str, ...]] = {
    "learning_rate": ("--lr",), "agents_per_design": ("--agents",), "design_resample_every": ("--resample-designs",),
    "task.commands.yaw_range": ("--yaw-range",), "randomization.preset": ("--randomization",),
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
        _TRAIN_SETTINGS = partial(TrainConfig, "TrainCommandSettings", unset=UNSET, exclude=("device", "seed", "extra"),
                                  extra={
            "task": (TaskSection, setting(default_factory=TaskSection, help=fields["task"].description)),
            "randomization": (RandomizationSection, setting(default_factory=RandomizationSection,
                                                            help=fields["randomization"].description)),
        })
    return _TRAIN_SETTINGS


_TRAIN_SETTINGS: type | None = None


def train_options() -> list[tuple[str, Any, Any, Any]]:
    return settings_options(train_settings_class(), aliases=TRAIN_ALIASES)


def _train_command_options() -> list[tuple[str, Any, Any]]:
    """`coadapt train`'s options that are not learner settings."""
    return [
        ("robot", str, typer.Option(None, help=default_help("robot", "Robot."))),
        ("sim", str, typer.Option(None, help=default_help("simulator", "Simulator backend."))),
        ("terrain", str, typer.Option("flat", help="Terrain: flat, slope or random.")),
        ("designs", str, typer.Option(None, help="Design range, one low:high per continuous variable, e.g. 0.5:1.5,0.5:1.5 (default: the full space; on --resume: the checkpoint's).")),
        ("steps", int, typer.Option(1_000_000, help="Environment interactions to train for (this invocation).")),
        ("objectives", str, typer.Option(DEFAULT_OBJECTIVES, help="Objectives whose pseudo-critics are trained, comma-separated.")),
        ("device", str, typer.Option("cpu", help="Learner device: cpu or cuda.")),
        ("threads", int, typer.Option(None, help="Physics threads (default: the backend's choice).")),
        ("seed", int, typer.Option(0, help="Random seed.")),
        ("resume", Path, typer.Option(None, help="Checkpoint to resume from (networks, optimizers, normalisers, counters).")),
        ("init_from", Path, typer.Option(None, "--init-from", help="Start from this policy's weights and normalisers (fresh optimizer state); one taking fewer design values (e.g. the leg scales only, for --mixed) gets zero weights for the new ones.")),
        ("out", Path, typer.Option(Path("runs/train"), help="Output directory (checkpoints, logs, progress.jsonl).")),
        ("mixed", bool, typer.Option(False, help="Also sample the discrete design variables (motor types).")),
        ("reset_pseudo_critics", bool, typer.Option(False, "--reset-pseudo-critics", help="With --resume or --init-from: restart the pseudo-critics from scratch (after an objective's definition changed).")),
        ("pseudo_critics_only", bool, typer.Option(False, "--pseudo-critics-only", help="With --resume or --init-from: train only the pseudo-critics; the policy, critic and observation normalisers stay exactly as loaded (refit a finished policy's surrogate, or give it a new objective).")),
        ("quiet", bool, typer.Option(False, help="No progress bar; one JSON line per iteration on stdout.")),
        ("logger", str, typer.Option("tensorboard", help="Experiment tracking: tensorboard (event files in OUT/logs), wandb (if installed) or none.")),
    ]


def register(app: typer.Typer) -> None:
    settings = train_options()

    def train_command(**values: Any) -> None:
        """Train the universal policy pi(a|o, xi) with its critic and pseudo-critics (PPO)."""
        robot, sim = plugin_name("robot", values["robot"]), plugin_name("simulator", values["sim"])
        terrain, designs, steps, mixed = values["terrain"], values["designs"], values["steps"], values["mixed"]
        resume, init_from, out, quiet = values["resume"], values["init_from"], values["out"], values["quiet"]
        device, seed, logger, threads = values["device"], values["seed"], values["logger"], values["threads"]
        reset_pseudo_critics, pseudo_only = values["reset_pseudo_critics"], values["pseudo_critics_only"]
        if steps < 0 or (steps == 0 and resume is None and init_from is None):
            fail(f"--steps must be >= 1 (or 0 with --resume or --init-from: export without training), got {steps}")
        _check_device(device)
        try:
            check_logger(logger)
            # the settings given: checked against their declarations (one line naming the option)
            given = overrides(train_settings_class()(**given_settings(values, settings)))
        except UserError as exc:
            fail(str(exc))
        robot_obj = resolve("robot", robot)()
        sim_cls = _simulator(sim, terrain)
        objective_objs = _objectives(values["objectives"])

        from coadapt_core.coadapt.config import resolve_learner
        from coadapt_core.design_space import DesignSpace
        from coadapt_core.learning import TrainConfig, Trainer, read_checkpoint
        from coadapt_core.task import TaskConfig

        if resume is not None and init_from is not None:
            fail("--resume and --init-from exclude each other: resume continues a run, --init-from starts a new one from its weights")
        from coadapt_core.io import checkpoint_path

        try:  # a training folder means its newest checkpoint (model_final.pt or the last one saved)
            resume = checkpoint_path(resume, field="--resume") if resume is not None else None
            init_from = checkpoint_path(init_from, field="--init-from") if init_from is not None else None
        except UserError as exc:
            fail(str(exc))
        if reset_pseudo_critics and resume is None and init_from is None:
            fail("--reset-pseudo-critics needs --resume or --init-from (a new run's pseudo-critics are fresh anyway)")
        if pseudo_only and resume is None and init_from is None:
            fail("--pseudo-critics-only needs --resume or --init-from: the policy whose pseudo-critics are trained")
        source = resume if resume is not None else init_from
        state = read_checkpoint(source) if source is not None else None
        if state is not None and state["robot"] != robot:
            flag = "--resume" if resume is not None else "--init-from"
            fail(f"{flag} checkpoint was trained for robot '{state['robot']}', not '{robot}'")
        # the checkpoint's settings (the defaults for a new run) with the options given
        try:
            learner = resolve_learner(state, given, given.pop("task", {}), given.pop("randomization", {}))
        except UserError as exc:
            fail(str(exc))
        base = learner.get("train_config") or (TrainConfig.from_dict(state["train_config"]) if state else TrainConfig())
        task = learner.get("task_config") or (TaskConfig.from_dict(state["task_config"]) if state else TaskConfig())
        base.device, base.seed = device, seed
        checkpoint_every, lr = base.checkpoint_every, given.get("learning_rate")
        full = robot_obj.design_space(mixed)
        if designs is not None:
            space = full.parse_ranges(designs)
        elif state is not None and resume is not None:
            space = DesignSpace.from_dict(state["design_space"])
        else:
            space = full

        trainer = Trainer(
            robot_obj, sim_cls, objective_objs, terrain=terrain, design_space=space, train_config=base,
            task_config=task, randomization=learner.get("randomization"), num_threads=threads,
        )
        if resume is not None:
            trainer.load(resume)
        elif init_from is not None:
            trainer.load(init_from, optimizers=False, widen=True)
            if int(state["dims"]["num_design"]) < space.dim:
                print(
                    f"widened {init_from}'s design input from {state['dims']['num_design']} to {space.dim} values "
                    "(zero weights for the new ones)",
                    file=sys.stderr,
                )
        if reset_pseudo_critics and trainer.ppo.pseudo_critic is not None:
            trainer.ppo.reset_pseudo_critics()
        if pseudo_only:
            if trainer.ppo.pseudo_critic is None:
                fail("--pseudo-critics-only: no objectives, so no pseudo-critics to train (see --objectives)")
            trainer.ppo.freeze_policy()
        if lr is not None and source is not None:  # --lr wins over the rate the checkpoint reached
            trainer.ppo.learning_rate = lr
            for group in trainer.ppo.optimizer.param_groups:
                group["lr"] = lr
        trainer.set_designs(trainer.sample_designs())
        iterations = trainer.iterations_for(steps) if steps > 0 else 0  # 0: export only
        out.mkdir(parents=True, exist_ok=True)
        tracker = make_logger(logger, out / "logs", name=f"train-{robot}-{terrain}", config={"robot": robot, "sim": sim, "terrain": terrain, **base.__dict__})
        tracker.train_step = trainer.total_steps  # a resumed run continues its curves
        progress_file = (out / "progress.jsonl").open("a")
        print(
            f"training {robot} on {sim}/{terrain}: {base.num_designs} designs x {base.agents_per_design} agents = "
            f"{trainer.env.num_envs} envs, {iterations} iterations of {trainer.samples_per_iteration} samples, "
            f"range {space.describe()}, device {device}, randomization {base.extra.get('randomization', 'table2')}, "
            f"yaw {task.commands.yaw_range[0]:g}:{task.commands.yaw_range[1]:g} rad/s"
            + (", pseudo-critics only (the policy stays as loaded)" if pseudo_only else ""),
            file=sys.stderr,
        )

        def record(stats) -> None:
            row = stats.to_dict()
            progress_file.write(json.dumps(row) + "\n")
            progress_file.flush()
            if stats.iteration % checkpoint_every == 0:
                trainer.save(out / "checkpoints" / f"model_{stats.iteration}.pt")
            if quiet:
                print(json.dumps(row), flush=True)
            if interrupt["requested"]:  # Ctrl-C during this iteration: stop at its end
                raise _Interrupted

        interrupt = _catch_ctrl_c()
        with tracking.active(tracker), ProgressLine("train", iterations, unit=" it", enabled=not quiet) as bar:

            def show(stats) -> None:
                record(stats)
                bar.update(stats.iteration - first_iteration, f"{stats.collect_steps_per_s:,.0f} steps/s  reward "
                           f"{stats.mean_reward:.4f}  vx {stats.vx:.2f}/{stats.command_vx:.2f} m/s  "
                           f"err {stats.tracking_error:.3f} m/s  ep {stats.episode_length_s:.1f} s")

            first_iteration = trainer.iteration
            try:
                if iterations > 0:
                    trainer.learn(iterations, show)
            except _Interrupted:
                path = trainer.save(out / "checkpoints" / f"model_{trainer.iteration}.pt")
                interrupt["restore"]()
                tracker.close()
                progress_file.close()
                trainer.close()
                print(f"interrupted: wrote {path} after iteration {trainer.iteration}; continue with "
                      f"coadapt train --resume {path} --out {out}", file=sys.stderr)
                raise typer.Exit(130) from None
            finally:
                interrupt["restore"]()
        tracker.close()
        progress_file.close()
        final = trainer.save(out / "model_final.pt")
        weights = trainer.export_weights(out / "policy.pt")
        trainer.close()
        print(f"wrote {final} and {weights} ({weights.stat().st_size / 1e6:.1f} MB) after {trainer.total_steps} steps", file=sys.stderr)

    app.command("train")(with_options(train_command, settings, _train_command_options(), others_first=True))

    @app.command("eval")
    def eval_command(
        checkpoint: Path | None = typer.Option(None, help="Checkpoint or weights file (default: the policy shipped for the robot and terrain)."),
        robot: str | None = typer.Option(None, help=choice_help("robot", "Robot (default: the one the checkpoint was trained for; without --checkpoint, the only installed robot).")),
        design: str | None = typer.Option(None, help="Design, comma-separated (default: the nominal design)."),
        sim: str | None = typer.Option(None, help=default_help("simulator", "Simulator backend.")),
        terrain: str = typer.Option("flat", help="Terrain: flat, slope or random."),
        command: str = typer.Option("0.5,0,0", help="Velocity command vx,vy,yaw_rate (m/s, m/s, rad/s)."),
        agents: int = typer.Option(50, help="Agents (environments) on the design."),
        seconds: float = typer.Option(20.0, help="Simulated seconds per agent."),
        device: str = typer.Option("cpu", help="Policy device: cpu or cuda."),
        seed: int = typer.Option(0, help="Random seed."),
        randomize: bool = typer.Option(True, help="Domain randomization (Table 2) as in training."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON."),
        video: Path | None = typer.Option(None, help="Render agent 0 offscreen into a .gif (or .mp4 with ffmpeg)."),
        objective: list[str] = typer.Option(None, "--objective", help=choice_help("objective", "Also evaluate this installed objective (repeatable, or a comma list): its cost per step and standard error over the agents, in `costs` / `costs_se` with --json.")),
    ) -> None:
        """Roll out a policy on one design and report survival, speed and costs."""
        if agents < 1:
            fail(f"--agents must be >= 1, got {agents}")
        if not (0 < seconds <= 3600):
            fail(f"--seconds must lie in (0, 3600], got {seconds}")
        if video is not None and video.suffix.lower() not in (".gif", ".mp4"):
            fail(f"--video '{video}' must end in .gif or .mp4")
        if video is not None and video.suffix.lower() == ".mp4" and shutil.which("ffmpeg") is None:
            fail("--video .mp4 needs ffmpeg on PATH, which is not installed; write a .gif instead")  # before the rollout
        _check_device(device)
        objective_names = [n.strip() for text in objective or [] for n in text.split(",") if n.strip()]
        for name in objective_names:
            resolve("objective", name)  # unknown: one line listing the installed ones
        try:
            values = [float(v) for v in command.split(",")]
        except ValueError:
            values = []
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            fail(f"--command '{command}' must be three numbers vx,vy,yaw_rate, e.g. 0.5,0,0")
        if checkpoint is not None:  # a training folder: its newest checkpoint
            from coadapt_core.io import checkpoint_path

            try:
                checkpoint = checkpoint_path(checkpoint, field="--checkpoint")
            except UserError as exc:
                fail(str(exc))
        if robot is None:  # the checkpoint records its robot; else the one installed robot
            if checkpoint is not None and checkpoint.is_file():
                from coadapt_core.learning import read_checkpoint

                try:
                    robot = str(read_checkpoint(checkpoint)["robot"])
                except Exception as exc:
                    fail(f"--checkpoint {checkpoint} is not a coadapt checkpoint ({type(exc).__name__}: {exc})")
            else:
                from coadapt_core.plugins import get_registry

                installed = get_registry().names("robot")
                if checkpoint is not None and len(installed) != 1:
                    fail(f"--checkpoint {checkpoint} does not exist")
                if len(installed) != 1:
                    fail(f"--robot is needed: {len(installed)} robots are installed ({', '.join(installed)})")
                robot = installed[0]
        robot_obj = resolve("robot", robot)()
        sim = plugin_name("simulator", sim)
        sim_cls = _simulator(sim, terrain)
        from coadapt_core.cli.robot import parse_design

        design_values = parse_design(robot_obj, design)
        if checkpoint is None:
            from coadapt_core.learning import shipped_checkpoint

            mixed = robot_obj.design_space_for(design_values).is_mixed
            checkpoint = shipped_checkpoint(robot_obj, terrain, mixed=mixed)
            if checkpoint is None:
                space = "mixed" if mixed else "continuous"
                fail(
                    f"robot '{robot}' ships no policy for terrain '{terrain}' and the {space} design space; "
                    f"pass --checkpoint (e.g. one `coadapt train --robot {robot} --terrain {terrain}` wrote)"
                )
        from coadapt_core.experiments.evaluate import evaluate_checkpoint

        with ProgressLine("eval", None, unit=" steps", enabled=not as_json) as bar:
            result = evaluate_checkpoint(
                checkpoint, robot_obj, sim_cls, design_values, terrain=terrain, command=values, agents=agents,
                seconds=seconds, device=device, seed=seed, randomize=randomize, record=video is not None,
                progress=bar.update, objectives=objective_names,
            )
        trajectory = result.pop("_trajectory", None)
        if as_json:
            print(json.dumps(result))
        else:
            from rich.console import Console
            from rich.table import Table

            table = Table(title=f"{robot} design {design_values.tolist()} on {sim}/{terrain}, command {values}")
            table.add_column("metric")
            table.add_column("value", justify="right")
            costs, costs_se = result.pop("costs", {}), result.pop("costs_se", {})
            for key, value in result.items():
                table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
            for name, value in costs.items():
                table.add_row(f"{name} cost (per step)", f"{value:.4g} +- {costs_se[name]:.2g} SE")
            Console().print(table)
            from coadapt_core.plugins import get_registry

            units = []  # each `<objective>_cost` in the objective's declared unit
            for key in result:
                name = key.removesuffix("_cost")
                if key.endswith("_cost") and name in get_registry().names("objective"):
                    unit = getattr(get_registry().get("objective", name), "unit", "")
                    units += [f"{name} {unit}"] if unit else []
            Console().print(f"costs: mean per step over {agents} agents of {seconds:g} s under this one command "
                            "(`coadapt eval` protocol: not comparable with `coadapt run` or `coadapt landscape`, "
                            "whose scenarios draw their commands)" + (f"; units: {', '.join(units)}" if units else ""))
        if video is not None:
            from coadapt_core.viz.video import write_rollout_video

            backend, errors = write_rollout_video(robot_obj, design_values, trajectory, video)
            if backend is None:
                fail("offscreen rendering is unavailable here (" + "; ".join(errors) + "); no video written", code=1)
            print(f"wrote {video} ({len(trajectory['frames'][::2])} frames, MUJOCO_GL={backend})", file=sys.stderr)
