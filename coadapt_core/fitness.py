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


# -- the cost of a design over its scenarios, and its standard errors ----------------------
#: share of a design's costliest scenarios left out of its cost (an upper-trimmed mean). A
#: scenario in which the agent falls costs 3 to 33 times the design's median scenario (the
#: stumble and the restart, not the capped w_t of the fall step, which is 1-2 % of the cost);
#: with 3-6 % of scenarios falling, a plain mean ranked a 5 x 5 grid by who fell (Spearman
#: 0.45-0.63 between scenario seeds even at 32 agents). Falls enter the cost only when a design
#: falls in more than this share of its scenarios; its fall rate is reported beside the cost.
#: docs/coadaptation.md, "Evaluation protocol", has the measurements.
TRIM_SHARE = 0.25
#: bootstrap resamples behind every standard error (scenarios resampled jointly for paired designs)
BOOTSTRAP = 400


def robust_cost(per_scenario: np.ndarray) -> np.ndarray:
    """[K, M] cost of each design from its per-scenario costs [K, A, M]: the mean over its
    A - floor(TRIM_SHARE * A) cheapest scenarios (the upper-trimmed mean; see TRIM_SHARE)."""
    x = np.sort(np.asarray(per_scenario, dtype=float), axis=1)
    keep = x.shape[1] - int(TRIM_SHARE * x.shape[1])
    return x[:, :keep].mean(axis=1)


def _resamples(a: int, seed: int = 0) -> np.ndarray:
    """[BOOTSTRAP, a] scenario indices drawn with replacement (fixed seed: the same error bars
    for the same costs)."""
    return np.random.default_rng(seed).integers(0, a, size=(BOOTSTRAP, a))


def scenario_se(per_scenario: np.ndarray) -> np.ndarray:
    """[K, M] standard error of `robust_cost` over scenarios (bootstrap over the A scenarios;
    0 with a single scenario: no spread to measure)."""
    x = np.asarray(per_scenario, dtype=float)
    if x.shape[1] < 2:
        return np.zeros((x.shape[0], x.shape[2]))
    idx = _resamples(x.shape[1])
    boot = np.stack([robust_cost(x[:, i, :]) for i in idx])  # [B, K, M]
    return boot.std(axis=0, ddof=1)


def paired_difference(per_scenario: np.ndarray, i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """(difference [M], paired standard error [M]) of cost(design i) - cost(design j): the
    bootstrap resamples the same scenarios for both, so what they share (command,
    randomization, noise) cancels."""
    x = np.asarray(per_scenario, dtype=float)[[i, j]]  # [2, A, M]
    cost = robust_cost(x)
    diff = cost[0] - cost[1]
    if x.shape[1] < 2:
        return diff, np.zeros_like(diff)
    boot = np.stack([robust_cost(x[:, r, :]) for r in _resamples(x.shape[1])])  # [B, 2, M]
    return diff, (boot[:, 0] - boot[:, 1]).std(axis=0, ddof=1)


def improvement_se(objective: Any, best: np.ndarray, nominal: np.ndarray) -> float:
    """Paired standard error of `objective.improvement(cost(best), cost(nominal))` from the
    per-scenario costs of the two designs [A] (bootstrap with the same scenarios drawn for
    both; a plugin's own `improvement` is honoured)."""
    b, n = np.asarray(best, dtype=float), np.asarray(nominal, dtype=float)
    if len(b) < 2:
        return float("nan")
    pair = np.stack([b, n])[:, :, None]  # [2, A, 1]
    values = []
    for r in _resamples(len(b)):
        cb, cn = robust_cost(pair[:, r, :])[:, 0]
        values.append(float(objective.improvement(float(cb), float(cn))))
    values = np.asarray(values)
    values = values[np.isfinite(values)]
    return float(values.std(ddof=1)) if len(values) > 1 else float("nan")


def scenario_seed(run_seed: int, block: int = 0) -> int:
    """The seed of a run's scenario set (block 0: every real round; 1, 2, ...: the final
    check's fresh blocks). `coadapt landscape --seed s`, `coadapt eval --seed s` and the
    report's re-evaluations use the same function, so a run with seed s and those commands
    with seed s evaluate designs on the same scenarios."""
    seq = np.random.SeedSequence([int(run_seed), 7, int(block)])
    return int(seq.generate_state(1)[0] % (2**31 - 1))
