"""What a co-adaptation run ends with: the candidates its final check re-evaluates, the
outcome of that check, `summary.json` (the run's one record of its result) and the `--json`
line printed from it (`CoadaptResult`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.coadapt.cautions import run_warnings
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.refine import refinement_center, refinement_summary
from coadapt_core.coadapt.reliability import fall_verdict, judge_short
from coadapt_core.coadapt.state import LoopState
from coadapt_core.numerics import simulated_numerics
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer

#: the `--json` line's fields beside the rule's cost: the rule, the paper's plain mean (eq. 4)
#: with its standard error and improvement, fall rates with standard errors and their paired
#: difference, and whether the best design falls significantly more often than nominal
JSON_PLAIN_AND_FALLS = (
    "cost_rule",
    "best_plain_mean",
    "best_plain_mean_se",
    "nominal_plain_mean",
    "nominal_plain_mean_se",
    "improvement_plain",
    "improvement_plain_se",
    "best_fall_rate_se",
    "nominal_fall_rate_se",
    "fall_rate_difference",
    "fall_rate_difference_se",
    "falls_more",
)


@dataclass
class CoadaptResult:
    run_id: str
    run_dir: Path
    summary: dict[str, Any]

    def json_line(self) -> dict[str, Any]:
        s = self.summary
        line = {
            k: s.get(k)
            for k in (
                "run_id",
                "best_design",
                "best_cost",
                "best_cost_se",
                "nominal_cost",
                "nominal_cost_se",
                "improvement",
                "improvement_se",
                "significant",
                "best_fall_rate",
                "nominal_fall_rate",
                *JSON_PLAIN_AND_FALLS,
                "interactions",
                "seconds",
            )
        }
        # the walking gate's verdict travels with every improvement (reliability.py)
        line["reliable"] = s.get("reliable")
        line["reliability"] = s.get("reliability")
        line["warnings"] = s.get("warnings", [])  # what to know before trusting it (cautions.py)
        line["numerics"] = s.get("numerics")  # precision, device kind, versions (numerics.py)
        if s.get("verification") is not None:  # `coadapt run --verify` (coadapt/verify.py)
            line["verification"] = s["verification"]
        front = s.get("pareto_front")
        if isinstance(
            front, dict
        ):  # several objectives: the front's hypervolume and its SE (pareto.py)
            line["hypervolume"], line["hypervolume_se"] = (
                front.get("hypervolume"),
                front.get("hypervolume_se"),
            )
        return line


@dataclass
class FinalOutcome:
    """What the final re-evaluation found: the best design and its costs [M], the nominal
    design's costs [M], the Pareto front of several objectives, the check's standard errors
    and significance (`final_check.FinalCheck.uncertainty`) and the walking gate's inputs."""

    best_design: np.ndarray
    best_costs: np.ndarray
    nominal_costs: np.ndarray
    uncertainty: dict[str, Any]
    front: dict[str, Any] | None = None
    walking: dict[str, dict[str, Any]] = field(default_factory=dict)


def final_candidates(
    state: LoopState, optimizer: Optimizer | None, objectives: int, population: int
) -> list[np.ndarray]:
    """The designs the final check re-evaluates beside the nominal one: the lowest real costs
    and the lowest cost of any kind for one objective; for several, the optimizer's Pareto
    front (at most `population` designs, evenly along it, both ends included)."""
    if objectives > 1:
        front, _ = optimizer.pareto_front()  # sorted by the first cost
        if len(front) > population:
            front = front[np.unique(np.linspace(0, len(front) - 1, population).round().astype(int))]
        return list(front)
    candidates: list[np.ndarray] = []
    # and the refinement's accepted design (refine.py): the final check judges what it bought
    refined = refinement_center(state)
    for item in [*state.top_real, state.best_any, None if refined is None else (refined,)]:
        if item is not None and not any(np.allclose(item[0], x) for x in candidates):
            candidates.append(np.asarray(item[0]))
    return candidates


