"""Cost landscapes: the real cost (Algorithm 2) of an n x n grid over the first two design
variables (Kuafu: the two leg scales), evaluated with one universal policy and stored like
any run (method "landscape"), so reports can draw Fig. 6-style heat-maps and show how far
each method's optimum is from the grid's."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from coadapt_core.costs import CostRule, compare_designs, scenario_se
from coadapt_core.errors import UserError
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.objective import Objective
from coadapt_core.results.recorders import SqliteRecorder
from coadapt_core.results.schema import LANDSCAPE_METHOD
from coadapt_core.scenarios.seeds import scenario_seed


def landscape_designs(
    grid: int, low: Sequence[float], high: Sequence[float], nominal: Sequence[float]
) -> np.ndarray:
    """[grid*grid, dim]: rows sweep the first design variable, columns the second; the
    other variables (e.g. motor types) stay at their nominal values."""
    if grid < 2:
        raise UserError(f"--grid must be >= 2 points per axis, got {grid}", field="grid")
    nominal = np.asarray(nominal, dtype=float)
    a = np.linspace(low[0], high[0], grid)
    b = np.linspace(low[1], high[1], grid)
    aa, bb = np.meshgrid(a, b, indexing="ij")  # [grid, grid]
    designs = np.tile(nominal, (grid * grid, 1))
    designs[:, 0] = aa.ravel()
    designs[:, 1] = bb.ravel()
    return designs


def run_landscape(
    backend: CoadaptationBackend,
    objectives: Sequence[Objective],
    recorder: SqliteRecorder,
    *,
    config: dict[str, Any],
    grid: int = 11,
    low: Sequence[float] = (0.5, 0.5),
    high: Sequence[float] = (1.5, 1.5),
    nominal: Sequence[float] = (1.0, 1.0),
    agents: int = 16,
    steps: int = 500,
    seed: int = 0,
    on_row: Any = None,
    on_start: Any = None,
    rule: CostRule | None = None,
) -> dict[str, Any]:
    """Evaluate every grid design for real, one grid row (fixed first variable) per batch, each
    row committed as it finishes. Every row runs on the same scenario set (`seed`), so any two
    designs of the grid are paired (docs/coadaptation.md, "Evaluation protocol"). With
    `config["run_id"]` of an interrupted landscape, rows already stored are not evaluated
    again (their standard errors are then not known to the summary). Returns the run's
    summary, with the standard errors of the optimum's and the nominal cost, the paired
    standard error of the improvement, fall rates and each evaluated design's error bars.

    Costs follow `rule` (default: the capped rule, its reference level the nominal design's
    median scenario cost, from one evaluation of the nominal design on the same scenarios);
    the summary has the plain mean (eq. 4) and the fall rates beside them. `on_start(run_id)`
    is told the run's id once it is registered; an interrupt (Ctrl-C) marks the run
    "interrupted" (its finished rows stay) and propagates."""
    rule = rule or CostRule()
    designs = landscape_designs(grid, low, high, nominal)
    names = [o.name for o in objectives]
    cfg = {
        **config,
        "method": LANDSCAPE_METHOD,
        "objectives": names,
        "grid": grid,
        "agents": agents,
        "steps": steps,
        "seed": seed,
        "low": list(low),
        "high": list(high),
        "cost_rule": rule.rule,
        "cost_cap": rule.cap,
    }
    run_id = recorder.start_run(cfg)
    if on_start is not None:
        on_start(run_id)
    try:
        summary = _evaluate_grid(
            backend,
            objectives,
            recorder,
            run_id,
            designs,
            names,
            grid,
            agents,
            steps,
            seed,
            nominal,
            on_row,
            rule,
        )
    except BaseException as exc:
        recorder.finish(
            run_id, {"run_id": run_id, "error": f"{type(exc).__name__}: {exc}"}, "interrupted"
        )
        raise
    recorder.finish(run_id, summary)
    return summary


def _evaluate_grid(
    backend: CoadaptationBackend,
    objectives: Sequence[Objective],
    recorder: SqliteRecorder,
    run_id: str,
    designs: np.ndarray,
    names: list[str],
    grid: int,
    agents: int,
    steps: int,
    seed: int,
    nominal: Sequence[float],
    on_row: Any,
    rule: CostRule,
) -> dict[str, Any]:
    """The rows not yet stored, evaluated and recorded one by one; the run's summary."""
    store = recorder.store
    done_rows = {e.inner for e in store.evaluations(run_id, kind="real")}
    start = time.perf_counter()
    per_scenario: dict[tuple[float, ...], np.ndarray] = {}  # design -> [A, M], rows run here
    scenario_falls: dict[tuple[float, ...], np.ndarray] = {}  # design -> [A] bool
    fall_rate: dict[tuple[float, ...], float] = {}
    reference, extra_interactions = None, 0
    for row in range(grid):
        if row in done_rows and store.count_evaluations(run_id) >= (row + 1) * grid:
            continue
        batch = designs[row * grid : (row + 1) * grid]  # [grid, dim]
        # one scenario set for the whole grid: the one a run with this seed evaluates on
        fit = backend.real_fitness(
            batch, objectives, agents=agents, steps=steps, seed=scenario_seed(seed)
        )
        _keep_scenarios(fit, batch, per_scenario, scenario_falls, fall_rate)
        if (
            getattr(fit, "per_scenario", None) is not None
            and rule.needs_reference
            and reference is None
        ):
            reference, extra_interactions = _reference_level(
                backend, objectives, nominal, agents=agents, steps=steps, seed=seed, rule=rule
            )
        costs = _row_costs(fit, rule, reference).reshape(len(batch), len(names))  # [grid, M]
        _record_row(recorder, run_id, row, batch, names, costs, fit)
        if on_row is not None:
            on_row(row, grid)
    rows = store.evaluations(run_id, kind="real")
    first = names[0]
    best = min(rows, key=lambda e: e.costs[first])
    nominal_arr = np.asarray(nominal, dtype=float)
    nominal_row = min(rows, key=lambda e: float(np.abs(np.asarray(e.design) - nominal_arr).sum()))
    return {
        "run_id": run_id,
        "best_design": best.design,
        "best_cost": best.costs[first],
        "nominal_design": nominal_row.design,
        "nominal_cost": nominal_row.costs[first],
        "improvement": objectives[0].improvement(best.costs[first], nominal_row.costs[first]),
        "interactions": int(sum(e.interactions for e in rows)) + extra_interactions,
        "cost_rule": rule.rule,
        "seconds": time.perf_counter() - start,
        "grid": grid,
        "agents": agents,
        "steps": steps,
        **_uncertainty(
            rule,
            objectives,
            best.design,
            nominal_row.design,
            per_scenario,
            scenario_falls,
            fall_rate,
        ),
    }


