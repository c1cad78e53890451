"""`coadapt_core.coadapt.setup`: which policy a run starts from (shipped, widened, scratch) and
how the BO baseline's specialised policies are built."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.setup import build_parts
from coadapt_core.coadapt.starting_policy import resolve_checkpoint
from coadapt_core.learning import shipped_checkpoint
from coadapt_core.learning.checkpoints import read_checkpoint


def actor_weight(backend) -> torch.Tensor:
    return backend.ppo.actor_net.body[0].weight.detach()


def test_shipped_policies_match_their_design_spaces() -> None:
    flat = shipped_checkpoint("kuafu", "flat")
    assert flat is not None and int(read_checkpoint(flat)["dims"]["num_design"]) == 2
    assert resolve_checkpoint(make_config("quick", overrides={"optimizer": "pso"})) == str(flat)
    mixed = shipped_checkpoint("kuafu", "flat", mixed=True)
    if mixed is not None:
        assert int(read_checkpoint(mixed)["dims"]["num_design"]) == 4
        assert resolve_checkpoint(
            make_config("quick", overrides={"optimizer": "mixed-pso"})
        ) == str(mixed)
    for terrain in ("slope", "random"):  # issue 17: fine-tuned from flat.pt on their terrain
        policy = read_checkpoint(shipped_checkpoint("kuafu", terrain))
        assert policy["terrain"] == terrain and int(policy["dims"]["num_design"]) == 2
    for terrain in ("slope", "random"):  # widened from the terrain's checkpoint to the motor types
        mixed_policy = read_checkpoint(shipped_checkpoint("kuafu", terrain, mixed=True))
        assert mixed_policy["terrain"] == terrain and int(mixed_policy["dims"]["num_design"]) == 4
        assert resolve_checkpoint(
            make_config("quick", overrides={"optimizer": "mixed-pso", "terrain": terrain})
        ) == str(shipped_checkpoint("kuafu", terrain, mixed=True))


SHIPPED = [(t, m) for t in ("flat", "slope", "random") for m in (False, True)]


@pytest.mark.parametrize(("terrain", "mixed"), SHIPPED)
def test_shipped_pseudo_critics_are_trained_in_the_metrics_units(terrain, mixed) -> None:
    # the surrogate of a shipped policy: trained (a normaliser that has seen data) and in the
    # units of the per-step metrics, which are all non-negative costs. Checkpoints whose
    # bootstrap had run away (docs/training.md, Pseudo-critics) held means of -1e9..1e13, or
    # NaN, which loads as untrained pseudo-critics (count 0)
    path = shipped_checkpoint("kuafu", terrain, mixed=mixed)
    assert path is not None, (
        f"Kuafu ships a {terrain} policy for the {'mixed' if mixed else 'continuous'} space"
    )
    state = read_checkpoint(path)
    norm = state["ppo"]["pseudo_norm"]
    mean, std = norm["mean"].double(), norm["var"].double().sqrt()
    assert state["objectives"] == ["tracking", "power", "torque"]
    assert float(norm["count"]) >= 500_000, "pseudo-critics never trained"
    assert torch.isfinite(mean).all() and torch.isfinite(std).all()
    assert (mean > 0).all(), mean
    assert (std < 100 * mean).all(), (mean, std)
    bank = state["ppo"]["pseudo_critic"]
    assert all(torch.isfinite(t).all() for t in bank.values())


@pytest.mark.parametrize(("init", "warm"), [("universal", True), ("scratch", False)])
def test_specialised_policies_start_from_the_universal_policy_or_from_scratch(init, warm) -> None:
    config = make_config(
        "quick",
        overrides={
            "method": "bo-specialized",
            "specialized_init": init,
            "population": 3,
            "agents_per_design": 2,
        },
    )
    parts = build_parts(config)
    assert not parts.pretrained  # the BO baseline shares no universal policy
    backend = parts.backend_factory(0).policy_factory(0)  # the policy of one design
    try:
        backend.train(np.array([[1.0, 1.0]]), 1, seed=0)  # builds the networks; one PPO iteration
        assert (
            backend.trainer.env.num_envs == 3 * 2
        )  # the universal training's batch, on one design
        shipped = read_checkpoint(shipped_checkpoint("kuafu", "flat"))["ppo"]["actor"][
            "body.0.weight"
        ]
        distance = float((actor_weight(backend) - shipped).abs().max())
        if warm:
            assert distance < 0.05  # one small update away from the shipped weights
        else:
            assert distance > 0.1  # a fresh initialisation
    finally:
        backend.close()
