"""The analytic fake of the tests: `coadapt_core.testing.analytic`'s backend with the bowls'
minima of the built-in objectives (`OPTIMA`), for testing the co-adaptation loop's logic in
milliseconds (not a registered plugin)."""

from __future__ import annotations

from typing import Any

import numpy as np

from coadapt_core.testing import analytic
from coadapt_core.testing.analytic import (  # noqa: F401  (what the tests import from here)
    BASE_COST,
    BEST_MOTORS,
    BIAS_DIRECTION,
    DEFAULT_OPTIMUM,
    MIXED_NOMINAL,
    MIXED_SPACE,
    MOTOR_PENALTY,
    NOISE_STD,
    NOMINAL,
    RATE,
    SPACE,
    SURROGATE_BIAS,
)

#: minimum of each objective's bowl
OPTIMA: dict[str, np.ndarray] = {
    "torque": np.array([0.6, 0.6]),
    "power": np.array([1.1, 0.8]),
    "tracking": np.array([1.3, 1.1]),
    "composite": np.array([0.9, 1.2]),
}


def optimum_of(name: str) -> np.ndarray:
    return analytic.optimum_of(name, OPTIMA)


def true_cost(designs: np.ndarray, name: str) -> np.ndarray:
    """[K] the noiseless cost of designs [K, 2 or 4]."""
    return analytic.true_cost(designs, name, OPTIMA)


class AnalyticBackend(analytic.AnalyticBackend):
    """The analytic backend over the bowls of `OPTIMA`."""

    def __init__(self, seed: int = 0, **kwargs: Any):
        super().__init__(seed, optima=OPTIMA, **kwargs)
