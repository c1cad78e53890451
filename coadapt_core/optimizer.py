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

import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.options import PluginOption, resolve_options

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: seeds an optimizer must accept: any integer in [0, SEED_LIMIT)
SEED_LIMIT = 2**63


class OutOfBoundsProposal(UserWarning):
    """An optimizer proposed continuous values outside the design space's bounds; they were
    clipped to the bounds (a proposal the optimizer did not make), and the warning says so.
    `OptimizerConformance` fails an optimizer that needs the clipping."""


def _optimizers_where(flag: str) -> str:
    """Registered optimizer names with a class flag set (for error messages only)."""
    try:
        from coadapt_core.plugins import get_registry

        registry = get_registry()
        names = [
            n
            for n in registry.names("optimizer")
            if getattr(registry.get("optimizer", n), flag, False)
        ]
    except Exception:
        names = []
    return ", ".join(names) or "none installed"


class Optimizer(ABC):
    """Ask/tell design optimizer.

    `population` designs per `ask` (1 for sequential optimizers such as BO), `budget`
    ask/tell rounds in all. Costs are minimised; a multi-objective optimizer receives
    costs [n, num_objectives].

    Constructor contract (the co-adaptation loop relies on every point):

    - `seed`: any integer in [0, 2**63). The loop derives one per outer iteration from the
      run's seed. Same seed, same costs told -> same proposals. Libraries that take 32-bit
      seeds (numpy's legacy `RandomState`, pymoo, optuna samplers) get `self.seed32`; do not
      pass `seed` to them directly (seeds above 2**32 crash them, and some, such as `cma`,
      read 0 as "random").
    - `initial_designs`: None, or designs [n, dim] inside `space` the first proposals must
      start from. A population optimizer gets exactly `population` rows and its first `ask`
      returns them (the loop trains the universal policy on K sampled designs and the swarm
      starts from those same designs, Algorithm 4 line 10). A sequential optimizer's first n
      asks return the n rows in order. The base class validates them (`self.initial_designs`,
      or None); ignoring them is a broken contract the conformance suite catches.
    - `**options`: the plugin's own settings, declared in `option_specs` (typed, with
      defaults and help; see `coadapt_core.options`). The base class checks them, fills in
      defaults and stores them in `self.options`; an undeclared option is a one-line user
      error. They reach the plugin from YAML `optimizer_options:` and the CLI's
      `--optimizer-option KEY=VALUE`.
    - State must survive a resume: a run checkpoints the optimizer between rounds
      (`state_dict()` / `load_state_dict()` below); the conformance suite checks that a
      restored optimizer proposes what the original would have.
    """

    #: user-facing key (`--optimizer pso`)
    name: ClassVar[str]
    #: rank as the default of its kind: with no name given, a command takes the installed
    #: plugin of highest rank (ties: the first name in alphabetical order; docs/plugins.md)
    default_rank: ClassVar[int] = 0
    description: ClassVar[str] = ""
    #: handles discrete variables of a mixed design space
    supports_mixed: ClassVar[bool] = False
    #: expects costs [n, M] with M >= 2 instead of [n]
    multi_objective: ClassVar[bool] = False
    #: proposes one design at a time (population is forced to 1)
    sequential: ClassVar[bool] = False
    #: choosing this optimizer switches a run to the robot's mixed design space
    implies_mixed: ClassVar[bool] = False
    #: the plugin's own options (`coadapt_core.options.PluginOption`), read from `self.options`
    option_specs: ClassVar[tuple[PluginOption, ...]] = ()

    def __init__(
        self,
        space: DesignSpace,
        *,
        population: int = 20,
        budget: int = 5,
        seed: int = 0,
        num_objectives: int = 1,
        initial_designs: np.ndarray | None = None,
        **options: Any,
    ):
        import numpy as np

        if (
            isinstance(seed, bool)
            or not isinstance(seed, int | np.integer)
            or not (0 <= int(seed) < SEED_LIMIT)
        ):
            raise UserError(
                f"optimizer seed must be an integer in [0, 2**63), got {seed!r}", field="seed"
            )
        if population < 1:
            raise UserError(f"population must be >= 1, got {population}", field="population")
        if budget < 1:
            raise UserError(f"budget must be >= 1 iteration, got {budget}", field="budget")
        if space.is_mixed and not self.supports_mixed:
            raise UserError(
                f"optimizer '{self.name}' handles continuous variables only; the design space has "
                "discrete ones (optimizers that handle them: "
                f"{_optimizers_where('supports_mixed')})",
                field="optimizer",
            )
        if self.multi_objective and num_objectives < 2:
            raise UserError(
                f"optimizer '{self.name}' needs at least 2 objectives, got {num_objectives}",
                field="objective",
            )
        if not self.multi_objective and num_objectives != 1:
            raise UserError(
                f"optimizer '{self.name}' optimizes one objective; got {num_objectives} (use a "
                "weighted objective, or a multi-objective optimizer: "
                f"{_optimizers_where('multi_objective')})",
                field="objective",
            )
        self.space = space
        self.population = 1 if self.sequential else int(population)
        self.budget = int(budget)
        self.seed = int(seed)
        self.num_objectives = int(num_objectives)
        self.options = resolve_options(
            type(self).option_specs,
            options,
            owner=f"optimizer '{self.name}'",
            field="optimizer_options",
        )
        self.initial_designs = self._check_initial(initial_designs)
        self.iteration = 0  # completed ask/tell rounds
        self.out_of_bounds = 0  # proposed designs clipped into the bounds (`OutOfBoundsProposal`)
        self._best_design: np.ndarray | None = None
        self._best_cost: float = float("inf")
        self._last_asked: np.ndarray | None = None
        self._history: list[tuple[np.ndarray, np.ndarray]] = []  # every told (designs, costs)

    @property
    def seed32(self) -> int:
        """A seed in [1, 2**32) for libraries that take 32-bit seeds: `seed` itself when it
        fits (and is not 0), else one derived from it (numpy `SeedSequence`)."""
        import numpy as np

        if 0 < self.seed < 2**32:
            return self.seed
        return int(np.random.SeedSequence(self.seed).generate_state(1)[0]) or 1

    def _check_initial(self, designs: np.ndarray | None) -> np.ndarray | None:
        """`initial_designs` validated: [population, dim] (sequential: [n >= 1, dim]) inside
        the space, or None."""
        import numpy as np

        if designs is None:
            return None
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        rows_ok = designs.shape[0] >= 1 if self.sequential else designs.shape[0] == self.population
        if designs.ndim != 2 or designs.shape[1] != self.space.dim or not rows_ok:
            rows = "n" if self.sequential else str(self.population)
            raise UserError(
                f"initial_designs must have shape ({rows}, {self.space.dim}), got {designs.shape}",
                field="initial_designs",
            )
        return self.space.validate_batch(designs)

    @abstractmethod
    def _ask(self) -> np.ndarray:
        """Propose candidate designs [population, dim] inside `space`."""

    def ask(self) -> np.ndarray:
        """Candidate designs [population, dim], inside `space` (discrete values exact)."""
        designs = self._checked(self._ask())
        self._last_asked = designs
        return designs

    def _checked(self, raw: np.ndarray) -> np.ndarray:
        import numpy as np

        designs = np.atleast_2d(np.asarray(raw, dtype=float))
        if designs.shape[1] != self.space.dim:
            raise RuntimeError(
                f"optimizer '{self.name}' proposed designs of width {designs.shape[1]}, expected "
                f"{self.space.dim}"
            )
        self._report_out_of_bounds(designs)
        # discrete values snap to their exact choices; continuous ones are clipped to bounds
        designs = (
            self.space.decode(self.space.encode(designs))
            if self.space.is_mixed
            else np.clip(designs, self.space.lower, self.space.upper)
        )
        return designs

    def _report_out_of_bounds(self, designs: np.ndarray) -> None:
        """Warn (`OutOfBoundsProposal`) when continuous values lie outside the bounds by more
        than rounding (1e-9 of the width): the clipping below changes the proposal. Counted
        in `self.out_of_bounds` (designs)."""
        import numpy as np

        mask = self.space.continuous_mask
        if not mask.any():
            return
        lower, upper = self.space.lower[mask], self.space.upper[mask]
        tol = 1e-9 * np.maximum(upper - lower, 1e-12)
        values = designs[:, mask]
        outside = ((values < lower - tol) | (values > upper + tol)).any(axis=1)
        if not outside.any():
            return
        self.out_of_bounds = getattr(self, "out_of_bounds", 0) + int(outside.sum())
        first = values[outside][0]
        warnings.warn(
            f"optimizer '{self.name}' proposed {int(outside.sum())} of {len(designs)} designs "
            f"outside the design space's bounds (e.g. {np.round(first, 4).tolist()} against "
            f"{np.round(lower, 4).tolist()} to {np.round(upper, 4).tolist()}); they were clipped "
            "to the bounds (docs/plugins.md, section 4)",
            OutOfBoundsProposal,
            stacklevel=3,
        )

    @abstractmethod
    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        """Update the optimizer's own state with the evaluated batch."""

    def tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        """Report costs [n] (or [n, M]) of the designs last asked for."""
        import numpy as np

        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        costs = np.asarray(costs, dtype=float)
        expected = (
            (designs.shape[0],)
            if self.num_objectives == 1
            else (designs.shape[0], self.num_objectives)
        )
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
        import numpy as np

        if not isinstance(state, dict) or state.get("optimizer") != self.name:
            found = state.get("optimizer") if isinstance(state, dict) else type(state).__name__
            raise UserError(
                f"optimizer state is for '{found}', not '{self.name}'", field="optimizer"
            )
        if self.iteration != 0 or self._history:
            raise RuntimeError("load_state_dict needs a freshly constructed optimizer")
        try:
            rounds = [
                (
                    np.atleast_2d(np.asarray(r["designs"], dtype=float)),
                    np.asarray(r["costs"], dtype=float),
                )
                for r in state["rounds"]
            ]
            self._restore(state, rounds)
            self.iteration = int(state["iteration"])
            best = state["best_design"]
            self._best_design = None if best is None else np.asarray(best, dtype=float)
            self._best_cost = float(state["best_cost"])
            last = state["last_asked"]
            self._last_asked = (
                None if last is None else np.atleast_2d(np.asarray(last, dtype=float))
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, UserError):
                raise
            raise UserError(
                f"optimizer state for '{self.name}' is damaged ({type(exc).__name__}: {exc})",
                field="optimizer",
            ) from None
        self._history = rounds

    def _restore(self, state: dict[str, Any], rounds: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Bring the subclass's own state to where `state` was taken. Default: replay the
        recorded rounds through `_ask`/`_tell` (deterministic optimizers, seeded in the
        constructor), refusing if a replayed proposal differs from the recorded one."""
        import numpy as np

        for i, (designs, costs) in enumerate(rounds):
            proposed = self._checked(self._ask())
            if proposed.shape != designs.shape or not np.array_equal(proposed, designs):
                raise UserError(
                    f"optimizer '{self.name}' does not replay its recorded round {i} identically "
                    "(a different library version or constructor options?); the run cannot be "
                    "resumed exactly",
                    field="optimizer",
                )
            self._tell(designs, costs)


#: what a gradient-following optimizer is handed: designs [K, dim] -> (surrogate costs [K],
#: their gradients [K, dim] in cost units per design unit)
SlopeFn = Callable[["np.ndarray"], tuple["np.ndarray", "np.ndarray"]]


@runtime_checkable
class FollowsSurrogateSlope(Protocol):
    """An optimizer that steps along the surrogate's gradient declares
    `follows_surrogate_slope = True` and implements `set_slope`. Before each `ask` the
    co-adaptation loop hands it the surrogate's cost and gradient (None when the backend
    offers no `coadapt_core.fitness.SurrogateSlope`), and every round of it is real, so
    each step is confirmed by rollouts on the run's paired scenarios."""

    follows_surrogate_slope: bool

    def set_slope(self, slope: SlopeFn | None) -> None:
        """The surrogate's cost and gradient for the next `ask`, or None."""


def follows_surrogate_slope(optimizer: object) -> bool:
    """Whether `optimizer` (a class or an instance) declares `follows_surrogate_slope`."""
    return getattr(optimizer, "follows_surrogate_slope", False) is True
