"""Helpers shared by the MuJoCo backend's tests: a batch of designs with the nominal one
first, and a randomization with every range a point."""

from __future__ import annotations

import numpy as np
from coadapt_plugins.robots.kuafu.robot import Kuafu

from coadapt_core.physics.randomization import RandomizationConfig


def batch_designs(robot: Kuafu, n: int, seed: int = 0, mixed: bool = False) -> np.ndarray:
    designs = robot.design_space(mixed).sample(n, rng=seed)
    designs[0] = robot.nominal_design(mixed)
    return designs


def fixed_randomization(**overrides) -> RandomizationConfig:
    """Randomization with every range a point (nominal unless overridden)."""
    values = {k: (v, v) for k, v in RandomizationConfig.NOMINAL.items()}
    values.update({k: (v, v) for k, v in overrides.items()})
    return RandomizationConfig(**values)
