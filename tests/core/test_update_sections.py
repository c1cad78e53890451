"""benchmarks/update_sections.py: where the update's time goes, by section. The sections
cover `compute_returns` + `update` exactly once (shares sum to 1), each part the update makes
is seen, the wrappers change nothing the learner computes and leave nothing behind."""

from __future__ import annotations

import pytest
import torch

from tests.benchmarks import load_benchmark
from tests.core.test_learning_ppo import make_trainer, small_config


def _weights(trainer) -> list[torch.Tensor]:
    return [p.detach().clone() for p in trainer.ppo.loss.parameters()] + [
        p.detach().clone() for p in trainer.ppo.pseudo_critic.parameters()
    ]


def test_sections_cover_the_update_once_and_change_nothing(fake_robot, fake_sim_cls):
    mod = load_benchmark("update_sections")
    plain = make_trainer(fake_robot, fake_sim_cls, small_config())
    plain.learn(2)
    timed = make_trainer(fake_robot, fake_sim_cls, small_config())
    timed.learn(1)  # the learner is built with the first designs
    ppo = timed.ppo
    backward, clip = torch.Tensor.backward, torch.nn.utils.clip_grad_norm_
    sections = mod.UpdateSections(ppo)
    returns, update = ppo.compute_returns, ppo.update

    def wrapped(fn):
        def run():
            with sections.active():
                return fn()

        return run

    ppo.compute_returns, ppo.update = wrapped(returns), wrapped(update)
    with sections.installed():
        timed.learn(1)
    del ppo.compute_returns, ppo.update
    # the same training to the bit
    assert all(torch.equal(a, b) for a, b in zip(_weights(plain), _weights(timed), strict=True))
    report = sections.report(1)
    assert list(report) == list(mod.SECTIONS)
    assert sum(r["share"] for r in report.values()) == pytest.approx(1.0, abs=0.01)
    assert sum(r["seconds"] for r in report.values()) == pytest.approx(sections.total, rel=0.01)
    # every section saw work (3 epochs x 2 minibatches: steps, clips, passes, the recursions)
    assert all(r["seconds"] > 0 for r in report.values()), report
    assert report["network_passes"]["share"] > 0.2
    # nothing left behind: the classes' methods and the module functions are back
    assert "forward" not in vars(ppo.actor_net) and "step" not in vars(ppo.optimizer)
    assert torch.Tensor.backward is backward and torch.nn.utils.clip_grad_norm_ is clip
    before = sections.total
    timed.learn(1)  # outside `installed`: nothing is counted
    assert sections.total == before
