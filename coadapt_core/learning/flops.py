"""The learner's arithmetic and its ceiling: the matrix passes one PPO update makes (what
`PPO.compute_returns` and `PPO.update` multiply, counted by torch's FLOP counter) and the same
networks' forward and backward passes at those shapes, timed alone: the update's own ceiling,
which `benchmarks/train_throughput.py` prints its achieved GFLOP/s against."""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import torch
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils.flop_counter import flop_registry


class _FlopCounter(TorchDispatchMode):
    """torch's FLOP formulas (`flop_registry`) over every operator dispatched; without
    `FlopCounterMode`'s module tracker, which cannot hash TorchRL's modules."""

    def __init__(self):
        super().__init__()
        self.flops = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        out = func(*args, **kwargs)
        formula = flop_registry.get(func._overloadpacket)
        if formula is not None:
            self.flops += int(formula(*args, **kwargs, out_val=out))
        return out


def matrix_flops(fn: Callable[[], object]) -> int:
    """FLOPs of the matrix products (mm, addmm, bmm, baddbmm, ...) that `fn()` runs, forward
    and backward; elementwise work (activations, the optimizer) is not counted."""
    with _FlopCounter() as counter:
        fn()
    return counter.flops


@dataclass(frozen=True)
class Pass:
    """One kind of network pass in an update: `network` ("actor", "critic", "pseudo") on
    `batch` samples, forward only or forward and backward, `count` times per update, in the
    numerics `precision` ("float32" | "bf16", autocast as `PPO._autocast`)."""

    network: str
    backward: bool
    batch: int
    count: int
    precision: str = "float32"


def update_passes(ppo, samples: int) -> list[Pass]:
    """The network passes of one `compute_returns` + `update` of `ppo` on a rollout of
    `samples` transitions: GAE's critic values of s and s' (one batch of both, in float32:
    outside the loss's autocast) and the pseudo-critics' values of s' (forward only), then per
    minibatch the actor's and critic's forward and backward (the clipped PPO loss) and, in
    their epochs, the pseudo-critics'. Under symmetry each minibatch's mirror image is one more
    call of the PPO loss."""
    c = ppo.config
    size = max(samples // c.minibatches, 1)
    minibatches = len(range(0, samples - size + 1, size))  # as `PPO.update` loops
    pseudo_epochs = c.pseudo_epochs or c.epochs
    passes = []
    calls = c.epochs * minibatches * (1 if getattr(ppo, "mirror", None) is None else 2)
    if not ppo.policy_frozen:
        passes += [
            # TorchRL's GAE: one call of the critic on s and s' together
            Pass("critic", False, 2 * samples, 1, "float32"),
            Pass("actor", True, size, calls, ppo.precision),
            Pass("critic", True, size, calls, ppo.precision),
        ]
    if ppo.pseudo_critic is not None and not getattr(ppo, "pseudo_paused", False):
        epochs = pseudo_epochs if ppo.policy_frozen else min(pseudo_epochs, c.epochs)
        passes += [
            Pass("pseudo", False, samples, 1, ppo.pseudo_precision),
            Pass("pseudo", True, size, epochs * minibatches, ppo.pseudo_precision),
        ]
    return passes


def pass_runner(ppo, p: Pass) -> Callable[[], object]:
    """One pass `p` of a copy of `ppo`'s network on random inputs, in the numerics the update
    uses for it (the learner's parameters and gradients untouched)."""
    network, backward, batch = p.network, p.backward, p.batch
    dims, device = ppo.dims, ppo.device
    net = copy.deepcopy(
        {"actor": ppo.actor_net, "critic": ppo.critic_net, "pseudo": ppo.pseudo_critic}[network]
    )
    width = dims.num_obs if network == "actor" else dims.num_critic_obs
    generator = torch.Generator(device=device).manual_seed(0)
    inputs = (
        torch.randn(batch, width, device=device, generator=generator),
        torch.rand(batch, dims.num_design, device=device, generator=generator),
    )

    def run() -> object:
        with torch.set_grad_enabled(backward), ppo._autocast(p.precision):
            out = net(*inputs)
        if not backward:
            return out
        outputs = out if isinstance(out, tuple) else (out,)
        net.zero_grad(set_to_none=True)
        sum(o.float().sum() for o in outputs).backward()
        return None

    return run


@dataclass
class LearnerCeiling:
    """What one update's matrix work costs at the rate the same networks reach alone.

    flops: matrix FLOPs of one update; seconds: the time its passes take timed alone (each
    pass kind timed `repeats` times, its mean, times its count); rates: GFLOP/s of each pass
    kind ("actor fwd+bwd x1536": ...)."""

    flops: int
    seconds: float
    rates: dict[str, float] = field(default_factory=dict)

    @property
    def gflops_per_s(self) -> float:
        return self.flops / self.seconds / 1e9


def learner_ceiling(ppo, samples: int, repeats: int = 5) -> LearnerCeiling:
    """Time the network passes of one update of `ppo` on `samples` transitions
    (`update_passes`), each kind alone (one warm-up, then `repeats` timed), on the current
    torch threads; count their FLOPs."""
    flops = seconds = 0.0
    rates = {}
    for p in update_passes(ppo, samples):
        run = pass_runner(ppo, p)
        run()  # warm-up (allocator, kernels)
        pass_flops = matrix_flops(run)
        if ppo.device.type == "cuda":
            torch.cuda.synchronize(ppo.device)
        start = time.perf_counter()
        for _ in range(repeats):
            run()
        if ppo.device.type == "cuda":
            torch.cuda.synchronize(ppo.device)
        each = (time.perf_counter() - start) / repeats
        kind = f"{p.network} {'fwd+bwd' if p.backward else 'fwd'} x{p.batch} {p.precision}"
        rates[kind] = pass_flops / each / 1e9
        flops += pass_flops * p.count
        seconds += each * p.count
    return LearnerCeiling(int(flops), seconds, rates)
