"""Design refinement along the surrogate's gradient (issue 52): projected gradient descent
on the pseudo-critics' cost from one start design, inside a trust region that shrinks when a
step's real cost does not improve; every step is confirmed by real rollouts."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_plugins.optimizers._common import finite_costs

from coadapt_core import hookimpl
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.optimizer import Optimizer, SlopeFn
from coadapt_core.options import PluginOption

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.2"

OPTIONS: tuple[PluginOption, ...] = (
    PluginOption(
        "step_size",
        "float",
        0.2,
        "the first step's length (the trust region's radius), as a fraction of the range",
        minimum=1e-6,
        maximum=1.0,
    ),
    PluginOption(
        "shrink",
        "float",
        0.5,
        "the radius's factor after a step whose real cost did not improve",
        minimum=0.01,
        maximum=0.99,
    ),
    PluginOption(
        "grow",
        "float",
        1.5,
        "the radius's factor after an accepted step (at most max_step)",
        minimum=1.0,
    ),
    PluginOption(
        "max_step",
        "float",
        0.3,
        "the largest radius, as a fraction of the range",
        minimum=1e-6,
        maximum=1.0,
    ),
    PluginOption(
        "min_step",
        "float",
        0.05,
        "the smallest radius: a failed step at it keeps it (no real evaluation of designs "
        "closer than this), as a fraction of the range",
        minimum=1e-6,
        maximum=1.0,
    ),
    PluginOption(
        "backtracks",
        "int",
        6,
        "halvings of a step, on the surrogate alone, while it predicts no improvement over the "
        "centre (before a real evaluation is spent)",
        minimum=0,
    ),
    PluginOption(
        "start_at",
        "str",
        None,
        "the design the descent starts from, comma-separated values (a run fills it: the "
        "robot's nominal design, then the lowest real cost so far); unset: the range's middle",
        from_run="start_design",
    ),
)


class GradientOptimizer(Optimizer):
    """Trust-region projected gradient descent on the surrogate (issue 52), one design a round.

    The first rounds evaluate the start: `initial_designs` in order when given, else
    `start_at` (projected into the range), else the range's middle; the lowest real cost
    among them is the centre. Each later round proposes one step from the centre: along the
    negative gradient of the surrogate (`set_slope`, handed by the co-adaptation loop)
    over the continuous variables in the unit cube of the range, to the trust region's
    radius, projected onto the bounds; the motor types (discrete variables) stay the
    centre's. Before a real evaluation is spent the step is halved on the surrogate alone
    (at most `backtracks` times) while the surrogate predicts no improvement over the
    centre. The loop evaluates every round real on the run's paired scenarios: a step whose
    real cost is lower becomes the centre and the radius grows (`grow`, at most `max_step`);
    otherwise the radius shrinks (`shrink`, at least `min_step`).

    Without a surrogate gradient (a backend that offers none, or the conformance suite's
    sphere) the gradient is a linear least-squares model of the real costs evaluated within
    twice the radius of the centre, and a round probes a coordinate at the radius where
    there are too few of them: a derivative-free trust-region method.

    `last_step` describes the round just told (the loop keeps it in the run's `batches`):
    kind (start, step, probe), the centre it left, the radius, the gradient's source, the
    surrogate's cost at the centre and at the proposal, the real cost, accepted or not.
    State for resumed runs is explicit (centre, radius, queue, the step log), never replayed:
    the surrogate a proposal followed is not stored.
    """

    name: ClassVar[str] = "gradient"
    description: ClassVar[str] = (
        "projected gradient descent on the surrogate in a trust region, each step confirmed real"
    )
    sequential: ClassVar[bool] = True
    supports_mixed: ClassVar[bool] = True
    follows_surrogate_slope: ClassVar[bool] = True
    option_specs: ClassVar[tuple] = OPTIONS

    def __init__(self, space: DesignSpace, **kwargs: Any):
        super().__init__(space, **kwargs)
        o = self.options
        if o["max_step"] < o["step_size"]:
            raise UserError(
                f"max_step ({o['max_step']}) must be at least step_size ({o['step_size']})",
                field="optimizer_options.max_step",
            )
        if o["min_step"] > o["step_size"]:
            raise UserError(
                f"min_step ({o['min_step']}) must be at most step_size ({o['step_size']})",
                field="optimizer_options.min_step",
            )
        self._mask = space.continuous_mask
        self.center: np.ndarray | None = None  # [dim] accepted design
        self.center_cost = float("inf")
        self.radius = float(o["step_size"])
        self.queue = self._starts()  # designs still to evaluate first
        self.pending: dict[str, Any] | None = None  # the proposal asked, until told
        self.oracle: SlopeFn | None = None  # the surrogate's, handed before each ask
        self.last_step: dict[str, Any] | None = None
        self.steps: list[dict[str, Any]] = []

    def set_slope(self, slope: SlopeFn | None) -> None:
        """The surrogate's cost and gradient for the next `ask` (`FollowsSurrogateSlope`);
        None: the model of the real costs stands in."""
        self.oracle = slope

    def _starts(self) -> list[np.ndarray]:
        import numpy as np

        if self.initial_designs is not None:
            return [row.copy() for row in self.initial_designs]
        text = self.options["start_at"]
        if text:
            try:
                values = np.array([float(v) for v in str(text).split(",")], dtype=float)
            except ValueError:
                values = np.array([])
            if values.shape != (self.space.dim,):
                raise UserError(
                    f"start_at must be {self.space.dim} comma-separated numbers, got '{text}'",
                    field="optimizer_options.start_at",
                )
            unit = np.clip(self.space.encode(values[None]), 0.0, 1.0)
            return [self.space.decode(unit)[0]]
        return [self.space.decode(np.full((1, self.space.dim), 0.5))[0]]

    # -- the unit cube of the continuous variables -------------------------------------------
    def _unit(self, designs: np.ndarray) -> np.ndarray:
        import numpy as np

        return self.space.encode(np.atleast_2d(designs))[:, self._mask]

    def _design(self, unit: np.ndarray) -> np.ndarray:
        """The centre with its continuous variables at `unit` (clipped: the projection)."""
        import numpy as np

        full = self.space.encode(self.center[None])[0]
        full[self._mask] = np.clip(unit, 0.0, 1.0)
        design = self.space.decode(full[None])[0]
        design[~self._mask] = self.center[~self._mask]  # motor types stay exactly
        return design

    def _unit_gradient(self, gradient: np.ndarray) -> np.ndarray:
        import numpy as np

        width = (self.space.upper - self.space.lower)[self._mask]
        return np.asarray(gradient, dtype=float)[self._mask] * width

    # -- ask / tell --------------------------------------------------------------------------
    def _ask(self) -> np.ndarray:
        import numpy as np

        if self.queue:
            design = self.queue[0]
            self.pending = {"kind": "start", "design": design.tolist()}
            return design[None]
        self.pending = self._proposal()
        return np.asarray(self.pending["design"], dtype=float)[None]

    def _proposal(self) -> dict[str, Any]:
        import numpy as np

        step: dict[str, Any] = {
            "kind": "step",
            "from": self.center.tolist(),
            "radius": self.radius,
            "center_cost": self.center_cost,
        }
        if self.oracle is not None:
            cost, grad = self.oracle(self.center[None])
            step["source"], step["surrogate_center"] = "surrogate", float(cost[0])
            slope = self._unit_gradient(grad[0])
        else:
            step["source"], slope = "model", self._model_gradient()
        u = self._unit(self.center)[0]
        if slope is not None:
            # projected gradient: a variable at a bound the gradient pushes past stays there
            free = ~(((u <= 0.0) & (slope > 0)) | ((u >= 1.0) & (slope < 0)))
            slope = np.where(free, slope, 0.0)
        if slope is None or not np.linalg.norm(slope) > 0:
            return self._probe(step, u)
        direction = -slope / np.linalg.norm(slope)
        step["design"] = self._design(u + self.radius * direction).tolist()
        if self.oracle is not None:
            self._backtrack(step, u, direction)
        return step

    def _backtrack(self, step: dict[str, Any], u: np.ndarray, direction: np.ndarray) -> None:
        """Halve the step, on the surrogate alone, while it predicts no improvement over the
        centre (a curved surrogate, a step past its minimum): one batch of the candidate
        lengths, the longest that improves, else the shortest."""
        import numpy as np

        lengths = self.radius * 0.5 ** np.arange(self.options["backtracks"] + 1)
        designs = np.stack([self._design(u + length * direction) for length in lengths])
        costs, _ = self.oracle(designs)
        better = np.flatnonzero(costs < step["surrogate_center"])
        i = int(better[0]) if better.size else len(lengths) - 1
        step["design"], step["surrogate_cost"] = designs[i].tolist(), float(costs[i])
        step["length"] = float(lengths[i])

    def _probe(self, step: dict[str, Any], u: np.ndarray) -> dict[str, Any]:
        """One coordinate at the radius (too few evaluations near the centre for a model, or
        a stationary centre), cycling through the continuous variables."""
        j = sum(1 for s in self.steps if s["kind"] == "probe") % max(1, len(u))
        target = u.copy()
        target[j] = u[j] + self.radius if u[j] + self.radius <= 1.0 else u[j] - self.radius
        step["kind"] = "probe"
        step["design"] = self._design(target).tolist()
        return step

    def _model_gradient(self) -> np.ndarray | None:
        """The slope of a linear least-squares fit of the real costs told within twice the
        radius of the centre (unit cube), or None when they do not determine one."""
        import numpy as np

        if not self._history:
            return None
        designs = np.concatenate([d for d, _ in self._history])
        costs = finite_costs(np.concatenate([c for _, c in self._history]))
        same = (designs[:, ~self._mask] == self.center[~self._mask]).all(axis=1)
        offset = self._unit(designs) - self._unit(self.center)
        near = same & (np.linalg.norm(offset, axis=1) <= 2.0 * self.radius + 1e-12)
        a = np.hstack([np.ones((int(near.sum()), 1)), offset[near]])
        if a.shape[0] < a.shape[1] or np.linalg.matrix_rank(a) < a.shape[1]:
            return None
        coef = np.linalg.lstsq(a, costs[near], rcond=None)[0]
        return coef[1:]

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        if self.pending is None:
            raise RuntimeError("tell() without a preceding ask()")
        cost = float(finite_costs(costs)[0])
        step = {**self.pending, "real_cost": cost}
        improved = cost < self.center_cost
        if step["kind"] == "start":
            self.queue.pop(0)
        elif step["kind"] == "step":
            grown = min(self.radius * self.options["grow"], self.options["max_step"])
            shrunk = max(self.radius * self.options["shrink"], self.options["min_step"])
            self.radius = grown if improved else shrunk
        if improved:
            self.center, self.center_cost = designs[0].copy(), cost
        step["accepted"] = bool(improved)
        self.steps.append(step)
        self.last_step, self.pending = step, None

    def final_population(self) -> np.ndarray:
        """The centre (the range narrows around the accepted design)."""
        return super().final_population() if self.center is None else self.center[None]

    # -- state as data -----------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        return {
            **super().state_dict(),
            "center": None if self.center is None else self.center.tolist(),
            "center_cost": self.center_cost,
            "radius": self.radius,
            "queue": [q.tolist() for q in self.queue],
            "steps": self.steps,
        }

    def _restore(self, state: dict[str, Any], rounds: list[tuple[np.ndarray, np.ndarray]]) -> None:
        import numpy as np

        center = state["center"]
        self.center = None if center is None else np.asarray(center, dtype=float)
        self.center_cost = float(state["center_cost"])
        self.radius = float(state["radius"])
        self.queue = [np.asarray(q, dtype=float) for q in state["queue"]]
        self.steps = [dict(s) for s in state["steps"]]
        self.last_step = self.steps[-1] if self.steps else None


@hookimpl
def coadapt_register_optimizers() -> list[type[Optimizer]]:
    return [GradientOptimizer]
