"""The final check of a co-adaptation run (docs/coadaptation.md, "Evaluation protocol"): the
best candidates and the nominal design are re-evaluated together, block by block of paired
scenarios, until the improvement of the best over the nominal design is at least four paired
standard errors or `max_blocks` blocks are spent; it is then reported as significant or not.

Blocks are scenario sets drawn from the run's seed (`block_seed(b)`) other than the one the
optimizer's real rounds used, so the candidates' selection does not flatter them."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coadapt_core.costs import CostRule, compare_designs, fall_statistics, falls_more, scenario_se
from coadapt_core.fitness import RealFitness
from coadapt_core.objective import Objective
from coadapt_core.pareto import HV_DEFINITION, front_rows, hypervolume, hypervolume_se

#: the improvement must be at least this many paired standard errors to count as significant
SIGNIFICANCE_RATIO = 4.0


@dataclass
class FinalCheck:
    fit: RealFitness  # pooled over blocks: costs [C + 1, M] etc.; the nominal design is last
    #: index of the best candidate (the lowest first cost among those that do not fall more);
    #: -1: the nominal design
    best: int
    blocks: int
    scenarios: int  # per design
    cost_se: np.ndarray | None  # [C + 1, M]
    improvement_se: dict[str, float | None]
    significant: bool | None  # None: the backend gives no per-scenario costs
    rule: CostRule = field(default_factory=CostRule)
    # best against nominal on the pooled scenarios (costs.compare_designs); None without
    # per-scenario costs
    comparison: dict[str, Any] | None = None
    # per candidate: its paired fall-rate difference to the nominal design and whether it may
    # be the best
    fall_check: list[dict[str, Any]] = field(default_factory=list)

    def uncertainty(self, names: Sequence[str]) -> dict[str, Any]:
        """Summary fields: standard errors of the best and nominal costs, the improvements'
        paired standard errors, the plain mean (eq. 4) beside the rule's cost, fall rates with
        their standard errors, the scenario count and the verdict."""
        se = self.cost_se
        falls = self.fit.fall_rate

        def per_objective(row: int) -> dict[str, float | None]:
            return {n: (None if se is None else float(se[row, j])) for j, n in enumerate(names)}

        best_se, nominal_se = per_objective(self.best), per_objective(-1)
        out = {
            "cost_rule": self.rule.rule,
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
            "best_is_nominal": self.best in (-1, len(np.asarray(self.fit.costs)) - 1),
            "fall_check": self.fall_check,
        }
        comp = self.comparison
        if comp is not None:
            objs = comp["objectives"]
            first = objs[names[0]]
            out.update(
                {
                    "best_plain_mean": first["plain_mean"],
                    "best_plain_mean_se": first["plain_mean_se"],
                    "nominal_plain_mean": first["nominal_plain_mean"],
                    "nominal_plain_mean_se": first["nominal_plain_mean_se"],
                    "improvement_plain": first["improvement_plain"],
                    "improvement_plain_se": _finite(first["improvement_plain_se"]),
                    "best_plain_means": {n: objs[n]["plain_mean"] for n in names},
                    "best_plain_means_se": {n: objs[n]["plain_mean_se"] for n in names},
                    "nominal_plain_means": {n: objs[n]["nominal_plain_mean"] for n in names},
                    "nominal_plain_means_se": {n: objs[n]["nominal_plain_mean_se"] for n in names},
                    "improvements_plain": {n: objs[n]["improvement_plain"] for n in names},
                    "improvements_plain_se": {
                        n: _finite(objs[n]["improvement_plain_se"]) for n in names
                    },
                }
            )
            if comp.get("fall_rate") is not None:
                out.update(
                    {
                        "best_fall_rate": comp["fall_rate"],
                        "best_fall_rate_se": _finite(comp["fall_rate_se"]),
                        "nominal_fall_rate": comp["reference_fall_rate"],
                        "nominal_fall_rate_se": _finite(comp["reference_fall_rate_se"]),
                        "fall_rate_difference": comp["fall_rate_difference"],
                        "fall_rate_difference_se": _finite(comp["fall_rate_difference_se"]),
                    }
                )
        return out

    def front(self, designs: np.ndarray, names: Sequence[str]) -> dict[str, Any]:
        """The stored Pareto front of several objectives: the non-dominated candidates of this
        re-evaluation (the optimizer's own front mixes surrogate and noisier in-run costs),
        sorted by the first cost, each with its costs and their standard errors; the design
        the run returns (`returned`: index 0, the lowest first cost); the front's hypervolume
        (`coadapt_core.pareto.HV_DEFINITION`) with its paired bootstrap standard error over
        the check's scenarios (None without per-scenario costs)."""
        designs = np.asarray(designs, dtype=float)
        costs = np.asarray(self.fit.costs, dtype=float).reshape(len(designs), -1)
        rows = front_rows(designs[:-1], costs[:-1])
        se = self.cost_se
        out: dict[str, Any] = {
            "designs": designs[rows].tolist(),
            "costs": [dict(zip(names, map(float, costs[r]), strict=True)) for r in rows],
            "costs_se": None
            if se is None
            else [dict(zip(names, map(float, se[r]), strict=True)) for r in rows],
            "returned": 0,
            "scenarios": self.scenarios,
            "hypervolume_definition": HV_DEFINITION,
        }
        if self.fit.per_scenario is not None:
            per = np.asarray(self.fit.per_scenario, dtype=float)
            falls = self.fit.scenario_falls
            ref = (
                self.rule.reference(per[-1], None if falls is None else falls[-1])
                if self.rule.needs_reference
                else None
            )
            values = self.rule.scenario_values(per, falls, ref)
            # every candidate: one off the front here may be on it in a resample (a dominated
            # one adds nothing)
            out["hypervolume"], out["hypervolume_se"] = hypervolume_se(values, self.rule.aggregate)
        else:
            out["hypervolume"], out["hypervolume_se"] = hypervolume(costs[rows], costs[-1]), None
        return out


def _finite(value: Any) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def _pool(fits: list[RealFitness], rule: CostRule | None = None) -> RealFitness:
    """One RealFitness over all scenarios of several blocks (costs under `rule` and their
    errors over the pooled scenarios, the reference level from the last row, the nominal
    design; [K] figures such as survival averaged, the blocks being of equal size)."""
    rule = rule or CostRule()
    out = copy.copy(fits[-1])
    if all(f.per_scenario is not None for f in fits):
        per = np.concatenate([np.asarray(f.per_scenario, dtype=float) for f in fits], axis=1)
        falls = (
            np.concatenate([np.asarray(f.scenario_falls, dtype=bool) for f in fits], axis=1)
            if all(f.scenario_falls is not None for f in fits)
            else None
        )
        out.per_scenario, out.scenario_falls = per, falls
        ref = (
            rule.reference(per[-1], None if falls is None else falls[-1])
            if rule.needs_reference
            else None
        )
        values = rule.scenario_values(per, falls, ref)
        out.costs = rule.aggregate(values)
        out.cost_se = scenario_se(values, rule.aggregate)
    else:
        out.costs = np.mean([np.asarray(f.costs, dtype=float) for f in fits], axis=0)
    out.interactions = int(sum(int(f.interactions) for f in fits))
    out.seconds = float(sum(float(f.seconds) for f in fits))
    k = np.asarray(out.costs).shape[0]
    for name, value in vars(fits[-1]).items():  # survival, fall rate and any other [K] figure
        if name in ("costs", "per_scenario", "cost_se", "buffer", "scenario_falls"):
            continue
        if (
            isinstance(value, np.ndarray)
            and value.shape == (k,)
            and all(getattr(f, name) is not None for f in fits)
        ):
            setattr(
                out,
                name,
                np.mean([np.asarray(getattr(f, name), dtype=float) for f in fits], axis=0),
            )
    return out


def _fall_check(
    falls: np.ndarray | None, candidates: int, tolerance: float
) -> list[dict[str, Any]]:
    """Per candidate row: its paired fall-rate difference to the nominal design (the last row)
    and whether it stays within max(tolerance, 2 standard errors)."""
    out = []
    for i in range(candidates):
        st = fall_statistics(falls, i, -1) if falls is not None else fall_statistics(None, 0, 0)
        d, se = st["fall_rate_difference"], st["fall_rate_difference_se"]
        out.append(
            {
                "row": i,
                "fall_rate": st["fall_rate"],
                "fall_rate_difference": d,
                "fall_rate_difference_se": _finite(se),
                "eligible": not falls_more(d, se, tolerance),
            }
        )
    return out


def _best_row(
    costs: np.ndarray,
    falls: np.ndarray | None,
    fall_tolerance: float | None,
    choose_best: Callable[[np.ndarray], int] | None,
) -> tuple[int, list[dict[str, Any]]]:
    """(the best row of `costs` [C + 1, M], the nominal design last; the fall gate per
    candidate): `choose_best`'s row, else the lowest first cost among the candidates the
    fall gate lets through, the nominal design when none is cheaper than it."""
    if choose_best is not None:
        return choose_best(costs), []
    nominal = len(costs) - 1
    gate = _fall_check(falls, nominal, fall_tolerance) if fall_tolerance is not None else []
    allowed = [i for i in range(nominal) if not gate or gate[i]["eligible"]]
    best = min(allowed, key=lambda i: costs[i, 0]) if allowed else nominal
    if fall_tolerance is not None and costs[best, 0] >= costs[nominal, 0]:
        best = nominal
    return best, gate


def final_check(
    real_fitness: Callable[[np.ndarray, int], RealFitness],
    designs: np.ndarray,
    objectives: Sequence[Objective],
    *,
    max_blocks: int,
    min_blocks: int = 1,
    rule: CostRule | None = None,
    fall_tolerance: float | None = None,
    choose_best: Callable[[np.ndarray], int] | None = None,
    on_block: Callable[[int], None] | None = None,
) -> FinalCheck:
    """`designs` [C + 1, dim] with the nominal design last; `real_fitness(designs, block)`
    evaluates them on scenario block `block` (1, 2, ...). Adds blocks until at least
    `min_blocks` are spent and the paired standard error of the best candidate's improvement
    (first objective) is at most a quarter of the improvement, or `max_blocks` are spent.

    With `fall_tolerance` set, a candidate whose fall rate exceeds the nominal design's by
    more than max(fall_tolerance, 2 paired standard errors) cannot be the best; when every
    candidate does, or none is cheaper than the nominal design, the nominal design is the best
    (`best == C`, improvement 0): the run found nothing that beats the robot it started from
    without falling more. `choose_best(costs)` picks the best row instead (the Pareto front's
    own choice; no fall gate)."""
    rule = rule or CostRule("trimmed")
    fits: list[RealFitness] = []
    pooled: RealFitness | None = None
    best, se_map, significant, gate = 0, {o.name: None for o in objectives}, None, []
    nominal = len(designs) - 1
    for block in range(1, max(1, int(max_blocks)) + 1):
        if on_block is not None:
            on_block(block)
        fits.append(real_fitness(designs, block))
        pooled = _pool(fits, rule)
        costs = np.asarray(pooled.costs, dtype=float).reshape(len(designs), -1)
        best, gate = _best_row(costs, pooled.scenario_falls, fall_tolerance, choose_best)
        if pooled.per_scenario is None:  # no scenario spread to measure: one block is all
            break
        per = np.asarray(pooled.per_scenario, dtype=float)
        comp = compare_designs(rule, objectives, per, pooled.scenario_falls, best, nominal)
        se_map = {name: v["improvement_se"] for name, v in comp["objectives"].items()}
        first = objectives[0]
        gain = float(first.improvement(float(costs[best, 0]), float(costs[-1, 0])))
        se = se_map[first.name]
        settled = bool(np.isfinite(se) and abs(gain) >= SIGNIFICANCE_RATIO * se and se >= 0)
        # the nominal design as the best is no improvement: its 0.0 +- 0.0 settles the check
        # (no more blocks) but is not significant
        significant = settled and best != nominal and gain != 0
        if settled and block >= min_blocks:
            break
    assert pooled is not None
    cost_se = None if pooled.per_scenario is None else np.asarray(pooled.cost_se, dtype=float)
    scenarios = (
        int(np.asarray(pooled.per_scenario).shape[1]) if pooled.per_scenario is not None else 0
    )
    comparison = None
    if pooled.per_scenario is not None:
        comparison = compare_designs(
            rule,
            objectives,
            np.asarray(pooled.per_scenario, dtype=float),
            pooled.scenario_falls,
            best,
            nominal,
        )
    se_out = {k: (None if v is None or not np.isfinite(v) else float(v)) for k, v in se_map.items()}
    return FinalCheck(
        fit=pooled,
        best=best,
        blocks=len(fits),
        scenarios=scenarios,
        cost_se=cost_se,
        improvement_se=se_out,
        significant=significant,
        rule=rule,
        comparison=comparison,
        fall_check=gate,
    )


def no_uncertainty(names: Sequence[str]) -> dict[str, Any]:
    """The summary fields of `FinalCheck.uncertainty` when no final check measured them (the
    BO baseline, whose designs each have their own policy)."""
    empty = {n: None for n in names}
    return {
        "best_cost_se": None,
        "best_costs_se": dict(empty),
        "nominal_cost_se": None,
        "nominal_costs_se": dict(empty),
        "improvement_se": None,
        "improvements_se": dict(empty),
        "significant": None,
        "best_fall_rate": None,
        "nominal_fall_rate": None,
        "final_scenarios": 0,
        "final_blocks": 0,
    }


def batch_errors(
    fit: RealFitness, rule: CostRule | None = None, reference: np.ndarray | None = None
) -> dict[str, Any]:
    """What a real optimisation round records beside its costs (the run summary's `batches`):
    for its best design (first objective, under `rule` with its reference level) the cost's
    standard error, the plain mean (eq. 4) with its standard error and the fall rate with its
    standard error; the median relative standard error and the mean fall rate over its
    designs; each design's cost SE (`cost_se`) and, with two designs or more on per-scenario
    costs, its paired SE (`cost_paired_se`: the noise of their ranking on common scenarios).
    Empty when the backend gives no per-scenario costs."""
    if getattr(fit, "per_scenario", None) is None and getattr(fit, "cost_se", None) is None:
        return {}
    if getattr(fit, "per_scenario", None) is not None and rule is not None:
        per = np.asarray(fit.per_scenario, dtype=float)
        values = rule.scenario_values(per, fit.scenario_falls, reference)
        costs, se = rule.aggregate(values), scenario_se(values, rule.aggregate)
    else:
        costs = np.asarray(fit.costs, dtype=float).reshape(len(fit.cost_se), -1)
        se = np.asarray(fit.cost_se, dtype=float).reshape(costs.shape)
        per = None
    best = int(np.nanargmin(costs[:, 0])) if np.isfinite(costs[:, 0]).any() else 0
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = se[:, 0] / np.abs(costs[:, 0])
    rel = rel[np.isfinite(rel)]
    falls = None if fit.fall_rate is None else np.asarray(fit.fall_rate, dtype=float)
    out = {
        "best_cost_se": float(se[best, 0]),
        "median_relative_se": float(np.median(rel)) if rel.size else None,
        "best_fall_rate": None if falls is None else float(falls[best]),
        "fall_rate": None if falls is None else float(falls.mean()),
        # each design's cost SE (first objective): the noise ceiling of the surrogate's ranking
        "cost_se": [float(x) if np.isfinite(x) else None for x in se[:, 0]],
    }
    if per is not None and len(values) > 1:
        # the noise of the designs' ranking: every design ran on the same scenarios, so a
        # fresh scenario set moves their costs together but for each design's own response
        # (its scenario values less the designs' mean on each scenario; K/(K-1) corrects
        # for its own share of that mean)
        own = values - values.mean(axis=0, keepdims=True)
        paired = scenario_se(own, rule.aggregate)[:, 0] * np.sqrt(len(values) / (len(values) - 1))
        out["cost_paired_se"] = [float(x) if np.isfinite(x) else None for x in paired]
    if per is not None:
        column = per[best, :, 0]
        out["best_plain_mean"] = float(column.mean())
        out["best_plain_mean_se"] = (
            float(column.std(ddof=1) / np.sqrt(len(column))) if len(column) > 1 else None
        )
        if fit.scenario_falls is not None:
            st = fall_statistics(np.asarray(fit.scenario_falls, dtype=float), best, best)
            out["best_fall_rate"], out["best_fall_rate_se"] = (
                st["fall_rate"],
                _finite(st["fall_rate_se"]),
            )
    return out