def run_summary(
    state: LoopState,
    config: CoadaptConfig,
    objectives: Sequence[Objective],
    outcome: FinalOutcome,
    *,
    optimizer: str,
    nominal: np.ndarray,
    seconds: float,
    surrogate_quality: dict[str, Any],
    shared: bool,
    backend: Any = None,
) -> dict[str, Any]:
    """summary.json: the run's settings, its best and nominal designs with their costs and
    improvements, its interactions and seconds by phase, every batch, the surrogate's quality,
    the walking gate's verdict and the fall comparison, and the numerics `backend` trained and
    evaluated with (`coadapt_core.numerics`: precision in force, device kind, versions)."""
    s, c = state, config
    summary = {
        "run_id": s.run_id,
        "method": c.method,
        "optimizer": optimizer,
        "objective": c.objective,
        "terrain": c.terrain,
        "seed": c.seed,
        "preset": c.preset,
        **_designs_and_costs(objectives, outcome, nominal),
        **_spend(s.counters, seconds),
        "spaces": s.spaces,
        "final_space": s.space,
        "batches": s.batches,
        "pareto_front": outcome.front,
        "evaluation_policy": c.evaluation_policy,
        "cost_rule": c.cost_rule,
        "cost_cap": c.cost_cap,
        "cost_reference": s.reference,
        "surrogate_quality": surrogate_quality,
        # what a printed cost is: per-step mean of the final check's paired scenarios of
        # eval_steps steps each (costs of other commands or sizes are not comparable)
        "cost_units": {o.name: getattr(o, "unit", "") for o in objectives},
        "eval_steps": int(c.eval_steps),
    }
    refinement = refinement_summary(s)
    if refinement is not None:  # the refinement stage (refine.py): was its design the best?
        center = refinement["center"]
        refinement["chosen"] = center is not None and bool(np.allclose(center, outcome.best_design))
        # the step whose design the final check picked (0: the start, the search's own), if any
        refinement["chosen_step"] = next(
            (
                i
                for i, st in enumerate(refinement["steps"])
                if st.get("design") is not None and np.allclose(st["design"], outcome.best_design)
            ),
            None,
        )
        summary["refinement"] = refinement
    summary["policy"] = s.policy
    summary["notes"] = list(s.notes)
    # a policy trained from scratch in this run (no starting policy, or the BO baseline's
    # per-design policies from scratch) is vouched for by nothing but this gate
    scratch = (
        str(c.checkpoint).strip().lower() == "none"
        if shared
        else getattr(c, "specialized_init", "scratch") != "universal"
    )
    summary["reliable"], summary["reliability"] = judge_short(
        s.batches, outcome.walking, c.eval_steps, from_scratch=scratch
    )
    summary["starting_policy"] = (
        None if str(c.checkpoint).strip().lower() == "none" else starting_policy_file(c)
    )
    summary["final_walking"] = outcome.walking
    summary.update(outcome.uncertainty)
    summary.update(fall_verdict(summary))
    summary["warnings"] = run_warnings(
        summary
    )  # at a bound, plain mean, weak surrogate (cautions.py)
    summary["numerics"] = simulated_numerics(backend, c.sim, c.device)
    return summary


def _designs_and_costs(
    objectives: Sequence[Objective], outcome: FinalOutcome, nominal: np.ndarray
) -> dict[str, Any]:
    """The best and nominal designs with their costs per objective and the improvements."""
    names = [o.name for o in objectives]
    best_costs, nominal_costs = outcome.best_costs, outcome.nominal_costs
    improvements = {
        o.name: float(
            o.improvement(
                float(best_costs[j]) if j < len(best_costs) else float("nan"),
                float(nominal_costs[j]),
            )
        )
        for j, o in enumerate(objectives)
        if j < len(best_costs)
    }
    return {
        "best_design": [float(x) for x in outcome.best_design],
        "best_cost": float(best_costs[0]),
        "best_costs": dict(zip(names, map(float, best_costs), strict=False)),
        "nominal_design": nominal.tolist(),
        "nominal_cost": float(nominal_costs[0]),
        "nominal_costs": dict(zip(names, map(float, nominal_costs), strict=True)),
        "improvement": improvements[names[0]],
        "improvements": improvements,
    }


def _spend(cnt: dict[str, Any], seconds: float) -> dict[str, Any]:
    """The run's interactions, seconds and evaluations, in all and by phase."""
    interactions = int(
        cnt["train_interactions"] + cnt["eval_interactions"] + cnt["final_interactions"]
    )
    return {
        "interactions": interactions,
        "train_interactions": int(cnt["train_interactions"]),
        "eval_interactions": int(cnt["eval_interactions"]),
        "final_interactions": int(cnt["final_interactions"]),
        "seconds": seconds,
        "train_seconds": cnt["train_seconds"],
        "eval_seconds": cnt["eval_seconds"],
        "surrogate_seconds": cnt["surrogate_seconds"],
        "final_seconds": cnt["final_seconds"],
        "real_evaluations": int(cnt["real_evaluations"]),
        "surrogate_evaluations": int(cnt["surrogate_evaluations"]),
        "designs_evaluated": int(cnt["designs_evaluated"]),
    }


def starting_policy_file(config: CoadaptConfig) -> str | None:
    """The policy the run started from, as a path (the robot's shipped one when not given)."""
    if config.checkpoint.strip():
        return config.checkpoint.strip()
    try:
        from coadapt_core.coadapt.starting_policy import resolve_checkpoint

        found = resolve_checkpoint(config)
    except Exception:  # a fake or third-party robot without one
        return None
    return None if found is None else str(found)
