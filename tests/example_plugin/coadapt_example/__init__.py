"""Example coadapt plugin: one objective and one optimizer, registered through pluggy hooks."""

from __future__ import annotations

import numpy as np

from coadapt_core import hookimpl
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.optimizer import Optimizer


class JointSpeedObjective(Objective):
    """Mean squared joint speed: penalises fast, jerky leg motion."""

    name = "joint-speed"
    display_name = "Joint speed"
    description = "mean squared joint speed per step (example plugin)"

    def step_cost(self, step: StepBatch):
        return (step.joint_vel**2).mean(dim=-1)


class RandomSearch(Optimizer):
    """Random search whose sampling box halves around the best design every round."""

    name = "random-search"
    description = "shrinking-box random search (example plugin)"
    supports_mixed = True

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        self._rng = np.random.default_rng(self.seed)
        self._centre = np.full(space.dim, 0.5)  # unit-cube encoding
        self._radius = 0.5

    def _ask(self) -> np.ndarray:
        unit = self._centre + self._rng.uniform(-self._radius, self._radius, (self.population, self.space.dim))
        return self.space.decode(np.clip(unit, 0.0, 1.0))

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        best_design, best_cost = self.best()
        i = int(np.argmin(costs))
        if best_design is None or costs[i] < best_cost:
            best_design = designs[i]
        self._centre = self.space.encode(best_design[None])[0]
        self._radius = max(self._radius * 0.7, 0.01)


@hookimpl
def coadapt_register_objectives():
    return [JointSpeedObjective]


@hookimpl
def coadapt_register_optimizers():
    return [RandomSearch]
