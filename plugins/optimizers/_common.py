"""Helpers the built-in optimizers share: swarm options and cost sanitising."""

from __future__ import annotations

from typing import TYPE_CHECKING

from coadapt_core.options import PluginOption

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: what a non-finite cost (a fallen robot, a failed rollout) is told as, so it is never best
WORST_COST = 1e30


def finite_costs(costs: np.ndarray) -> np.ndarray:
    import numpy as np

    costs = np.asarray(costs, dtype=float)
    return np.where(np.isfinite(costs), costs, WORST_COST)


#: the particle-swarm options of pso and mixed-pso (the paper's settings by default)
SWARM_OPTIONS: tuple[PluginOption, ...] = (
    PluginOption(
        "inertia",
        "float",
        0.9,
        "inertia (momentum) w of the particles",
        minimum=0.0,
        alias="inertia",
    ),
    PluginOption(
        "c1",
        "float",
        2.0,
        "cognitive impact: pull towards a particle's own best",
        minimum=0.0,
        alias="c1",
    ),
    PluginOption(
        "c2", "float", 2.0, "social impact: pull towards the swarm's best", minimum=0.0, alias="c2"
    ),
    PluginOption(
        "max_velocity_rate",
        "float",
        0.2,
        "largest step per round, as a fraction of the range",
        minimum=1e-9,
    ),
)
