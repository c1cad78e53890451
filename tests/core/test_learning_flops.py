"""The learner's arithmetic: the passes `update_passes` lists are the matrix work of a real
update, FLOP for FLOP, and the ceiling times them."""

from __future__ import annotations

import torch

from coadapt_core.learning.flops import (
    Pass,
    learner_ceiling,
    matrix_flops,
    pass_runner,
    update_passes,
)
from tests.core.test_learning_ppo import make_trainer, small_config


def _collected(fake_robot, fake_sim_cls, **over):
    trainer = make_trainer(fake_robot, fake_sim_cls, small_config(**over))
    trainer.learn(1)
    trainer._collect(trainer.env, trainer.ppo, trainer._obs)
    return trainer


def _pass_flops(ppo, p) -> int:
    return matrix_flops(pass_runner(ppo, p))


def test_a_pass_counts_two_flops_per_multiply_add_and_no_gradient_for_its_inputs(
    fake_robot, fake_sim_cls
) -> None:
    """The actor MLP (obs + design -> 64 -> 64 -> actions) on 8 rows: forward 2 B sum(in out);
    backward the weight gradients of every layer and the input gradients of all but the first."""
    trainer = _collected(fake_robot, fake_sim_cls)
    ppo = trainer.ppo
    d = ppo.dims
    layers = [(d.num_obs + d.num_design, 64), (64, 64), (64, d.num_actions)]
    forward = 2 * 8 * sum(i * o for i, o in layers)
    backward = 2 * 8 * sum(i * o for i, o in layers) + 2 * 8 * sum(i * o for i, o in layers[1:])
    assert _pass_flops(ppo, Pass("actor", False, 8, 1)) == forward
    assert _pass_flops(ppo, Pass("actor", True, 8, 1)) == forward + backward


def test_update_passes_are_the_matrix_work_of_a_real_update(fake_robot, fake_sim_cls) -> None:
    """compute_returns + update under torch's FLOP counter multiply exactly what the listed
    passes do (3 epochs x 2 minibatches, one pseudo-critic epoch, GAE's and the targets'
    forward passes): the ceiling times the update's own work, nothing more, nothing less."""
    trainer = _collected(fake_robot, fake_sim_cls)
    ppo = trainer.ppo
    samples = trainer.env.num_envs * trainer.config.steps_per_env
    passes = update_passes(ppo, samples)
    assert [(p.network, p.backward, p.count) for p in passes] == [
        ("critic", False, 1),
        ("actor", True, 6),
        ("critic", True, 6),
        ("pseudo", False, 1),
        ("pseudo", True, 2),
    ]
    listed = sum(_pass_flops(ppo, p) * p.count for p in passes)
    counted = matrix_flops(lambda: (ppo.compute_returns(), ppo.update()))
    assert counted == listed > 0


def test_frozen_policy_lists_only_the_pseudo_critics_passes(fake_robot, fake_sim_cls) -> None:
    trainer = _collected(fake_robot, fake_sim_cls, pseudo_epochs=2)
    ppo = trainer.ppo
    ppo.freeze_policy()
    samples = trainer.env.num_envs * trainer.config.steps_per_env
    passes = update_passes(ppo, samples)
    assert [(p.network, p.backward, p.batch, p.count) for p in passes] == [
        ("pseudo", False, samples, 1),
        ("pseudo", True, samples // 2, 4),
    ]
    listed = sum(_pass_flops(ppo, p) * p.count for p in passes)
    assert matrix_flops(lambda: (ppo.compute_returns(), ppo.update())) == listed


def test_ceiling_counts_the_update_and_leaves_the_learner_untouched(
    fake_robot, fake_sim_cls
) -> None:
    trainer = _collected(fake_robot, fake_sim_cls)
    ppo = trainer.ppo
    before = {k: v.clone() for k, v in ppo.actor_net.state_dict().items()}
    grads = [None if p.grad is None else p.grad.clone() for p in ppo.actor_net.parameters()]
    samples = trainer.env.num_envs * trainer.config.steps_per_env
    ceiling = learner_ceiling(ppo, samples, repeats=2)
    listed = sum(_pass_flops(ppo, p) * p.count for p in update_passes(ppo, samples))
    assert ceiling.flops == listed
    assert ceiling.seconds > 0 and ceiling.gflops_per_s == ceiling.flops / ceiling.seconds / 1e9
    assert set(ceiling.rates) == {
        f"critic fwd x{2 * samples} float32",
        f"actor fwd+bwd x{samples // 2} {ppo.precision}",
        f"critic fwd+bwd x{samples // 2} {ppo.precision}",
        f"pseudo fwd x{samples} {ppo.pseudo_precision}",
        f"pseudo fwd+bwd x{samples // 2} {ppo.pseudo_precision}",
    }
    assert all(torch.equal(v, before[k]) for k, v in ppo.actor_net.state_dict().items())
    after = [p.grad for p in ppo.actor_net.parameters()]
    assert all(a is b is None or torch.equal(a, b) for a, b in zip(after, grads, strict=True))
