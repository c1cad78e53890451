"""Particle swarm optimisation with pymoo's PSO (the paper's optimizer, section 4.1.3),
batch-evaluated through ask/tell, searching the unit-cube encoding of the design space."""

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


class PSOOptimizer(Optimizer):
    """pymoo PSO with fixed inertia and acceleration (`adaptive=False`, so w, c1, c2 stay as
    set; the paper uses w = 0.9, c1 = c2 = 2.0). Continuous variables only.

    Options (`option_specs`): inertia (0.9), c1 (2.0), c2 (2.0), max_velocity_rate (0.2 of
    the range, pymoo's default). `initial_designs` are the first swarm (default: a Latin
    hypercube). pymoo is seeded with `seed32` (it takes 32-bit seeds only).

    State for resumed runs (`state_dict`/`load_state_dict`): the told rounds; the pymoo
    algorithm is rebuilt from them by replay with the same seed (the base class's default),
    never unpickled.
    """

    name: ClassVar[str] = "pso"
    default_rank: ClassVar[int] = 10  # the default --optimizer (the paper's)
    description: ClassVar[str] = "particle swarm (pymoo PSO, inertia 0.9, c1 = c2 = 2.0)"
    option_specs: ClassVar[tuple] = SWARM_OPTIONS

    def __init__(self, space: DesignSpace, **kwargs: Any):
        import numpy as np

        super().__init__(space, **kwargs)
        o = self.options
        self.inertia, self.c1, self.c2 = o["inertia"], o["c1"], o["c2"]
        from pymoo.algorithms.soo.nonconvex.pso import PSO
        from pymoo.core.problem import Problem
        from pymoo.operators.sampling.lhs import LHS

        initial = self.initial_designs
        sampling = LHS() if initial is None else space.encode(initial)
        self._problem = Problem(
            n_var=space.dim, n_obj=1, xl=np.zeros(space.dim), xu=np.ones(space.dim)
        )
        self._algorithm = PSO(
            pop_size=self.population,
            sampling=sampling,
            w=self.inertia,
            c1=self.c1,
            c2=self.c2,
            adaptive=False,
            max_velocity_rate=o["max_velocity_rate"],
        )
        # the budget is enforced by the Optimizer base; pymoo's own termination never stops it
        self._algorithm.setup(
            self._problem, seed=self.seed32, termination=("n_gen", 10**9), verbose=False
        )
        self._pending = None

    def _ask(self) -> np.ndarray:
        self._pending = self._algorithm.ask()
        return self.space.decode(self._pending.get("X"))  # [population, dim]

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        if self._pending is None:
            raise RuntimeError("tell() without a preceding ask()")
        self._pending.set("F", finite_costs(costs)[:, None])
        self._algorithm.tell(infills=self._pending)
        self._pending = None

    def final_population(self) -> np.ndarray:
        """The particles' current positions (Algorithm 4 narrows around them)."""
        particles = getattr(self._algorithm, "particles", None)
        if particles is None:
            return super().final_population()
        return self.space.decode(particles.get("X"))


@hookimpl
def coadapt_register_optimizers() -> list[type[Optimizer]]:
    return [PSOOptimizer]
