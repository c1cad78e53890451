"""The `Optimizer` plugin kind: a gradient-free design optimizer on an ask/tell seam.

The co-adaptation loop never knows which optimizer runs: it asks for a batch of candidate
designs, evaluates them (real rollouts or the surrogate) and tells the costs back. Mixed
variables are declared by the design space; an optimizer that cannot handle them says so
through `supports_mixed`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError


class Optimizer(ABC):
    """Ask/tell design optimizer.

    `population` designs per `ask` (1 for sequential optimizers such as BO), `budget`
    ask/tell rounds in all. Costs are minimised; a multi-objective optimizer receives
    costs [n, num_objectives].
    """

    #: user-facing key (`--optimizer pso`)
    name: ClassVar[str]
    description: ClassVar[str] = ""
    #: handles discrete variables of a mixed design space
    supports_mixed: ClassVar[bool] = False
    #: expects costs [n, M] with M >= 2 instead of [n]
    multi_objective: ClassVar[bool] = False
    #: proposes one design at a time (population is forced to 1)
    sequential: ClassVar[bool] = False

    def __init__(
        self,
        space: DesignSpace,
        *,
        population: int = 20,
        budget: int = 5,
        seed: int = 0,
        num_objectives: int = 1,
        **options: Any,
    ):
        if population < 1:
            raise UserError(f"population must be >= 1, got {population}", field="population")
        if budget < 1:
            raise UserError(f"budget must be >= 1 iteration, got {budget}", field="budget")
        if space.is_mixed and not self.supports_mixed:
            raise UserError(
                f"optimizer '{self.name}' handles continuous variables only; the design space has "
                "discrete ones (use mixed-pso or bo)",
                field="optimizer",
            )
        if self.multi_objective and num_objectives < 2:
            raise UserError(
                f"optimizer '{self.name}' needs at least 2 objectives, got {num_objectives}",
                field="objective",
            )
        if not self.multi_objective and num_objectives != 1:
            raise UserError(
                f"optimizer '{self.name}' optimizes one objective; got {num_objectives} "
                "(use a composite objective or nsga2)",
                field="objective",
            )
        self.space = space
        self.population = 1 if self.sequential else int(population)
        self.budget = int(budget)
        self.seed = int(seed)
        self.num_objectives = int(num_objectives)
        self.options = options
        self.iteration = 0  # completed ask/tell rounds
        self._best_design: np.ndarray | None = None
        self._best_cost: float = float("inf")
        self._last_asked: np.ndarray | None = None

    @abstractmethod
    def _ask(self) -> np.ndarray:
        """Propose candidate designs [population, dim] inside `space`."""

    def ask(self) -> np.ndarray:
        """Candidate designs [population, dim], inside `space` (discrete values exact)."""
        designs = np.atleast_2d(np.asarray(self._ask(), dtype=float))
        if designs.shape[1] != self.space.dim:
            raise RuntimeError(f"optimizer '{self.name}' proposed designs of width {designs.shape[1]}, expected {self.space.dim}")
        # discrete values snap to their exact choices; continuous ones are clipped to bounds
        designs = self.space.decode(self.space.encode(designs)) if self.space.is_mixed else np.clip(
            designs, self.space.lower, self.space.upper
        )
        self._last_asked = designs
        return designs

    @abstractmethod
    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        """Update the optimizer's own state with the evaluated batch."""

    def tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        """Report costs [n] (or [n, M]) of the designs last asked for."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        costs = np.asarray(costs, dtype=float)
        expected = (designs.shape[0],) if self.num_objectives == 1 else (designs.shape[0], self.num_objectives)
        if costs.shape != expected:
            raise ValueError(f"tell expects costs of shape {expected}, got {costs.shape}")
        self._tell(designs, costs)
        if self.num_objectives == 1:
            finite = np.where(np.isfinite(costs), costs, np.inf)
            i = int(np.argmin(finite))
            if finite[i] < self._best_cost:
                self._best_cost = float(finite[i])
                self._best_design = designs[i].copy()
        self.iteration += 1

    @property
    def done(self) -> bool:
        return self.iteration >= self.budget

    def best(self) -> tuple[np.ndarray | None, float]:
        """Best design seen and its cost (single-objective)."""
        return self._best_design, self._best_cost

    def pareto_front(self) -> tuple[np.ndarray, np.ndarray]:
        """(designs [k, dim], costs [k, M]) non-dominated so far (multi-objective only)."""
        raise NotImplementedError(f"optimizer '{self.name}' is single-objective")

    def final_population(self) -> np.ndarray:
        """The designs the range is narrowed around at the end of an outer iteration
        (Algorithm 4 line 22). Default: the last batch asked for."""
        last = self._last_asked
        if last is None:
            raise RuntimeError("no designs have been asked for yet")
        return last
