"""The refinement stage after the search (issue 52, beyond the paper; `refine_with`, off by
default): when the last outer iteration's optimizer has finished, an optimizer that follows
the surrogate's gradient (`coadapt_core.optimizer.FollowsSurrogateSlope`, named by
`refine_with`) descends from the run's best real design for `refine_rounds` real rounds.

It is the descent optimizer's own machinery, built like an outer iteration's optimizer
(`outer_optimizer.py`): the loop hands it the surrogate's cost and gradient before each
round (`HybridPolicy.slope_oracle`, the ensemble fitted to this policy's real rounds), every
round is real on the run's paired scenarios, and the optimizer accepts a step only when its
real cost is lower than the centre's (a trust region that shrinks otherwise). The stage
runs inside the last outer iteration, so the surrogate is the final policy's: its range is
that iteration's (the designs the policy was last trained on and the surrogate fitted to),
its rounds continue that iteration's `inner` count, and its first round re-evaluates the
start design under the final policy (its earlier cost may be another policy's).

Every step is kept three times: in the round's entry of `batches` (`stage: refine`,
`descent_step`), in the state's `refine.steps` (what a resumed run continues from: the
optimizer's constructor arguments and `state_dict()` as data, never replayed), and in the
summary's `refinement` (start, centre, each step's surrogate and real cost with the real
cost's standard error). The refinement's centre joins the final check's candidates, so the
check on fresh scenarios decides whether the refinement bought anything.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.hybrid import HybridPolicy
from coadapt_core.coadapt.outer_optimizer import make_optimizer, optimizer_init, optimizer_options
from coadapt_core.coadapt.schedule import Schedule
from coadapt_core.coadapt.state import LoopState, RoundRecord
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.fitness import RunRecorder
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer, follows_surrogate_slope

#: the loop's phase while the refinement runs (`LoopState.phase`)
REFINE = "refine"


class RefineHost(Protocol):
    """What the refinement needs from the loop that runs it (`CoadaptationLoop`)."""

    state: LoopState
    config: CoadaptConfig
    schedule: Schedule
    hybrid: HybridPolicy
    recorder: RunRecorder
    run_dir: Path

    def seed_for(self, *parts: int) -> int: ...

    def checkpoint(self) -> None: ...

    def emit(self, phase: str, **extra: Any) -> None: ...

    def evaluate(
        self, designs: np.ndarray, kind: str, *, uncertainty: float | None = None
    ) -> RoundRecord: ...

    def record_batch(self, designs: np.ndarray, record: RoundRecord) -> None: ...

    def end_outer(self) -> None: ...


def refiner_class(name: str) -> type[Optimizer]:
    """The optimizer `refine_with` names (a `UserError` for one that does not follow the
    surrogate's gradient)."""
    from coadapt_core.plugins import get_registry

    cls = get_registry().get("optimizer", name)
    if not follows_surrogate_slope(cls):
        raise UserError(
            f"refine_with '{name}' does not follow the surrogate's gradient (an optimizer that "
            "declares follows_surrogate_slope refines; see `coadapt plugins`)",
            field="refine_with",
        )
    return cls


def check_refinement(
    config: CoadaptConfig, objectives: list[Objective] | tuple, space: DesignSpace
) -> None:
    """Refuse, before any training is paid for, a refinement the run cannot do."""
    name = config.refine_with.strip()
    if not name:
        return
    cls = refiner_class(name)
    if len(objectives) > 1:
        raise UserError(
            f"the refinement descends one objective; this run has {len(objectives)} (use the "
            "composite objective, or no refine_with)",
            field="refine_with",
        )
    if space.is_mixed and not cls.supports_mixed:
        raise UserError(
            f"refine_with '{name}' handles continuous variables only; the run's design space has "
            "discrete ones",
            field="refine_with",
        )


def refinement_due(host: RefineHost) -> bool:
    """At the end of an outer iteration: whether the refinement runs now (the last outer
    iteration's optimizer has finished, `refine_with` is set and the refinement has not
    finished); if so the state moves to the `REFINE` phase (checkpointed)."""
    s, c = host.state, host.config
    if not c.refine_with.strip() or s.outer + 1 < host.schedule.outer_count:
        return False
    if (s.refine or {}).get("done"):
        return False
    s.phase = REFINE
    host.checkpoint()
    return True


def _start(host: RefineHost) -> dict[str, Any]:
    """The refinement's record in the state: its optimizer's constructor arguments as data,
    started at the best real design so far, in the last outer iteration's range."""
    s, c = host.state, host.config
    cls = refiner_class(c.refine_with.strip())
    space = DesignSpace.from_dict(s.space)
    start = np.asarray(s.best_real[0], dtype=float) if s.best_real else None
    options = optimizer_options(
        cls, {}, run_name=f"{s.run_id}-refine", recorder=host.recorder, start=start
    )
    init = optimizer_init(
        space,
        population=1,
        budget=int(c.refine_rounds),
        seed=host.seed_for(8, s.outer),
        num_objectives=1,
        initial_designs=None,
        options=options,
    )
    return {"with": cls.name, "init": init, "state": None, "steps": [], "done": False}


def _refiner(record: dict[str, Any]) -> Optimizer:
    """The refinement's optimizer rebuilt from the state (each round: a resumed run takes
    the same path as an uninterrupted one)."""
    opt = make_optimizer(refiner_class(record["with"]), record["init"])
    if record["state"] is not None:
        opt.load_state_dict(record["state"])
    return opt


def refine_round(host: RefineHost) -> None:
    """One real round of the refinement; when its rounds are spent, the last outer iteration
    ends (`end_outer`: the range narrows, the final phase follows)."""
    s = host.state
    if s.refine is None:
        s.refine = _start(host)
    opt = _refiner(s.refine)
    if opt.done:
        s.refine["done"] = True
        host.end_outer()
        return
    t0 = time.perf_counter()
    slope = host.hybrid.slope_oracle()
    opt.set_slope(slope)
    designs = opt.ask()  # [1, dim]
    host.emit("refinement", refine_round=len(s.refine["steps"]) + 1)
    record = host.evaluate(designs, "real")
    opt.tell(designs, record.costs[:, 0])
    host.record_batch(designs, record)
    step = _step(getattr(opt, "last_step", None) or {}, record, slope, designs)
    s.batches[-1]["stage"], s.batches[-1]["descent_step"] = REFINE, step
    s.refine["steps"].append(step)
    s.refine["state"] = opt.state_dict()
    s.inner += 1
    s.counters["real_round_wall"] = (
        s.counters.get("real_round_wall", 0.0) + time.perf_counter() - t0
    )
    s.counters["real_rounds_timed"] = s.counters.get("real_rounds_timed", 0) + 1
    host.checkpoint()
    host.emit("evaluated", kind="real")


def _step(
    step: dict[str, Any], record: RoundRecord, slope: Any, designs: np.ndarray
) -> dict[str, Any]:
    """The optimizer's step with what the round measured beside it: the real cost's standard
    error, and the surrogate's cost at the design where the step carries none (the start)."""
    out = dict(step)
    ses = record.error_bars.get("cost_se") or [record.error_bars.get("best_cost_se")]
    out["real_cost_se"] = ses[0]
    if "surrogate_cost" not in out and slope is not None:
        out["surrogate_cost"] = float(np.asarray(slope(designs)[0], dtype=float)[0])
    return out


def refinement_center(state: LoopState) -> np.ndarray | None:
    """The refinement's accepted design (a final-check candidate), or None."""
    center = ((state.refine or {}).get("state") or {}).get("center")
    return None if center is None else np.asarray(center, dtype=float)


def refinement_summary(state: LoopState) -> dict[str, Any] | None:
    """summary.json's `refinement`: the optimizer, its start and accepted design with their
    real costs and standard errors (run scenarios, final policy), and every step."""
    r = state.refine
    if not r:
        return None
    steps = r["steps"]
    accepted = [st for st in steps if st.get("accepted")]
    last = accepted[-1] if accepted else None
    first = steps[0] if steps else None
    return {
        "with": r["with"],
        "rounds": len(steps),
        "done": bool(r.get("done")),
        "start": None if first is None else first.get("design"),
        "start_cost": None if first is None else first.get("real_cost"),
        "start_cost_se": None if first is None else first.get("real_cost_se"),
        "center": None if last is None else last.get("design"),
        "center_cost": None if last is None else last.get("real_cost"),
        "center_cost_se": None if last is None else last.get("real_cost_se"),
        "accepted_steps": sum(1 for st in accepted if st.get("kind") != "start"),
        "steps": steps,
    }
