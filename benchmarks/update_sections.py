"""Where one PPO update's time goes: `compute_returns` + `update` of a `PPO` split by wall clock
into the network passes (the learner's ceiling's work: forward and backward of actor, critic
and pseudo-critics, GAE's critic values included) and each part that is not, timed by wrapping
the calls the update makes (on the CPU every call is synchronous, so each time is exact; on a
GPU set `ppo.profile`). Exclusive times: a section nested in another is not counted twice.

Used by `benchmarks/train_throughput.py` (`update_sections`)."""

from __future__ import annotations

import inspect
import time
from collections import defaultdict
from contextlib import contextmanager

import torch

#: label -> what it holds, in the order printed
SECTIONS = {
    "network_passes": "actor, critic and pseudo-critic forward and backward passes",
    "loss_elementwise": "the PPO loss around the networks: distribution, ratio, advantage "
    "normalisation, clipping, entropy",
    "gae_recursion": "GAE's recursion around its critic values",
    "pseudo_targets": "the pseudo-critics' target recursion",
    "optimizer": "Adam's steps and zero_grad, both optimizers",
    "grad_clip": "gradient-norm clipping, both optimizers",
    "rest": "the rest: stacking the rollout, the minibatch gathers, casts of the losses, "
    "statistics and Python",
}


class UpdateSections:
    """Wraps a `PPO`'s calls while `active()`; `seconds` per section and `total`."""

    def __init__(self, ppo):
        import coadapt_core.learning.ppo as ppo_module

        self.seconds: dict[str, float] = defaultdict(float)
        self.total = 0.0
        self._stack: list[float] = []
        self._on = False
        nets = [ppo.actor_net, ppo.critic_net] + (
            [ppo.pseudo_critic] if ppo.pseudo_critic is not None else []
        )
        self._wrapped = [(net, "forward", "network_passes") for net in nets]
        self._wrapped += [
            (ppo.loss, "forward", "loss_elementwise"),
            (ppo.gae, "forward", "gae_recursion"),
            (ppo_module, "discounted_average_targets", "pseudo_targets"),
            (torch.Tensor, "backward", "network_passes"),
            (torch.nn.utils, "clip_grad_norm_", "grad_clip"),
        ]
        for opt in (ppo.optimizer, ppo.pseudo_optimizer):
            if opt is not None:
                self._wrapped += [(opt, "step", "optimizer"), (opt, "zero_grad", "optimizer")]
        self._saved = []

    def _timed(self, fn, label):
        def run(*args, **kwargs):
            if not self._on:
                return fn(*args, **kwargs)
            start = time.perf_counter()
            self._stack.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.perf_counter() - start
                self.seconds[label] += spent - self._stack.pop()
                self._stack[-1] += spent

        return run

    @contextmanager
    def installed(self):
        """The wrappers in place (outside `active`, they only pass the call on)."""
        self._saved = [(obj, name, getattr(obj, name)) for obj, name, _ in self._wrapped]
        for (obj, name, label), (_, _, fn) in zip(self._wrapped, self._saved, strict=True):
            setattr(obj, name, self._timed(fn, label))
        try:
            yield self
        finally:
            for obj, name, fn in self._saved:
                if inspect.ismodule(obj) or isinstance(obj, type):
                    setattr(obj, name, fn)
                else:  # an instance's own attribute: remove it, the class's method shows again
                    obj.__dict__.pop(name, None)

    @contextmanager
    def active(self):
        """Count the wrapped calls made inside; the whole block's time is `total`."""
        self._on, start = True, time.perf_counter()
        self._stack.append(0.0)
        try:
            yield
        finally:
            spent = time.perf_counter() - start
            self.seconds["rest"] += spent - self._stack.pop()
            self.total += spent
            self._on = False

    def report(self, updates: int) -> dict:
        """Seconds per update and share of `compute_returns` + `update`, per section."""
        total = max(self.total, 1e-12)
        return {
            k: {
                "seconds": round(self.seconds[k] / updates, 4),
                "share": round(self.seconds[k] / total, 3),
            }
            for k in SECTIONS
        }
