"""The final check of a co-adaptation run (docs/coadaptation.md, "Evaluation protocol"): the
best candidates and the nominal design are re-evaluated together, block by block of paired
scenarios, until the improvement of the best over the nominal design is at least four paired
standard errors or `max_blocks` blocks are spent; it is then reported as significant or not.

Blocks are scenario sets drawn from the run's seed (`block_seed(b)`) other than the one the
optimizer's real rounds used, so the candidates' selection does not flatter them."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from coadapt_core.fitness import RealFitness, improvement_se, robust_cost, scenario_se
from coadapt_core.objective import Objective

#: the improvement must be at least this many paired standard errors to count as significant
SIGNIFICANCE_RATIO = 4.0


@dataclass
class FinalCheck:
    fit: RealFitness  # pooled over blocks: costs [C + 1, M] etc.; the nominal design is last
    best: int  # index of the best candidate (lowest first cost)
    blocks: int
    scenarios: int  # per design
    cost_se: np.ndarray | None  # [C + 1, M]
    improvement_se: dict[str, float | None]
    significant: bool | None  # None: the backend gives no per-scenario costs

    def uncertainty(self, names: Sequence[str]) -> dict[str, Any]:
        """Summary fields: standard errors of the best and nominal costs, the improvements'
        paired standard errors, fall rates, the scenario count and the verdict."""
        se = self.cost_se
        falls = self.fit.fall_rate

        def per_objective(row: int) -> dict[str, float | None]:
            return {n: (None if se is None else float(se[row, j])) for j, n in enumerate(names)}

        best_se, nominal_se = per_objective(self.best), per_objective(-1)
        return {
            "best_cost_se": best_se[names[0]],
            "best_costs_se": best_se,
            "nominal_cost_se": nominal_se[names[0]],
            "nominal_costs_se": nominal_se,
            "improvement_se": self.improvement_se[names[0]],
            "improvements_se": self.improvement_se,
            "significant": self.significant,
            "best_fall_rate": None if falls is None else float(falls[self.best]),
            "nominal_fall_rate": None if falls is None else float(falls[-1]),
            "final_scenarios": self.scenarios,
            "final_blocks": self.blocks,
        }


def _pool(fits: list[RealFitness]) -> RealFitness:
    """One RealFitness over all scenarios of several blocks (costs and errors over the pooled
    scenarios; [K] figures such as survival averaged, the blocks being of equal size)."""
    out = copy.copy(fits[-1])
    if all(f.per_scenario is not None for f in fits):
        per = np.concatenate([np.asarray(f.per_scenario, dtype=float) for f in fits], axis=1)
        out.per_scenario = per
        out.costs = robust_cost(per)
        out.cost_se = scenario_se(per)
    else:
        out.costs = np.mean([np.asarray(f.costs, dtype=float) for f in fits], axis=0)
    out.interactions = int(sum(int(f.interactions) for f in fits))
    out.seconds = float(sum(float(f.seconds) for f in fits))
    k = np.asarray(out.costs).shape[0]
    for name, value in vars(fits[-1]).items():  # survival, fall rate and any other [K] figure
        if name in ("costs", "per_scenario", "cost_se", "buffer"):
            continue
        if isinstance(value, np.ndarray) and value.shape == (k,) and all(getattr(f, name) is not None for f in fits):
            setattr(out, name, np.mean([np.asarray(getattr(f, name), dtype=float) for f in fits], axis=0))
    return out


def final_check(
    real_fitness: Callable[[np.ndarray, int], RealFitness],
    designs: np.ndarray,
    objectives: Sequence[Objective],
    *,
    max_blocks: int,
    choose_best: Callable[[np.ndarray], int] | None = None,
    on_block: Callable[[int], None] | None = None,
) -> FinalCheck:
    """`designs` [C + 1, dim] with the nominal design last; `real_fitness(designs, block)`
    evaluates them on scenario block `block` (1, 2, ...). Adds blocks until the paired
    standard error of the best candidate's improvement (first objective) is at most a quarter
    of the improvement, or `max_blocks` are spent. `choose_best(costs)` picks the best row
    (default: the lowest first cost among the candidates)."""
    fits: list[RealFitness] = []
    pooled: RealFitness | None = None
    best, se_map, significant = 0, {o.name: None for o in objectives}, None
    for block in range(1, max(1, int(max_blocks)) + 1):
        if on_block is not None:
            on_block(block)
        fits.append(real_fitness(designs, block))
        pooled = _pool(fits)
        costs = np.asarray(pooled.costs, dtype=float).reshape(len(designs), -1)
        best = choose_best(costs) if choose_best is not None else int(np.argmin(costs[:-1, 0]))
        if pooled.per_scenario is None:  # no scenario spread to measure: one block is all
            break
        per = np.asarray(pooled.per_scenario, dtype=float)
        se_map = {o.name: improvement_se(o, per[best, :, j], per[-1, :, j]) for j, o in enumerate(objectives)}
        first = objectives[0]
        gain = float(first.improvement(float(costs[best, 0]), float(costs[-1, 0])))
        se = se_map[first.name]
        significant = bool(np.isfinite(se) and abs(gain) >= SIGNIFICANCE_RATIO * se and se >= 0)
        if significant:
            break
    assert pooled is not None
    cost_se = None if pooled.per_scenario is None else np.asarray(pooled.cost_se, dtype=float)
    scenarios = int(np.asarray(pooled.per_scenario).shape[1]) if pooled.per_scenario is not None else 0
    se_out = {k: (None if v is None or not np.isfinite(v) else float(v)) for k, v in se_map.items()}
    return FinalCheck(fit=pooled, best=best, blocks=len(fits), scenarios=scenarios, cost_se=cost_se,
                      improvement_se=se_out, significant=significant)


def no_uncertainty(names: Sequence[str]) -> dict[str, Any]:
    """The summary fields of `FinalCheck.uncertainty` when no final check measured them (the
    BO baseline, whose designs each have their own policy)."""
    empty = {n: None for n in names}
    return {"best_cost_se": None, "best_costs_se": dict(empty), "nominal_cost_se": None,
            "nominal_costs_se": dict(empty), "improvement_se": None, "improvements_se": dict(empty),
            "significant": None, "best_fall_rate": None, "nominal_fall_rate": None, "final_scenarios": 0,
            "final_blocks": 0}


def batch_errors(fit: RealFitness) -> dict[str, Any]:
    """What a real optimisation round records beside its costs (the run summary's `batches`):
    the standard error of its best design's cost and its fall rate (first objective), the
    median relative standard error and the mean fall rate over its designs. Empty when the
    backend gives no per-scenario costs."""
    if getattr(fit, "cost_se", None) is None:
        return {}
    costs = np.asarray(fit.costs, dtype=float).reshape(len(fit.cost_se), -1)
    se = np.asarray(fit.cost_se, dtype=float).reshape(costs.shape)
    best = int(np.nanargmin(costs[:, 0])) if np.isfinite(costs[:, 0]).any() else 0
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = se[:, 0] / np.abs(costs[:, 0])
    rel = rel[np.isfinite(rel)]
    falls = None if fit.fall_rate is None else np.asarray(fit.fall_rate, dtype=float)
    return {
        "best_cost_se": float(se[best, 0]),
        "median_relative_se": float(np.median(rel)) if rel.size else None,
        "best_fall_rate": None if falls is None else float(falls[best]),
        "fall_rate": None if falls is None else float(falls.mean()),
    }
