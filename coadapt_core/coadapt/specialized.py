"""The backend of the BO baseline (`bo-specialized`, the paper's Table 7): no policy is
shared between designs; every design evaluated gets a policy trained on it alone, which
then evaluates it for real.

It implements the loop's `CoadaptationBackend` protocol over any policy backend (the
universal learner on one design, or the analytic fake in tests), so the co-adaptation loop
runs the baseline on its ordinary path: the method's backend kind (`BACKEND_KINDS` in
`coadapt_core.methods`) says there is no shared policy to train and no surrogate.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from coadapt_core.errors import CoadaptError
from coadapt_core.fitness import CoadaptationBackend, RealFitness, TrainingResult
from coadapt_core.objective import Objective

#: the optional per-design arrays of `RealFitness` that are stacked over designs when every
#: policy's evaluation measured them
_PER_DESIGN = ("survival", "per_scenario", "cost_se", "fall_rate", "tracking_ratio")


class SpecializedPolicyBackend:
    """A fresh policy per design: `policy_factory(seed)` builds it, `train_steps`
    interactions train it on that one design, and its real rollouts are the design's cost.

    The seeds of a design's policy (construction and training) are a function of the run's
    `seed` and of the design's value alone, so a design evaluated again (or after a resume)
    gets the same policy."""

    def __init__(self, policy_factory: Callable[[int], CoadaptationBackend], *, train_steps: int, seed: int = 0):
        self.policy_factory = policy_factory
        self.train_steps = int(train_steps)
        self.seed = int(seed)

    def policy_seeds(self, design: np.ndarray) -> tuple[int, int]:
        """(construction seed, training seed) of `design`'s policy."""
        words = np.frombuffer(np.ascontiguousarray(design, dtype=np.float64).tobytes(), dtype=np.uint32)
        state = np.random.SeedSequence([self.seed, *map(int, words)]).generate_state(2)
        return int(state[0] % (2**31 - 1)), int(state[1] % (2**31 - 1))

    def train(self, designs: np.ndarray, steps: int, *, seed: int = 0) -> TrainingResult:
        """Nothing is shared, so nothing is trained here: each design's policy is trained
        when the design is evaluated (`real_fitness`)."""
        return TrainingResult(steps=0, seconds=0.0, mean_reward=float("nan"))

    def real_fitness(
        self, designs: np.ndarray, objectives: Sequence[Objective], *, agents: int, steps: int, seed: int = 0
    ) -> RealFitness:
        """Train each design's policy, then roll it out on the scenario set of `seed`; the
        training phases come back in `RealFitness.training`."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        fits, trainings = [], []
        for design in designs:
            policy_seed, train_seed = self.policy_seeds(design)
            policy = self.policy_factory(policy_seed)
            trainings.append(policy.train(design[None, :], self.train_steps, seed=train_seed))
            fits.append(policy.real_fitness(design[None, :], objectives, agents=agents, steps=steps, seed=seed))
        extra: dict[str, Any] = {}
        for name in _PER_DESIGN:
            values = [getattr(f, name) for f in fits]
            if all(v is not None for v in values):
                extra[name] = np.concatenate([np.asarray(v) for v in values])
        return RealFitness(
            costs=np.concatenate([np.asarray(f.costs, dtype=float).reshape(1, -1) for f in fits]),
            buffer=None,  # no shared policy, so no states for a surrogate
            interactions=sum(int(f.interactions) for f in fits),
            seconds=sum(float(f.seconds) for f in fits),
            training=trainings,
            **extra,
        )

    def surrogate_fitness(
        self, designs: np.ndarray, objectives: Sequence[Objective], buffer: Any, *, samples: int, seed: int = 0
    ) -> np.ndarray:
        raise CoadaptError("specialised policies have no surrogate: every design is evaluated for real")

    def save(self, path: str) -> None:
        """Nothing is kept between designs; what identifies the backend is written."""
        with open(path, "w", encoding="utf-8") as f:
            json.dump({"backend": "specialized", "train_steps": self.train_steps, "seed": self.seed}, f)

    def load(self, path: str) -> None:
        """Nothing to restore (see `save`)."""
