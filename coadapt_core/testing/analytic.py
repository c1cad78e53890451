"""An analytic `CoadaptationBackend` with a known optimum, for testing and timing the
co-adaptation loop's logic in milliseconds (not a registered plugin; the tests' fake,
tests/fakes/analytic.py, and `benchmarks/coadapt_cost.py --fake` use it).

Real fitness: a quadratic bowl per objective over (thigh, shank) in [0.5, 1.5]^2 with its
minimum at the backend's `optima[objective name]` (`DEFAULT_OPTIMUM` for a name it lacks;
plus motor-type penalties in the mixed space), with Gaussian noise that shrinks as
1/sqrt(agents), `designs x agents x steps` interactions and simulated seconds at `RATE`
interactions per second. Surrogate: the same bowl plus a smooth linear bias whose size is
proportional to the width of the range the backend was last trained on (a pseudo-critic
trained on a narrowed range is more accurate), so surrogate-only search lands off the
optimum while narrowing and real evaluations correct it.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.fitness import RealFitness, TrainingResult
from coadapt_core.objective import Objective

SPACE = DesignSpace([Continuous("thigh_scale", 0.5, 1.5), Continuous("shank_scale", 0.5, 1.5)])
MIXED_SPACE = DesignSpace(
    [*SPACE.variables, Discrete("hip_motor", (1, 2, 3)), Discrete("knee_motor", (1, 2, 3))]
)
NOMINAL = np.array([1.0, 1.0])
MIXED_NOMINAL = np.array([1.0, 1.0, 1.0, 1.0])

#: minimum of the bowl of an objective the backend's optima do not name
DEFAULT_OPTIMUM = np.array([0.8, 1.2])
#: best motor types (hip, knee) in the mixed space; each other choice costs MOTOR_PENALTY
BEST_MOTORS = np.array([3.0, 2.0])
MOTOR_PENALTY = 0.2
BASE_COST = 1.0
NOISE_STD = 0.02  # per agent; the mean over agents has NOISE_STD / sqrt(agents)
SURROGATE_BIAS = 0.3  # slope of the surrogate's tilt when trained on the full range
BIAS_DIRECTION = np.array([1.0, -1.0]) / np.sqrt(2.0)
RATE = 100_000.0  # simulated interactions per second


def optimum_of(name: str, optima: Mapping[str, Any] | None = None) -> np.ndarray:
    """The minimum of objective `name`'s bowl: `optima[name]`, else `DEFAULT_OPTIMUM`."""
    found = (optima or {}).get(name)
    return DEFAULT_OPTIMUM if found is None else np.asarray(found, dtype=float)


def true_cost(
    designs: np.ndarray, name: str, optima: Mapping[str, Any] | None = None
) -> np.ndarray:
    """[K] the noiseless cost of designs [K, 2 or 4]."""
    designs = np.atleast_2d(designs)
    cost = BASE_COST + ((designs[:, :2] - optimum_of(name, optima)) ** 2).sum(axis=1)
    if designs.shape[1] >= 4:
        cost = cost + MOTOR_PENALTY * (designs[:, 2:4] != BEST_MOTORS).sum(axis=1)
    return cost


