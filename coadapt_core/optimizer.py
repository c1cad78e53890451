"""The `Optimizer` plugin kind: a gradient-free design optimizer on an ask/tell seam.

The co-adaptation loop never knows which optimizer runs: it asks for a batch of candidate
designs, evaluates them (real rollouts or the surrogate) and tells the costs back. Mixed
variables are declared by the design space; an optimizer that cannot handle them says so
through `supports_mixed`.

Resumable runs keep an optimizer's state as data (`state_dict()` / `load_state_dict()`),
never as a pickle: the base class records every told batch, and by default rebuilds an
optimizer by replaying those rounds into a freshly constructed one (same constructor
arguments, same seed), checking that it proposes exactly what was recorded. An optimizer
whose proposals do not depend only on its seed and the costs told overrides both methods.
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
        self._history: list[tuple[np.ndarray, np.ndarray]] = []  # every told (designs, costs)

    @abstractmethod
    def _ask(self) -> np.ndarray:
        """Propose candidate designs [population, dim] inside `space`."""

    def ask(self) -> np.ndarray:
        """Candidate designs [population, dim], inside `space` (discrete values exact)."""
        designs = self._checked(self._ask())
        self._last_asked = designs
        return designs

    def _checked(self, raw: np.ndarray) -> np.ndarray:
        designs = np.atleast_2d(np.asarray(raw, dtype=float))
        if designs.shape[1] != self.space.dim:
            raise RuntimeError(f"optimizer '{self.name}' proposed designs of width {designs.shape[1]}, expected {self.space.dim}")
        # discrete values snap to their exact choices; continuous ones are clipped to bounds
        designs = self.space.decode(self.space.encode(designs)) if self.space.is_mixed else np.clip(
            designs, self.space.lower, self.space.upper
        )
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
        self._history.append((designs.copy(), costs.copy()))
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

    # -- state as data (resumable runs) ----------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """The optimizer's state as plain JSON values (lists, numbers, strings), taken between
        rounds (after `tell`, before the next `ask`). `load_state_dict` on an optimizer built
        with the same constructor arguments continues exactly as this one would.

        The base implementation stores the told rounds (`rounds`: designs and costs) and the
        bookkeeping of this class; subclasses that keep an explicit state extend the dict
        (calling `super().state_dict()`) and override `_restore`.
        """
        return {
            "optimizer": self.name,
            "iteration": int(self.iteration),
            "best_design": None if self._best_design is None else self._best_design.tolist(),
            "best_cost": float(self._best_cost),
            "last_asked": None if self._last_asked is None else self._last_asked.tolist(),
            "rounds": [{"designs": d.tolist(), "costs": c.tolist()} for d, c in self._history],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what `state_dict` returned, on a freshly constructed optimizer (same
        constructor arguments). Raises `UserError` if the state does not fit."""
        if not isinstance(state, dict) or state.get("optimizer") != self.name:
            found = state.get("optimizer") if isinstance(state, dict) else type(state).__name__
            raise UserError(f"optimizer state is for '{found}', not '{self.name}'", field="optimizer")
        if self.iteration != 0 or self._history:
            raise RuntimeError("load_state_dict needs a freshly constructed optimizer")
        try:
            rounds = [
                (np.atleast_2d(np.asarray(r["designs"], dtype=float)), np.asarray(r["costs"], dtype=float))
                for r in state["rounds"]
            ]
            self._restore(state, rounds)
            self.iteration = int(state["iteration"])
            best = state["best_design"]
            self._best_design = None if best is None else np.asarray(best, dtype=float)
            self._best_cost = float(state["best_cost"])
            last = state["last_asked"]
            self._last_asked = None if last is None else np.atleast_2d(np.asarray(last, dtype=float))
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, UserError):
                raise
            raise UserError(f"optimizer state for '{self.name}' is damaged ({type(exc).__name__}: {exc})", field="optimizer") from None
        self._history = rounds

    def _restore(self, state: dict[str, Any], rounds: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Bring the subclass's own state to where `state` was taken. Default: replay the
        recorded rounds through `_ask`/`_tell` (deterministic optimizers, seeded in the
        constructor), refusing if a replayed proposal differs from the recorded one."""
        for i, (designs, costs) in enumerate(rounds):
            proposed = self._checked(self._ask())
            if proposed.shape != designs.shape or not np.array_equal(proposed, designs):
                raise UserError(
                    f"optimizer '{self.name}' does not replay its recorded round {i} identically "
                    "(a different library version or constructor options?); the run cannot be resumed exactly",
                    field="optimizer",
                )
            self._tell(designs, costs)
