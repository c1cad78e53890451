"""`coadapt train` for a robot with no shipped policy starts from the new-robot recipe
(issue 53), and a two-legged one from its task settings too (issue 59: contact_match weight 4,
tracking sigma 0.05) and left-right symmetry where it has a mirror map; where a policy
ships, TrainConfig's and TaskConfig's defaults; options given apply over either."""

from __future__ import annotations

import pytest
import torch

from coadapt_core.cli import main
from coadapt_core.cli.train_setup import fresh_train_config
from coadapt_core.coadapt.learner_overrides import resolve_learner
from coadapt_core.learning.config import NEW_ROBOT_RECIPE, TrainConfig, new_robot_config
from coadapt_core.plugins import get_registry
from coadapt_core.task.config import TaskConfig


def _robot(name: str):
    return get_registry().get("robot", name)()


def _qilin():
    return _robot("qilin")


def _changed_task(task: TaskConfig) -> dict:
    """The task settings that differ from TaskConfig's defaults, as {name: value}."""
    base, rewards = TaskConfig(), task.rewards
    out = {k: v for k, v in rewards.weights.items() if base.rewards.weights[k] != v}
    if rewards.tracking_sigma != base.rewards.tracking_sigma:
        out["tracking_sigma"] = rewards.tracking_sigma
    assert task.commands == base.commands and task.gait == base.gait
    return out


def test_a_shipped_policy_keeps_the_defaults_and_none_takes_the_recipe():
    shipped, task, recipe = fresh_train_config(_qilin(), "flat", False)  # Qilin ships flat.pt
    assert recipe == ""
    assert (shipped.num_designs, shipped.agents_per_design, shipped.epochs) == (128, 32, 5)
    assert _changed_task(task) == {}
    fresh, task, recipe = fresh_train_config(_qilin(), "slope", False)  # and no slope policy
    assert recipe == "the new-robot recipe"
    assert (fresh.num_designs, fresh.agents_per_design, fresh.epochs) == (16, 16, 2)
    assert _changed_task(task) == {}  # four legs: TaskConfig's defaults
    # the recipe changes only what it names
    base = TrainConfig().to_dict()
    changed = {k for k, v in new_robot_config().to_dict().items() if base[k] != v}
    assert changed == set(NEW_ROBOT_RECIPE)


def test_a_biped_without_a_policy_takes_the_two_legged_task_settings():
    # nezha ships flat.pt: there its defaults stay, and its shipped policy's task with them
    _, task, recipe = fresh_train_config(_robot("nezha"), "flat", False)
    assert recipe == "" and _changed_task(task) == {}
    for name, terrain in (("nezha", "slope"), ("jingwei", "flat")):  # no policy for these
        fresh, task, recipe = fresh_train_config(_robot(name), terrain, False)
        assert recipe == "the new-robot recipe for two legs"
        assert (fresh.num_designs, fresh.agents_per_design, fresh.epochs) == (16, 16, 2)
        assert fresh.symmetry is True  # both declare a mirror map
        assert _changed_task(task) == {"contact_match": 4.0, "tracking_sigma": 0.05}
    # four legs: no symmetry from the recipe (Qilin has a map)
    assert fresh_train_config(_qilin(), "slope", False)[0].symmetry is False


class _NoMirror:
    """jingwei with no mirror map declared."""

    def __init__(self) -> None:
        self._robot = _robot("jingwei")

    def __getattr__(self, name):
        return getattr(self._robot, name)

    def mirror(self):
        from coadapt_core.robot import Robot

        return Robot.mirror(self._robot)  # the base class: none declared


def test_a_biped_without_a_mirror_map_takes_the_recipe_without_symmetry():
    fresh, task, recipe = fresh_train_config(_NoMirror(), "flat", False)
    assert recipe == "the new-robot recipe for two legs"
    assert fresh.symmetry is False
    assert _changed_task(task) == {"contact_match": 4.0, "tracking_sigma": 0.05}


def test_options_given_apply_over_the_biped_task_settings():
    _, task, _ = fresh_train_config(_robot("jingwei"), "flat", False)
    given = {"rewards": {"weights": {"contact_match": 2.0, "raibert": -1.0}}}
    out = resolve_learner(None, {}, given, {}, new_robot_config(), task)
    # the given weights win, the recipe's sigma stays, the other weights are the defaults'
    assert _changed_task(out["task_config"]) == {
        "contact_match": 2.0,
        "raibert": -1.0,
        "tracking_sigma": 0.05,
    }
    out = resolve_learner(None, {}, {"rewards": {"tracking_sigma": 0.25}}, {}, None, task)
    assert _changed_task(out["task_config"]) == {"contact_match": 4.0}


def test_options_given_apply_over_the_recipe():
    out = resolve_learner(None, {"epochs": 3}, {}, {}, new_robot_config())
    config = out["train_config"]
    assert (config.num_designs, config.agents_per_design, config.epochs) == (16, 16, 3)


def test_coadapt_train_announces_and_records_the_recipe(tmp_path, capsys):
    out = tmp_path / "slope"
    args = ["train", "--robot", "qilin", "--terrain", "slope", "--steps", "16"]
    args += ["--num-designs", "2", "--agents", "2", "--steps-per-env", "4", "--quiet"]
    assert main([*args, "--out", str(out), "--logger", "none"]) == 0
    err = capsys.readouterr().err
    assert "2 designs x 2 agents" in err and "the new-robot recipe" in err
    state = torch.load(out / "model_final.pt", map_location="cpu", weights_only=True)
    saved = state["train_config"]
    # the options given (2 x 2) over the recipe's 2 epochs, not TrainConfig's 5
    assert (saved["num_designs"], saved["epochs"], saved["minibatches"]) == (2, 2, 4)


@pytest.mark.parametrize(
    "extra, line, weight, sigma, symmetry",
    [
        ([], "contact_match weight 4, tracking sigma 0.05, symmetry on;", 4.0, 0.05, True),
        # an option given wins, and the start line says what is in force
        (
            [
                *("--task-rewards-tracking-sigma", "0.1"),
                *("--task-rewards-weights", "contact_match=1", "--no-symmetry"),
            ],
            "contact_match weight 1, tracking sigma 0.1, symmetry off;",
            1.0,
            0.1,
            False,
        ),
    ],
)
def test_coadapt_train_starts_a_biped_on_the_two_legged_recipe(
    tmp_path, capsys, extra, line, weight, sigma, symmetry
):
    args = ["train", "--robot", "jingwei", "--steps", "8", "--num-designs", "2", "--agents", "2"]
    args += ["--steps-per-env", "2", "--quiet", "--logger", "none", *extra]
    assert main([*args, "--out", str(tmp_path)]) == 0
    assert f"the new-robot recipe for two legs ({line}" in capsys.readouterr().err
    saved = torch.load(tmp_path / "model_final.pt", map_location="cpu", weights_only=True)
    rewards = saved["task_config"]["rewards"]
    assert (rewards["weights"]["contact_match"], rewards["tracking_sigma"]) == (weight, sigma)
    assert saved["train_config"]["symmetry"] is symmetry
