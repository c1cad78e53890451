"""Helpers the built-in optimizers share: the initial designs option and cost sanitising."""

from __future__ import annotations

import numpy as np

from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError

#: what a non-finite cost (a fallen robot, a failed rollout) is told as, so it is never best
WORST_COST = 1e30


def initial_designs(space: DesignSpace, designs: np.ndarray | None, population: int) -> np.ndarray | None:
    """Validated designs [population, dim] for the first `ask`, or None.

    Algorithm 4 trains the universal policy on K sampled designs and starts the swarm from
    those same designs, so the loop passes them in as `initial_designs`.
    """
    if designs is None:
        return None
    designs = np.atleast_2d(np.asarray(designs, dtype=float))
    if designs.shape != (population, space.dim):
        raise UserError(
            f"initial_designs must have shape ({population}, {space.dim}), got {designs.shape}",
            field="initial_designs",
        )
    return space.validate_batch(designs)


def finite_costs(costs: np.ndarray) -> np.ndarray:
    costs = np.asarray(costs, dtype=float)
    return np.where(np.isfinite(costs), costs, WORST_COST)


def check_positive(name: str, value: float, *, allow_zero: bool = True) -> float:
    value = float(value)
    if not np.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise UserError(f"optimizer option '{name}' = {value:g} must be a finite number {bound}", field=name)
    return value


def pop_swarm_options(kwargs: dict) -> tuple[float, float, float, float, np.ndarray | None]:
    """Take the particle-swarm options out of `kwargs` (the rest go to `Optimizer`) and check
    them: (inertia 0.9, c1 2.0, c2 2.0, max_velocity_rate 0.2, initial_designs None), the
    paper's settings by default."""
    inertia = check_positive("inertia", kwargs.pop("inertia", 0.9))
    c1 = check_positive("c1", kwargs.pop("c1", 2.0))
    c2 = check_positive("c2", kwargs.pop("c2", 2.0))
    max_velocity_rate = check_positive("max_velocity_rate", kwargs.pop("max_velocity_rate", 0.2), allow_zero=False)
    return inertia, c1, c2, max_velocity_rate, kwargs.pop("initial_designs", None)