class AnalyticBackend:
    """`CoadaptationBackend` over the analytic bowls (see module docstring); `optima` maps an
    objective name to its bowl's minimum (thigh, shank)."""

    #: implements `coadapt_core.fitness.SurrogateEnsemble` (fit_surrogate, surrogate_members)
    surrogate_ensemble = True

    def __init__(
        self,
        seed: int = 0,
        *,
        optima: Mapping[str, Any] | None = None,
        buffer_from_training: bool = True,
        fail_on_real_call: int | None = None,
        paired: bool = False,
    ):
        self.seed = seed
        # paired: real fitness gives per-scenario costs [K, A, M] (one scenario per agent, its
        # offset shared by every design of the call, as a real backend's paired scenarios), so
        # the loop measures standard errors
        self.paired = paired
        self.optima = dict(optima or {})
        self.buffer_from_training = buffer_from_training
        self.fail_on_real_call = fail_on_real_call  # raise on this (1-based) real_fitness call
        self.trained_low: np.ndarray | None = None  # [2] box of the last training designs
        self.trained_high: np.ndarray | None = None
        self.trainings = 0
        self.real_calls = 0
        self.surrogate_calls = 0

    # -- helpers ---------------------------------------------------------------------------
    def width_fraction(self) -> float:
        """Mean width of the last training range over the full range (1 = untrained/full)."""
        if self.trained_low is None:
            return 1.0
        return float(np.mean(self.trained_high - self.trained_low))

    def surrogate_bias(self, designs: np.ndarray) -> np.ndarray:
        return SURROGATE_BIAS * self.width_fraction() * ((designs[:, :2] - 1.0) @ BIAS_DIRECTION)

    # -- protocol --------------------------------------------------------------------------
    def train(self, designs: np.ndarray, steps: int, *, seed: int = 0) -> TrainingResult:
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        self.trained_low, self.trained_high = designs[:, :2].min(axis=0), designs[:, :2].max(axis=0)
        self.trainings += 1
        self.fitted_labels = 0  # a new policy: the fit is stale
        buffer = (
            {"kind": "training", "designs": designs.copy()} if self.buffer_from_training else None
        )
        return TrainingResult(
            steps=int(steps),
            seconds=steps / RATE,
            mean_reward=1.0 - self.width_fraction(),
            buffer=buffer,
        )

    def real_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        *,
        agents: int,
        steps: int,
        seed: int = 0,
    ) -> RealFitness:
        self.real_calls += 1
        if self.fail_on_real_call is not None and self.real_calls == self.fail_on_real_call:
            raise RuntimeError(f"injected failure on real evaluation call {self.real_calls}")
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        rng = np.random.default_rng(seed)
        true = np.stack(
            [true_cost(designs, o.name, self.optima) for o in objectives], axis=1
        )  # [K, M]
        interactions = len(designs) * agents * steps
        buffer = {"kind": "evaluation", "designs": designs.copy()}
        if (
            self.paired
        ):  # each scenario's offset shared by the designs, plus each design's own noise
            shared = rng.normal(0.0, NOISE_STD, size=(1, agents, len(objectives)))
            per = (
                true[:, None, :]
                + shared
                + rng.normal(0.0, NOISE_STD, size=(len(designs), agents, len(objectives)))
            )
            return RealFitness(
                costs=per.mean(axis=1),
                buffer=buffer,
                interactions=interactions,
                seconds=interactions / RATE,
                per_scenario=per,
                scenario_falls=np.zeros(per.shape[:2], dtype=bool),
                fall_rate=np.zeros(len(designs)),
            )
        noise = rng.normal(0.0, NOISE_STD / np.sqrt(agents), size=(len(designs), len(objectives)))
        return RealFitness(
            costs=true + noise,
            buffer=buffer,
            interactions=interactions,
            seconds=interactions / RATE,
        )

    def surrogate_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray:
        if buffer is None:
            raise RuntimeError("surrogate evaluation needs an evaluation buffer")
        self.surrogate_calls += 1
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        members = self.surrogate_members(designs, objectives, buffer, samples=samples, seed=seed)
        if members is not None:
            return members.mean(axis=0)
        bias = self.surrogate_bias(designs)
        return np.stack(
            [true_cost(designs, o.name, self.optima) + bias for o in objectives], axis=1
        )  # [K, M]

    def surrogate_slope(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(costs [K, M], gradients [K, M, D]) of `surrogate_fitness`, in closed form: the
        bowl's 2 (x - optimum) plus the bias's tilt (shrunk as the fit shrinks it, plus the
        members' mean tilt when fitted); 0 along the motor types."""
        costs = self.surrogate_fitness(designs, objectives, buffer, samples=samples, seed=seed)
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        labels = getattr(self, "fitted_labels", 0)
        tilt = SURROGATE_BIAS * self.width_fraction() * BIAS_DIRECTION  # [2]
        if labels:
            spread = getattr(self, "member_spread", None)
            spread = 0.1 / np.sqrt(labels) if spread is None else spread
            members = np.random.default_rng(12345).normal(size=(self.MEMBERS, 2))
            tilt = tilt / (1.0 + labels / 16.0) + spread * members.mean(axis=0)
        grads = np.zeros((len(designs), len(objectives), designs.shape[1]))
        for j, o in enumerate(objectives):
            grads[:, j, :2] = 2.0 * (designs[:, :2] - optimum_of(o.name, self.optima)) + tilt
        return costs, grads

    # -- pseudo-critics fitted to real rounds (issue 16), for the evaluation policies ------
    #: members of the fitted ensemble; member_spread: their disagreement (cost units per unit
    #: of design offset from the nominal), settable by tests; None: shrinks with the labels
    MEMBERS = 5

    def fit_surrogate(
        self,
        designs: np.ndarray,
        costs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        seed: int = 0,
    ) -> None:
        self.fits = getattr(self, "fits", 0) + 1
        self.fitted_labels = len(np.atleast_2d(designs))

    def surrogate_members(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray | None:
        """[E, K, M]: the fitted surrogate (the bowl plus the bias, shrunk by the labels) with
        each member tilted its own way by `member_spread`."""
        labels = getattr(self, "fitted_labels", 0)
        if not labels:
            return None
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        spread = getattr(self, "member_spread", None)
        if spread is None:
            spread = 0.1 / np.sqrt(labels)
        shrink = 1.0 / (1.0 + labels / 16.0)
        base = (
            np.stack([true_cost(designs, o.name, self.optima) for o in objectives], axis=1)
            + shrink * self.surrogate_bias(designs)[:, None]
        )
        tilts = np.random.default_rng(12345).normal(size=(self.MEMBERS, 2))
        return np.stack([base + spread * ((designs[:, :2] - 1.0) @ t)[:, None] for t in tilts])

    def save(self, path: str) -> None:
        data = {
            "trained_low": None if self.trained_low is None else self.trained_low.tolist(),
            "trained_high": None if self.trained_high is None else self.trained_high.tolist(),
            "trainings": self.trainings,
        }
        with open(path, "w") as f:
            json.dump(data, f)

    def load(self, path: str) -> None:
        with open(path) as f:
            data = json.load(f)
        self.trained_low = None if data["trained_low"] is None else np.array(data["trained_low"])
        self.trained_high = None if data["trained_high"] is None else np.array(data["trained_high"])
        self.trainings = data["trainings"]
        self.fitted_labels = 0
