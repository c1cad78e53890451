"""Particle swarm over mixed continuous + discrete designs (the paper's R^2 x D^2 motor-type
space, section 4.5). pymoo's PSO is continuous-only, so this swarm is our own.

Handling of discrete variables: every particle lives in the unit cube (the relaxation of
`DesignSpace.encode`), a discrete variable with m choices owning m equal bins of its axis.
The particle state is the *relaxed* position; only the design handed to the evaluator is
decoded by bins (`DesignSpace.decode`). Keeping the relaxed position lets small velocity
contributions accumulate until a particle crosses into the next bin, instead of being
rounded away every step. Velocities are clamped per axis to `max_velocity_rate` of the unit
range; a particle that leaves the cube is put back on the wall with that velocity component
zeroed (absorbing walls).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_plugins.optimizers._common import SWARM_OPTIONS, finite_costs

from coadapt_core import hookimpl
from coadapt_core.design_space import DesignSpace
from coadapt_core.optimizer import Optimizer

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"


class MixedPSOOptimizer(Optimizer):
    """Global-best PSO with relaxed discrete coordinates.

    v <- w v + c1 r1 (p_best - x) + c2 r2 (g_best - x);  x <- x + v   (unit cube)

    Options (`option_specs`): inertia (0.9), c1 (2.0), c2 (2.0), max_velocity_rate (0.2).
    `initial_designs` are the first swarm (default: uniform in the cube).
    """

    name: ClassVar[str] = "mixed-pso"
    description: ClassVar[str] = (
        "particle swarm over continuous + discrete variables (relaxed positions, binned decoding)"
    )
    supports_mixed: ClassVar[bool] = True
    implies_mixed: ClassVar[bool] = True
    option_specs: ClassVar[tuple] = SWARM_OPTIONS

    def __init__(self, space: DesignSpace, **kwargs: Any):
        import numpy as np

        super().__init__(space, **kwargs)
        o = self.options
        self.inertia, self.c1, self.c2, self.max_velocity = (
            o["inertia"],
            o["c1"],
            o["c2"],
            o["max_velocity_rate"],
        )
        self._rng = np.random.default_rng(self.seed)
        n, d = self.population, space.dim
        initial = self.initial_designs
        self.x = (
            self._rng.uniform(0, 1, (n, d)) if initial is None else space.encode(initial)
        )  # [n, dim]
        self.v = self._rng.uniform(-self.max_velocity, self.max_velocity, (n, d))  # [n, dim]
        self.p_best = self.x.copy()  # [n, dim] relaxed personal bests
        self.p_cost = np.full(n, np.inf)  # [n]
        self.g_best = self.x[0].copy()  # [dim]
        self.g_cost = np.inf
        self._evaluated_first = False

    def _ask(self) -> np.ndarray:
        if self._evaluated_first:
            self._move()
        return self.space.decode(self.x)

    def _move(self) -> None:
        import numpy as np

        n, d = self.x.shape
        r1, r2 = self._rng.uniform(size=(n, d)), self._rng.uniform(size=(n, d))
        self.v = (
            self.inertia * self.v
            + self.c1 * r1 * (self.p_best - self.x)
            + self.c2 * r2 * (self.g_best - self.x)
        )
        self.v = np.clip(self.v, -self.max_velocity, self.max_velocity)
        x = self.x + self.v
        outside = (x < 0) | (x > 1)
        self.v[outside] = 0.0
        self.x = np.clip(x, 0.0, 1.0)

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        import numpy as np

        costs = finite_costs(costs)  # [n]
        improved = costs < self.p_cost
        self.p_best[improved] = self.x[improved]
        self.p_cost[improved] = costs[improved]
        i = int(np.argmin(self.p_cost))
        if self.p_cost[i] < self.g_cost:
            self.g_cost = float(self.p_cost[i])
            self.g_best = self.p_best[i].copy()
        self._evaluated_first = True

    def final_population(self) -> np.ndarray:
        return self.space.decode(self.x)

    # -- state as data: the swarm's arrays and the random generator -----------------------
    def state_dict(self) -> dict[str, Any]:
        state = super().state_dict()
        state["swarm"] = {
            "x": self.x.tolist(),
            "v": self.v.tolist(),
            "p_best": self.p_best.tolist(),
            "p_cost": self.p_cost.tolist(),
            "g_best": self.g_best.tolist(),
            "g_cost": float(self.g_cost),
            "evaluated_first": bool(self._evaluated_first),
            "rng": self._rng.bit_generator.state,
        }
        return state

    def _restore(self, state: dict[str, Any], rounds: list) -> None:
        import numpy as np

        swarm = state["swarm"]
        n, d = self.x.shape
        arrays = {
            k: np.asarray(swarm[k], dtype=float) for k in ("x", "v", "p_best", "p_cost", "g_best")
        }
        shapes = {"x": (n, d), "v": (n, d), "p_best": (n, d), "p_cost": (n,), "g_best": (d,)}
        for key, shape in shapes.items():
            if arrays[key].shape != shape:
                raise ValueError(f"swarm '{key}' has shape {arrays[key].shape}, expected {shape}")
        self.x, self.v, self.p_best = arrays["x"], arrays["v"], arrays["p_best"]
        self.p_cost, self.g_best = arrays["p_cost"], arrays["g_best"]
        self.g_cost = float(swarm["g_cost"])
        self._evaluated_first = bool(swarm["evaluated_first"])
        self._rng.bit_generator.state = dict(swarm["rng"])


@hookimpl
def coadapt_register_optimizers() -> list[type[Optimizer]]:
    return [MixedPSOOptimizer]
