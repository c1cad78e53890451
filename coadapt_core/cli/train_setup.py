"""What `coadapt train` trains and how it starts: the objectives whose pseudo-critics it
trains, the plugins, the checkpoint it resumes or starts from (--resume, --init-from), the
trainer on its design range with the options given over the checkpoint's settings (a new
run's: TrainConfig's or the new-robot recipe) and the runner started from that checkpoint."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from coadapt_core.cli.common import fail, plugin_name, resolve, simulator_for
from coadapt_core.cli.help import choices
from coadapt_core.errors import UserError


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


def checkpoint_sources(values: dict[str, Any]) -> tuple[Path | None, Path | None]:
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


def train_plugins(values: dict[str, Any], robot: str) -> tuple[Any, type, list]:
    """The robot, the simulator class (checked for --terrain) and the objectives of --objectives."""
    robot_obj = resolve("robot", robot)()
    return (
        robot_obj,
        simulator_for(plugin_name("simulator", values["sim"]), values["terrain"]),
        _objectives(values["objectives"]),
    )


#: the name the start line gives the new-robot recipe (with " for two legs" where the leg
#: count adds task settings)
RECIPE_NAME = "the new-robot recipe"
#: leg counts the start line names in words
_LEG_WORDS = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 8: "eight"}


def fresh_train_config(robot: Any, terrain: str, mixed: bool) -> tuple[Any, Any, str]:
    """The train and task configs a new `coadapt train` starts from, and the recipe's name
    ("" where none): TrainConfig's and TaskConfig's defaults where the robot ships a policy
    for this terrain and design space (Kuafu's were trained so), else the new-robot recipe
    (`NEW_ROBOT_RECIPE` over TrainConfig's defaults, measured in docs/training.md "Time to
    walk") with, for a robot of a leg count `NEW_ROBOT_TASK_RECIPE` names (two legs), its
    task settings over TaskConfig's defaults; options given on the command line apply over
    either."""
    from coadapt_core.learning.config import (
        NEW_ROBOT_TASK_RECIPE,
        NEW_ROBOT_TRAIN_RECIPE,
        TrainConfig,
        new_robot_config,
    )
    from coadapt_core.settings import apply_overrides
    from coadapt_core.task.config import TaskConfig

    if robot.shipped_policy(terrain, mixed) is not None:
        return TrainConfig(), TaskConfig(), ""
    legs = len(robot.legs())
    task = NEW_ROBOT_TASK_RECIPE.get(legs)
    train = dict(NEW_ROBOT_TRAIN_RECIPE.get(legs, {}))
    if train.get("symmetry") and not _has_mirror(robot):
        train["symmetry"] = False  # no mirror map: the recipe goes without it
    if task is None and not train:
        return new_robot_config(), TaskConfig(), RECIPE_NAME
    name = f"{RECIPE_NAME} for {_LEG_WORDS.get(legs, legs)} legs"
    return new_robot_config(**train), apply_overrides(TaskConfig(), task or {}), name


def _has_mirror(robot: Any) -> bool:
    """Whether the robot declares a left-right mirror map (`Robot.mirror`)."""
    from coadapt_core.errors import UserError

    try:
        robot.mirror()
    except UserError:
        return False
    return True


def build_trainer(
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
    fresh, fresh_task, values["recipe"] = (
        (None, None, "")
        if state
        else fresh_train_config(robot_obj, values["terrain"], values["mixed"])
    )
    try:
        learner = resolve_learner(
            state, given, given.pop("task", {}), given.pop("randomization", {}), fresh, fresh_task
        )
    except UserError as exc:
        fail(str(exc))
    base = learner.get("train_config") or (
        TrainConfig.from_dict(state["train_config"]) if state else fresh
    )
    task = learner.get("task_config") or (
        TaskConfig.from_dict(state["task_config"]) if state else fresh_task
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


def start_runner(
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
