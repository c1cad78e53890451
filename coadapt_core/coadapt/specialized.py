"""The backend of the BO baseline (`bo-specialized`, the paper's Table 7): no policy is
shared between designs; every design evaluated gets a policy trained on it alone, which
then evaluates it for real.

It implements the loop's `CoadaptationBackend` protocol over any policy backend (the
universal learner on one design, or the analytic fake in tests), so the co-adaptation loop
runs the baseline on its ordinary path: the method's backend kind (`BACKEND_KINDS` in
`coadapt_core.methods`) says there is no shared policy to train and no surrogate.

The policies of the last few designs evaluated stay in memory (`keep`, least recently used
first out, keyed by the design's exact value), so the final check's scenario blocks reuse
them instead of training again; `save_policy` writes one design's policy, which is how a
run hands back the policies of its best and nominal designs (`OWN_POLICY_FILES`).
"""

from __future__ import annotations

import json
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from coadapt_core.errors import CoadaptError
from coadapt_core.fitness import CoadaptationBackend, RealFitness, TrainingResult
from coadapt_core.objective import Objective

#: the optional per-design arrays of `RealFitness` that are stacked over designs when every
#: policy's evaluation measured them
_PER_DESIGN = (
    "survival",
    "per_scenario",
    "cost_se",
    "fall_rate",
    "scenario_falls",
    "tracking_ratio",
)

#: where a run without a shared policy leaves its best and nominal designs' policies, relative
#: to its run folder; readers look them up by these names, never by a path from a store
OWN_POLICY_FILES = {
    "best": "checkpoints/policy-best.pt",
    "nominal": "checkpoints/policy-nominal.pt",
}


@runtime_checkable
class OwnPolicies(Protocol):
    """A backend that holds a policy per design and can write one design's policy."""

    def save_policy(self, design: np.ndarray, path: str) -> list[TrainingResult]: ...


def design_key(design: np.ndarray) -> bytes:
    """The exact value of a design (float64 bytes): two designs share a policy only if equal."""
    return np.ascontiguousarray(design, dtype=np.float64).tobytes()


class SpecializedPolicyBackend:
    """A fresh policy per design: `policy_factory(seed)` builds it, `train_steps`
    interactions train it on that one design, and its real rollouts are the design's cost.

    The seeds of a design's policy (construction and training) are a function of the run's
    `seed` and of the design's value alone, so a design evaluated again (or after a resume)
    gets the same policy. The last `keep` policies stay in memory; an older one is trained
    again, with the same seeds, when its design comes back."""

    def __init__(
        self,
        policy_factory: Callable[[int], CoadaptationBackend],
        *,
        train_steps: int,
        seed: int = 0,
        keep: int = 4,
    ):
        self.policy_factory = policy_factory
        self.train_steps = int(train_steps)
        self.seed = int(seed)
        self.keep = max(1, int(keep))
        self._policies: OrderedDict[bytes, CoadaptationBackend] = OrderedDict()

    def policy_seeds(self, design: np.ndarray) -> tuple[int, int]:
        """(construction seed, training seed) of `design`'s policy."""
        words = np.frombuffer(design_key(design), dtype=np.uint32)
        state = np.random.SeedSequence([self.seed, *map(int, words)]).generate_state(2)
        return int(state[0] % (2**31 - 1)), int(state[1] % (2**31 - 1))

    def policy(self, design: np.ndarray) -> tuple[CoadaptationBackend, list[TrainingResult]]:
        """`design`'s policy and the training it took now ([] when it was kept)."""
        design = np.asarray(design, dtype=float)
        key = design_key(design)
        if key in self._policies:
            self._policies.move_to_end(key)
            return self._policies[key], []
        policy_seed, train_seed = self.policy_seeds(design)
        policy = self.policy_factory(policy_seed)
        trained = policy.train(design[None, :], self.train_steps, seed=train_seed)
        self._policies[key] = policy
        while len(self._policies) > self.keep:
            _, old = self._policies.popitem(last=False)
            _close(old)
        return policy, [trained]

    def train(self, designs: np.ndarray, steps: int, *, seed: int = 0) -> TrainingResult:
        """Nothing is shared, so nothing is trained here: each design's policy is trained
        when the design is evaluated (`real_fitness`)."""
        return TrainingResult(steps=0, seconds=0.0, mean_reward=float("nan"))

    def real_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        *,
        agents: int,
        steps: int,
        seed: int = 0,
    ) -> RealFitness:
        """Each design's policy (trained now unless kept) rolled out on the scenario set of
        `seed`; the training phases come back in `RealFitness.training`."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        fits, trainings = [], []
        for design in designs:
            policy, trained = self.policy(design)
            trainings += trained
            fits.append(
                policy.real_fitness(
                    design[None, :], objectives, agents=agents, steps=steps, seed=seed
                )
            )
        fit = stack_fits(fits)
        fit.training = trainings
        return fit

    def surrogate_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray:
        raise CoadaptError(
            "specialised policies have no surrogate: every design is evaluated for real"
        )

    def save_policy(self, design: np.ndarray, path: str) -> list[TrainingResult]:
        """Write `design`'s policy with its own `save` (trained first unless kept); returns
        the training that took."""
        policy, trained = self.policy(design)
        policy.save(path)
        return trained

    def save(self, path: str) -> None:
        """Nothing is shared between designs; what identifies the backend is written."""
        with open(path, "w", encoding="utf-8") as f:
            json.dump(
                {"backend": "specialized", "train_steps": self.train_steps, "seed": self.seed}, f
            )

    def load(self, path: str) -> None:
        """Nothing to restore (see `save`)."""

    def numerics(self) -> dict[str, Any]:
        """The numerics of the designs' policies (the last one kept: they are all built by
        the same factory), {} before any was built (`coadapt_core.numerics`)."""
        for policy in reversed(self._policies.values()):
            report = getattr(policy, "numerics", None)
            return dict(report()) if callable(report) else {}
        return {}

    def close(self) -> None:
        """Close the kept policies."""
        while self._policies:
            _close(self._policies.popitem()[1])


def _close(policy: Any) -> None:
    close = getattr(policy, "close", None)
    if callable(close):
        close()


def stack_fits(fits: Sequence[RealFitness]) -> RealFitness:
    """One RealFitness with the designs of `fits` (each its own policy's) as rows; the
    optional per-design arrays (`_PER_DESIGN`) kept when every fit has them."""
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
        **extra,
    )
