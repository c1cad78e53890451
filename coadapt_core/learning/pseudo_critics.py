"""The pseudo-critics V_pseudo(s, xi), one per objective.

Pseudo-critics (paper section 3.2.2) share the critic's architecture and inputs (s, xi) but
are excluded from the policy update: they live in their own optimizer and regress, per
objective m, the discounted-average metric

    target_t = (1 - gamma) sum_k gamma^k P_{m, t+k}

(TD(lambda) estimate, bootstrapped with the pseudo-critic itself), whose scale equals the
per-step metric — so the surrogate fitness (mean of V_pseudo over states, Algorithm 3) is
directly comparable with the real fitness (mean of P over steps, Algorithm 2). A fall does
not end the metric stream (the real fitness keeps averaging after an auto-reset), so both
terminations and timeouts bootstrap from the pseudo-critic at the final state.

Two things keep the bootstrap from feeding on itself (before they did, every long fine-tune
diverged: the bootstrap values grew past anything the metric reached, the running scale grew
with them, and after ~1 M steps the surrogate ranked designs backwards):
- targets are normalised per objective by running statistics of the per-step metric P itself,
  data the pseudo-critics do not produce, so their own errors cannot inflate the scale
  (predictions are de-normalised with the same statistics);
- bootstrap values are clamped to the range the metric spans in the rollout: a discounted
  average of P cannot leave [min P, max P].

`PPO` trains them (`PPO.compute_returns`, `PPO.update`); what the surrogate reads of them is
a `PseudoCritics` record (`PPO.pseudo_critics`), so no one outside the learner reads its
layers or normalisers.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.networks import CriticBank, EmpiricalNormalization


@dataclass(frozen=True)
class PseudoCritics:
    """The trained pseudo-critics as the surrogate reads them: `bank`, one head per objective
    (M of them), whose raw outputs times `scale` plus `offset` ([M] each) are in units of the
    per-step metric."""

    bank: CriticBank
    scale: torch.Tensor
    offset: torch.Tensor


def discounted_average_targets(
    metrics: torch.Tensor,  # [N, T, M] per-step metric P_t
    value_next: torch.Tensor,  # [N, T, M] pseudo-critic at s_{t+1} (the final state where done)
    done: torch.Tensor,  # [N, T, 1] bool, the episode ended after step t
    gamma: float,
    lam: float,
) -> torch.Tensor:
    """[N, T, M] TD(lambda) targets of (1 - gamma) sum_k gamma^k P_{t+k}: a constant metric
    c has target c. Episode ends (falls and timeouts alike) and the rollout end bootstrap
    from `value_next`."""
    done = done.to(metrics.dtype)
    target = torch.empty_like(metrics)
    following = value_next[:, -1]
    for t in reversed(range(metrics.shape[1])):
        if t == metrics.shape[1] - 1:
            blend = value_next[:, t]
        else:
            blend = (1 - lam) * value_next[:, t] + lam * following
        boot = done[:, t] * value_next[:, t] + (1 - done[:, t]) * blend
        target[:, t] = (1 - gamma) * metrics[:, t] + gamma * boot
        following = target[:, t]
    return target


def new_pseudo_critics(
    num_critic_obs: int, num_design: int, num_metrics: int, config: TrainConfig, device
) -> tuple[CriticBank | None, EmpiricalNormalization, torch.optim.Adam | None]:
    """Fresh pseudo-critics (None when there are no objectives), their target normaliser
    and their optimizer."""
    norm = EmpiricalNormalization(max(num_metrics, 1), eps=1e-8, clip=1e9).to(device)
    if num_metrics == 0:
        return None, norm, None
    net = CriticBank(
        num_critic_obs, num_design, config.hidden, config.activation, outputs=num_metrics
    ).to(device)
    optimizer = torch.optim.Adam(net.parameters(), lr=config.pseudo_learning_rate, foreach=True)
    return net, norm, optimizer


def all_finite(*modules: torch.nn.Module) -> bool:
    """Whether every floating-point entry of the modules' states is finite."""
    return all(
        bool(torch.isfinite(t).all())
        for m in modules
        for t in m.state_dict().values()
        if t.is_floating_point()
    )
