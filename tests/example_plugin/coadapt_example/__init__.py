"""Example coadapt plugin: a robot (the `trotter` quadruped), an objective and an optimizer,
registered through pluggy hooks."""

from __future__ import annotations

import numpy as np

from coadapt_core import hookimpl
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.optimizer import Optimizer
from coadapt_core.options import PluginOption

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"


class JointSpeedObjective(Objective):
    """Mean squared joint speed: penalises fast, jerky leg motion."""

    name = "joint-speed"
    display_name = "Joint speed"
    description = "mean squared joint speed per step (example plugin)"

    def step_cost(self, step: StepBatch):
        return (step.joint_vel**2).mean(dim=-1)


class RandomSearch(Optimizer):
    """Random search whose sampling box shrinks around the best design every round.

    The first batch is `initial_designs` when the loop gives them (it does: the designs the
    policy was just trained on), else uniform samples. Option `shrink` (0.7) is the factor
    the box's half-width is multiplied by after each round.
    """

    name = "random-search"
    description = "shrinking-box random search (example plugin)"
    supports_mixed = True
    option_specs = (
        PluginOption(
            "shrink", "float", 0.7, "box half-width factor per round", minimum=0.01, maximum=1.0
        ),
    )

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)  # checks seed, initial_designs and options
        self._rng = np.random.default_rng(self.seed)  # numpy's Generator takes any seed < 2**63
        self._centre = np.full(space.dim, 0.5)  # unit-cube encoding
        self._radius = 0.5
        self._first = self.initial_designs  # [population, dim] or None

    def _ask(self) -> np.ndarray:
        if self._first is not None:
            first, self._first = self._first, None
            return first
        unit = self._centre + self._rng.uniform(
            -self._radius, self._radius, (self.population, self.space.dim)
        )
        return self.space.decode(np.clip(unit, 0.0, 1.0))

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        best_design, best_cost = self.best()
        i = int(np.argmin(costs))
        if best_design is None or costs[i] < best_cost:
            best_design = designs[i]
        self._centre = self.space.encode(best_design[None])[0]
        self._radius = max(self._radius * self.options["shrink"], 0.01)


@hookimpl
def coadapt_register_robots():
    from coadapt_example.robot import Trotter

    return [Trotter]


@hookimpl
def coadapt_register_objectives():
    return [JointSpeedObjective]


@hookimpl
def coadapt_register_optimizers():
    return [RandomSearch]
