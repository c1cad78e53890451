"""The seams of the co-adaptation loop (Algorithm 4): what the loop needs from the inner
loop (universal policy training, Algorithm 1) and from fitness evaluation (real rollouts,
Algorithm 2; pseudo-critic surrogate, Algorithm 3), and where it records results.

The loop depends only on these protocols, so it runs unchanged on the real learner
(`coadapt_core.learning`) and on the analytic fake used by the tests. How per-scenario costs
become a design's cost and its standard error is `coadapt_core.costs`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from coadapt_core.errors import CoadaptError
from coadapt_core.objective import Objective


@dataclass
class TrainingResult:
    """One training phase (Algorithm 1) on a set of designs."""

    steps: int  # environment interactions used
    seconds: float
    mean_reward: float  # mean per-step reward over the last iteration
    extra: dict[str, float] = field(default_factory=dict)
    # optional evaluation buffer R_eval filled from the training rollouts (states the
    # surrogate can average over); lets `--method no-real` run with 0 evaluation interactions
    buffer: Any = None


@dataclass
class RealFitness:
    """Algorithm 2 on K designs."""

    costs: np.ndarray  # [K, M] mean per-step metric of each objective
    buffer: Any  # evaluation buffer R_eval (states for the surrogate), opaque to the loop
    interactions: int  # environment steps spent
    seconds: float
    survival: np.ndarray | None = None  # [K] fraction of agents that did not fall
    # paired evaluation (optional: a backend without them still drives the loop; the loop
    # then reports no standard errors). Scenario a (agent a) is the same for every design of
    # a call and of every call with the same seed, so differences are paired.
    per_scenario: np.ndarray | None = None  # [K, A, M] each scenario's mean per-step cost
    cost_se: np.ndarray | None = None  # [K, M] standard error of `costs` over scenarios
    fall_rate: np.ndarray | None = None  # [K] share of scenarios (agents) that fell at least once
    scenario_falls: np.ndarray | None = (
        None  # [K, A] bool: scenario a of design k fell at least once
    )
    # the walking gate (coadapt_core.coadapt.reliability): RMS velocity tracking error over the
    # RMS commanded velocity, per design (0 = perfect, 1 = no better than standing still)
    tracking_ratio: np.ndarray | None = None  # [K]
    # policies this evaluation had to train first (a backend without a shared policy trains
    # one per design, `coadapt_core.coadapt.specialized`): the loop counts their steps as
    # training interactions and records each phase; `interactions` above excludes them
    training: list[TrainingResult] = field(default_factory=list)


@runtime_checkable
class CoadaptationBackend(Protocol):
    """Inner loop and fitness evaluation over designs [K, design_dim].

    The universal-policy learner (`coadapt_core.learning.factory.make_backend`) shares one
    policy between designs. A method whose backend kind shares none (`BACKEND_KINDS` in
    `coadapt_core.methods`; the BO baseline's `coadapt_core.coadapt.specialized`) is never
    asked to `train` or for `surrogate_fitness`: its `real_fitness` trains what it needs and
    reports those phases in `RealFitness.training`."""

    def train(self, designs: np.ndarray, steps: int, *, seed: int = 0) -> TrainingResult:
        """Train (or fine-tune) the universal policy, critic and pseudo-critics on `designs`."""

    def real_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        *,
        agents: int,
        steps: int,
        seed: int = 0,
    ) -> RealFitness:
        """Roll out `agents` copies of each design for `steps` policy steps."""

    def surrogate_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray:
        """[K, M] mean pseudo-critic prediction over `samples` states drawn from `buffer`
        with each candidate's design substituted. No environment interaction."""

    def save(self, path: str) -> None:
        """Checkpoint policy, critics, normalizers and optimizer state."""

    def load(self, path: str) -> None:
        """Restore what `save` wrote."""


@runtime_checkable
class SurrogateEnsemble(Protocol):
    """The surrogate fitted to real rounds (docs/coadaptation.md, "The surrogate"): copies of
    the pseudo-critics refitted, as an ensemble, to the current policy's real rounds. A
    backend that offers it declares `surrogate_ensemble = True` and implements both methods
    (`coadapt_core.testing.BackendConformance` checks); the loop then fits it before a
    surrogate round, records the members' spread on real rounds, and the `uncertainty`
    evaluation policy asks it. A backend without it runs every surrogate round on the
    paper's estimator (`CoadaptationBackend.surrogate_fitness`), and under `uncertainty`
    every round is real."""

    surrogate_ensemble: bool

    def fit_surrogate(
        self,
        designs: np.ndarray,
        costs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        seed: int = 0,
    ) -> None:
        """Fit the ensemble to labelled designs [N, D] and their real costs [N, M] on the
        states of `buffer`; until `train` changes the policy, `surrogate_fitness` is the
        members' mean."""

    def surrogate_members(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray | None:
        """[E, K, M] each member's prediction (mean over `samples` states of `buffer`), or
        None when nothing is fitted (before `fit_surrogate`, after `train`)."""


#: the methods a backend declaring `surrogate_ensemble` implements
SURROGATE_ENSEMBLE_METHODS: tuple[str, ...] = ("fit_surrogate", "surrogate_members")


def surrogate_ensemble(backend: object) -> SurrogateEnsemble | None:
    """`backend` as a `SurrogateEnsemble` when it declares one (`surrogate_ensemble = True`),
    else None. One that declares it without implementing it is a one-line error naming
    what is missing."""
    if getattr(backend, "surrogate_ensemble", False) is not True:
        return None
    missing = [
        name for name in SURROGATE_ENSEMBLE_METHODS if not callable(getattr(backend, name, None))
    ]
    if missing:
        raise CoadaptError(
            f"backend {type(backend).__name__} declares surrogate_ensemble but has no "
            f"{', '.join(missing)} (coadapt_core.fitness.SurrogateEnsemble)"
        )
    return backend  # type: ignore[return-value]


@runtime_checkable
class SurrogateSlope(Protocol):
    """The surrogate's gradient in the design (the pseudo-critics take xi as an input): what a
    gradient optimizer (`coadapt_core.optimizer.FollowsSurrogateSlope`) steps along. A backend that
    offers it implements this one method; the loop then hands the optimizer, before each
    round, the cost and gradient of the surrogate a surrogate round would use (the fitted
    ensemble's mean when fitted, else the paper's estimator) on the states of the last
    rollouts."""

    def surrogate_slope(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(costs [K, M], gradients [K, M, D]): `surrogate_fitness` of designs [K, D] and its
        derivative in each design variable, in cost units per design unit (a discrete
        variable's entry is whatever the surrogate's slope there is; callers hold it fixed)."""


def surrogate_slope(backend: object) -> SurrogateSlope | None:
    """`backend` as a `SurrogateSlope` when it offers `surrogate_slope`, else None."""
    return backend if callable(getattr(backend, "surrogate_slope", None)) else None  # type: ignore[return-value]


@runtime_checkable
class RunRecorder(Protocol):
    """Where a run's evidence goes (JSON files, or the results store)."""

    def start_run(self, config: dict[str, Any]) -> str:
        """Register a run; returns its id."""

    def record_evaluations(
        self,
        run_id: str,
        *,
        outer: int,
        inner: int,
        kind: str,  # "real" | "surrogate" | "sim2sim"
        designs: Sequence[Sequence[float]],  # [K, dim]
        costs: Sequence[dict[str, float]],  # [K] objective -> cost
        interactions: Sequence[int] | int,  # [K], or each design's
        seconds: Sequence[float] | float,  # [K], or each design's
        surrogate_errors: Sequence[dict[str, float] | None] | None = None,  # [K]
        simulator: str | None = None,
    ) -> None:
        """One evaluation batch of (outer, inner, kind), its designs idx 0..K-1: recording
        the same batch again (a resumed run redoing it) replaces it."""

    def record_training(self, run_id: str, *, outer: int, result: TrainingResult) -> None: ...

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None: ...

    def finish(self, run_id: str, summary: dict[str, Any], status: str = "finished") -> None: ...
