"""The seams of the co-adaptation loop (Algorithm 4): what the loop needs from the inner
loop (universal policy training, Algorithm 1) and from fitness evaluation (real rollouts,
Algorithm 2; pseudo-critic surrogate, Algorithm 3), and where it records results.

The loop depends only on these protocols, so it runs unchanged on the real learner
(`coadapt_core.learning`) and on the analytic fake used by the tests.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

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


@runtime_checkable
class CoadaptationBackend(Protocol):
    """Inner loop and fitness evaluation over designs [K, design_dim]."""

    def train(self, designs: np.ndarray, steps: int, *, seed: int = 0) -> TrainingResult:
        """Train (or fine-tune) the universal policy, critic and pseudo-critics on `designs`."""

    def real_fitness(
        self, designs: np.ndarray, objectives: Sequence[Objective], *, agents: int, steps: int, seed: int = 0
    ) -> RealFitness:
        """Roll out `agents` copies of each design for `steps` policy steps."""

    def surrogate_fitness(
        self, designs: np.ndarray, objectives: Sequence[Objective], buffer: Any, *, samples: int, seed: int = 0
    ) -> np.ndarray:
        """[K, M] mean pseudo-critic prediction over `samples` states drawn from `buffer`
        with each candidate's design substituted. No environment interaction."""

    def save(self, path: str) -> None:
        """Checkpoint policy, critics, normalizers and optimizer state."""

    def load(self, path: str) -> None:
        """Restore what `save` wrote."""


@runtime_checkable
class RunRecorder(Protocol):
    """Where a run's evidence goes (JSON files, or the results store)."""

    def start_run(self, config: dict[str, Any]) -> str:
        """Register a run; returns its id."""

    def record_evaluation(
        self,
        run_id: str,
        *,
        outer: int,
        inner: int,
        design: Sequence[float],
        costs: dict[str, float],
        kind: str,  # "real" | "surrogate"
        interactions: int,
        seconds: float,
        surrogate_error: dict[str, float] | None = None,
    ) -> None: ...

    def record_training(self, run_id: str, *, outer: int, result: TrainingResult) -> None: ...

    def record_checkpoint(self, run_id: str, *, outer: int, path: str) -> None: ...

    def finish(self, run_id: str, summary: dict[str, Any], status: str = "finished") -> None: ...