def _record_row(
    recorder: SqliteRecorder,
    run_id: str,
    row: int,
    batch: np.ndarray,
    names: list[str],
    costs: np.ndarray,
    fit: Any,
) -> None:
    """One grid row's designs and costs [grid, M] as real evaluations (inner = the row), the
    interactions and seconds shared evenly."""
    recorder.record_evaluations(
        run_id,
        outer=0,
        inner=row,
        designs=batch.tolist(),
        costs=[dict(zip(names, c.tolist(), strict=True)) for c in costs],
        kind="real",
        interactions=[fit.interactions // len(batch)] * len(batch),
        seconds=[fit.seconds / len(batch)] * len(batch),
    )


def _row_costs(fit: Any, rule: CostRule, reference: Any) -> np.ndarray:
    """A row's costs by the run's cost rule where the backend gave per-scenario costs (and
    the rule's reference level is known), else the backend's own costs."""
    if getattr(fit, "per_scenario", None) is not None and (
        reference is not None or not rule.needs_reference
    ):
        return rule.cost(fit.per_scenario, getattr(fit, "scenario_falls", None), reference)
    return np.asarray(fit.costs, dtype=float)


def _keep_scenarios(
    fit: Any,
    batch: np.ndarray,
    per_scenario: dict[tuple[float, ...], np.ndarray],
    scenario_falls: dict[tuple[float, ...], np.ndarray],
    fall_rate: dict[tuple[float, ...], float],
) -> None:
    """Keep each design's per-scenario costs, falls and fall rate, where `fit` has them."""
    if getattr(fit, "per_scenario", None) is not None:
        for design, per in zip(batch, np.asarray(fit.per_scenario, dtype=float), strict=True):
            per_scenario[tuple(np.round(design, 9))] = per
    if getattr(fit, "fall_rate", None) is not None:
        for design, rate in zip(batch, np.asarray(fit.fall_rate, dtype=float), strict=True):
            fall_rate[tuple(np.round(design, 9))] = float(rate)
    if getattr(fit, "scenario_falls", None) is not None:
        for design, falls in zip(batch, np.asarray(fit.scenario_falls, dtype=bool), strict=True):
            scenario_falls[tuple(np.round(design, 9))] = falls


def _reference_level(
    backend: CoadaptationBackend,
    objectives: Sequence[Objective],
    nominal: Sequence[float],
    *,
    agents: int,
    steps: int,
    seed: int,
    rule: CostRule,
) -> tuple[Any, int]:
    """(the rule's reference level, the interactions it took): the nominal design on the
    grid's scenario set."""
    ref_fit = backend.real_fitness(
        np.asarray(nominal, dtype=float)[None, :],
        objectives,
        agents=agents,
        steps=steps,
        seed=scenario_seed(seed),
    )
    falls = getattr(ref_fit, "scenario_falls", None)
    reference = rule.reference(
        np.asarray(ref_fit.per_scenario)[0], None if falls is None else np.asarray(falls)[0]
    )
    return reference, int(ref_fit.interactions)


def _uncertainty(
    rule: CostRule,
    objectives: Sequence[Objective],
    best: Sequence[float],
    nominal: Sequence[float],
    per_scenario: dict[tuple[float, ...], np.ndarray],
    scenario_falls: dict[tuple[float, ...], np.ndarray],
    fall_rate: dict[tuple[float, ...], float],
) -> dict[str, Any]:
    """Standard errors (first objective) of the optimum's and the nominal cost, the paired
    standard error of the improvement, the plain mean (eq. 4) with its standard error and
    the improvement under it, fall rates with standard errors, and the grid's median relative
    error (all from the rows evaluated in this process)."""
    key_b, key_n = tuple(np.round(best, 9)), tuple(np.round(nominal, 9))
    out: dict[str, Any] = {
        "best_cost_se": None,
        "nominal_cost_se": None,
        "improvement_se": None,
        "best_fall_rate": fall_rate.get(key_b),
        "nominal_fall_rate": fall_rate.get(key_n),
        "median_relative_se": None,
    }
    if key_b in per_scenario and key_n in per_scenario:
        pair = np.stack([per_scenario[key_b], per_scenario[key_n]])  # [2, A, M]
        falls = (
            np.stack([scenario_falls[key_b], scenario_falls[key_n]])
            if key_b in scenario_falls and key_n in scenario_falls
            else None
        )
        comp = compare_designs(rule, objectives, pair, falls, 0, 1)
        first = comp["objectives"][objectives[0].name]
        finite = lambda v: float(v) if v is not None and np.isfinite(v) else None  # noqa: E731
        out.update(
            {
                "best_cost_se": first["cost_se"],
                "nominal_cost_se": first["nominal_cost_se"],
                "improvement_se": finite(first["improvement_se"]),
                "best_plain_mean": first["plain_mean"],
                "best_plain_mean_se": first["plain_mean_se"],
                "nominal_plain_mean": first["nominal_plain_mean"],
                "nominal_plain_mean_se": first["nominal_plain_mean_se"],
                "improvement_plain": first["improvement_plain"],
                "improvement_plain_se": finite(first["improvement_plain_se"]),
            }
        )
        if comp.get("fall_rate") is not None:
            out.update(
                {
                    "best_fall_rate_se": finite(comp["fall_rate_se"]),
                    "nominal_fall_rate_se": finite(comp["reference_fall_rate_se"]),
                    "fall_rate_difference": comp["fall_rate_difference"],
                    "fall_rate_difference_se": finite(comp["fall_rate_difference_se"]),
                }
            )
    if per_scenario:
        per = np.stack(list(per_scenario.values()))  # [D, A, M]
        keys = list(per_scenario)
        falls = (
            np.stack([scenario_falls[k] for k in keys])
            if all(k in scenario_falls for k in keys)
            else None
        )
        ref = None
        if rule.needs_reference and key_n in per_scenario:
            ref = rule.reference(per_scenario[key_n], scenario_falls.get(key_n))
        if ref is not None or not rule.needs_reference:
            values = rule.scenario_values(per, falls, ref)
            rel = scenario_se(values, rule.aggregate)[:, 0] / np.abs(rule.aggregate(values)[:, 0])
            out["median_relative_se"] = (
                float(np.median(rel[np.isfinite(rel)])) if np.isfinite(rel).any() else None
            )
    return out
