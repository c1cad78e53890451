"""The pseudo-critics paused while training until the policy walks, then fitted on the walking
policy with it frozen (`train_until_walks(pseudo_catch_up=K)`, `coadapt train --until-walks
--pseudo-catch-up K`): paused, their weights, normaliser and optimizer stay as they were at
every check; the policy trains to the bit as when they train along; once a check walks they
are fitted and the policy the check judged is unchanged. On the fake simulator (the loop's
logic); tests/core/test_train_until_walks.py runs the command on MuJoCo."""

from __future__ import annotations

import torch

from coadapt_core.experiments.walking_check import train_until_walks
from coadapt_core.learning.flops import update_passes
from coadapt_core.learning.runner import Runner
from tests.core.test_learning_ppo import make_trainer, small_config


def _state(module) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def _equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _runner(fake_robot, fake_sim_cls) -> Runner:
    trainer = make_trainer(fake_robot, fake_sim_cls, small_config(epochs=2, minibatches=2))
    trainer.set_designs(trainer.sample_designs())
    return Runner(trainer)


def _until_walks(runner: Runner, walks_at: int, catch_up: int) -> tuple[list, object]:
    """Train with a check every iteration that walks at the `walks_at`-th; each check
    records the pseudo-critics' weights, normaliser and optimizer as they are then."""
    ppo, seen = runner.trainer.ppo, []

    def check() -> dict:
        seen.append(
            (
                _state(ppo.pseudo_critic),
                _state(ppo.pseudo_norm),
                len(ppo.pseudo_optimizer.state),  # Adam keeps no moments before its first step
            )
        )
        return {"walking": len(seen) == walks_at, "worst": "nominal", "designs": {}}

    steps = 10 * runner.trainer.samples_per_iteration
    done = train_until_walks(
        runner, steps=steps, check=check, check_every=1, pseudo_catch_up=catch_up
    )
    return seen, done


def test_paused_pseudo_critics_stay_as_they_were_at_every_check(fake_robot, fake_sim_cls):
    runner = _runner(fake_robot, fake_sim_cls)
    ppo = runner.trainer.ppo
    initial, initial_norm = _state(ppo.pseudo_critic), _state(ppo.pseudo_norm)
    ppo.pseudo_paused = True  # the learner's ceiling counts no pseudo-critic pass then
    assert "pseudo" not in {p.network for p in update_passes(ppo, 64)}
    ppo.pseudo_paused = False
    assert "pseudo" in {p.network for p in update_passes(ppo, 64)}
    seen, done = _until_walks(runner, walks_at=3, catch_up=4)
    assert done.walked and len(seen) == 3
    for weights, norm, moments in seen:  # three updates later, nothing of theirs moved
        assert _equal(weights, initial) and _equal(norm, initial_norm) and moments == 0
    assert done.interactions == 3 * runner.trainer.samples_per_iteration
    # then the fit: 4 iterations, the heads moved away from their start, the learner as before
    assert done.catch_up_interactions == 4 * runner.trainer.samples_per_iteration
    assert runner.trainer.iteration == 7 and done.catch_up_seconds > 0
    fitted = _state(ppo.pseudo_critic)
    assert all(not torch.equal(fitted[k], initial[k]) for k in fitted if k.endswith("weight"))
    assert not ppo.pseudo_paused and not ppo.policy_frozen


def test_the_pause_leaves_the_policy_as_training_them_would_and_the_fit_freezes_it(
    fake_robot, fake_sim_cls
):
    along = _runner(fake_robot, fake_sim_cls)
    _, done = _until_walks(along, walks_at=3, catch_up=0)
    assert done.catch_up_interactions == 0 and along.trainer.iteration == 3
    # trained along (catch-up 0): the heads moved
    start = _state(_runner(fake_robot, fake_sim_cls).trainer.ppo.pseudo_critic)
    assert not _equal(_state(along.trainer.ppo.pseudo_critic), start)
    paused = _runner(fake_robot, fake_sim_cls)  # the same seed: the same start
    before_fit = {}

    def remember(stats) -> None:
        if paused.trainer.iteration == 3:
            ppo = paused.trainer.ppo
            before_fit.update(actor=_state(ppo.actor_net), critic=_state(ppo.critic_net))

    ppo = paused.trainer.ppo
    train_until_walks(
        paused,
        steps=10 * paused.trainer.samples_per_iteration,
        check=lambda: {"walking": paused.trainer.iteration == 3, "worst": "n", "designs": {}},
        check_every=1,
        pseudo_catch_up=2,
        on_iteration=remember,
    )
    a = along.trainer.ppo
    # the policy the check judged is the one trained along, to the bit, and the fit kept it
    assert _equal(before_fit["actor"], _state(a.actor_net))
    assert _equal(before_fit["critic"], _state(a.critic_net))
    assert _equal(_state(ppo.actor_net), before_fit["actor"])
    assert _equal(_state(ppo.critic_net), before_fit["critic"])
    assert _equal(_state(ppo.obs_norm), _state(a.obs_norm))
