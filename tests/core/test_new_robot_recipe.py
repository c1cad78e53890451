"""`coadapt train` for a robot with no shipped policy starts from the new-robot recipe
(issue 53); where a policy ships, TrainConfig's defaults; options given apply over either."""

from __future__ import annotations

import torch

from coadapt_core.cli import main
from coadapt_core.cli.train_setup import fresh_train_config
from coadapt_core.coadapt.learner_overrides import resolve_learner
from coadapt_core.learning.config import NEW_ROBOT_RECIPE, TrainConfig, new_robot_config
from coadapt_core.plugins import get_registry


def _qilin():
    return get_registry().get("robot", "qilin")()


def test_a_shipped_policy_keeps_the_defaults_and_none_takes_the_recipe():
    shipped, recipe = fresh_train_config(_qilin(), "flat", False)  # Qilin ships flat.pt
    assert recipe is False
    assert (shipped.num_designs, shipped.agents_per_design, shipped.epochs) == (128, 32, 5)
    fresh, recipe = fresh_train_config(_qilin(), "slope", False)  # and no slope policy
    assert recipe is True
    assert (fresh.num_designs, fresh.agents_per_design, fresh.epochs) == (16, 16, 2)
    # the recipe changes only what it names
    base = TrainConfig().to_dict()
    changed = {k for k, v in new_robot_config().to_dict().items() if base[k] != v}
    assert changed == set(NEW_ROBOT_RECIPE)


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
