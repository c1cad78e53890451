"""NSGA-II (pymoo) over two or three objectives at once: the trade-off the paper leaves to a
weighted composite, searched directly. `pareto_front()` gives the non-dominated designs."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_plugins.optimizers._common import finite_costs

from coadapt_core import hookimpl
from coadapt_core.design_space import DesignSpace
from coadapt_core.optimizer import Optimizer
from coadapt_core.pareto import pareto_front

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"


class NSGA2Optimizer(Optimizer):
    """pymoo NSGA-II in the unit-cube encoding; continuous variables only.

    Options: initial_designs ([population, dim]; default random). The Pareto front is kept
    over every design told so far, not only the last generation.

    State for resumed runs (`state_dict`/`load_state_dict`): the told rounds; the pymoo
    algorithm is rebuilt from them by replay with the same seed (the base class's default),
    never unpickled.
    """

    name: ClassVar[str] = "nsga2"
    description: ClassVar[str] = "multi-objective NSGA-II (pymoo) over 2-3 objectives, Pareto front"
    multi_objective: ClassVar[bool] = True

    def __init__(self, space: DesignSpace, **kwargs: Any):
        import numpy as np

        super().__init__(space, **kwargs)
        from pymoo.algorithms.moo.nsga2 import NSGA2
        from pymoo.core.problem import Problem
        from pymoo.operators.sampling.rnd import FloatRandomSampling

        initial = self.initial_designs
        sampling = FloatRandomSampling() if initial is None else space.encode(initial)
        problem = Problem(
            n_var=space.dim,
            n_obj=self.num_objectives,
            xl=np.zeros(space.dim),
            xu=np.ones(space.dim),
        )
        self._algorithm = NSGA2(pop_size=self.population, sampling=sampling)
        self._algorithm.setup(
            problem, seed=self.seed32, termination=("n_gen", 10**9), verbose=False
        )
        self._pending = None
        self._designs: list[np.ndarray] = []  # every told batch [n, dim]
        self._costs: list[np.ndarray] = []  # [n, M]

    def _ask(self) -> np.ndarray:
        self._pending = self._algorithm.ask()
        return self.space.decode(self._pending.get("X"))

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        if self._pending is None:
            raise RuntimeError("tell() without a preceding ask()")
        costs = finite_costs(costs)  # [n, M]
        self._pending.set("F", costs)
        self._algorithm.tell(infills=self._pending)
        self._pending = None
        self._designs.append(designs.copy())
        self._costs.append(costs.copy())

    def pareto_front(self) -> tuple[np.ndarray, np.ndarray]:
        import numpy as np

        if not self._costs:
            return np.zeros((0, self.space.dim)), np.zeros((0, self.num_objectives))
        return pareto_front(np.concatenate(self._designs), np.concatenate(self._costs))

    def best(self) -> tuple[np.ndarray | None, float]:
        """The front's best design for the first objective (a single number for progress)."""
        import numpy as np

        designs, costs = self.pareto_front()
        if len(costs) == 0:
            return None, float("inf")
        i = int(np.argmin(costs[:, 0]))
        return designs[i], float(costs[i, 0])

    def final_population(self) -> np.ndarray:
        pop = getattr(self._algorithm, "pop", None)
        if pop is None or len(pop) == 0:
            return super().final_population()
        return self.space.decode(pop.get("X"))


@hookimpl
def coadapt_register_optimizers() -> list[type[Optimizer]]:
    return [NSGA2Optimizer]
