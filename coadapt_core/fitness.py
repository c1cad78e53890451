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
    # paired evaluation (optional: a backend without them still drives the loop; the loop
    # then reports no standard errors). Scenario a (agent a) is the same for every design of
    # a call and of every call with the same seed, so differences are paired.
    per_scenario: np.ndarray | None = None  # [K, A, M] each scenario's mean per-step cost
    cost_se: np.ndarray | None = None  # [K, M] standard error of `costs` over scenarios
    fall_rate: np.ndarray | None = None  # [K] share of scenarios (agents) that fell at least once
    # the walking gate (coadapt_core.coadapt.reliability): RMS velocity tracking error over the
    # RMS commanded velocity, per design (0 = perfect, 1 = no better than standing still)
    tracking_ratio: np.ndarray | None = None  # [K]


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


# -- standard errors of paired real fitness -------------------------------------------------
def scenario_se(per_scenario: np.ndarray) -> np.ndarray:
    """[K, M] standard error of the mean over scenarios of per-scenario costs [K, A, M]
    (0 with a single scenario: no spread to measure)."""
    x = np.asarray(per_scenario, dtype=float)
    a = x.shape[1]
    if a < 2:
        return np.zeros((x.shape[0], x.shape[2]))
    return x.std(axis=1, ddof=1) / np.sqrt(a)


def paired_difference(per_scenario: np.ndarray, i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """(mean [M], paired standard error [M]) of cost(design i) - cost(design j), scenario by
    scenario: what the two designs share (command, randomization, noise) cancels."""
    x = np.asarray(per_scenario, dtype=float)
    d = x[i] - x[j]  # [A, M]
    se = d.std(axis=0, ddof=1) / np.sqrt(len(d)) if len(d) > 1 else np.zeros(d.shape[1])
    return d.mean(axis=0), se


def improvement_se(objective: Any, best: np.ndarray, nominal: np.ndarray) -> float:
    """Paired standard error of `objective.improvement(mean(best), mean(nominal))` from the
    per-scenario costs of the two designs [A] (delta method: the improvement's gradient,
    taken numerically so a plugin's own `improvement` is honoured, applied to each
    scenario's deviation from the means)."""
    b, n = np.asarray(best, dtype=float), np.asarray(nominal, dtype=float)
    if len(b) < 2:
        return float("nan")
    mb, mn = float(b.mean()), float(n.mean())
    h = 1e-6 * max(abs(mb), abs(mn), 1e-12)
    f = objective.improvement
    gb = (f(mb + h, mn) - f(mb - h, mn)) / (2 * h)
    gn = (f(mb, mn + h) - f(mb, mn - h)) / (2 * h)
    u = gb * (b - mb) + gn * (n - mn)  # [A] influence of each scenario
    return float(u.std(ddof=1) / np.sqrt(len(u)))
