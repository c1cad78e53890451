"""The report's tables: the paper's Table 6 (best design, improvement, sim-to-sim
improvement per objective x method x terrain) and Table 7 (interactions and wall clock per
method) as rows, with the orders and statistics they share; `table_markdown` writes them as
Markdown and CSV."""

from __future__ import annotations

import itertools
import math
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import (
    METHOD_LABELS,
    TERRAIN_ORDER,
    RunFacts,
    as_float,
    objective_order,
)
from coadapt_core.analysis.measures import as_cost_reduction, differs, objective_named
from coadapt_core.methods import METHOD_NAMES
from coadapt_core.numerics import numerics_cell
from coadapt_core.results.schema import LANDSCAPE_METHOD


def ordered(values: Sequence[str], order: Sequence[str]) -> list[str]:
    known = [v for v in order if v in values]
    return known + sorted(v for v in set(values) if v not in order)


def optimizer_order() -> tuple[str, ...]:
    """Installed optimizers in the order of every table, legend and figure: the default one
    first (highest `default_rank`), then by name; one not installed here sorts after them."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    return tuple(
        sorted(
            registry.names("optimizer"),
            key=lambda n: (-int(getattr(registry.get("optimizer", n), "default_rank", 0)), n),
        )
    )


def group_order(keys: Sequence[tuple[str, str]]) -> list[tuple[str, str]]:
    """(method, optimizer) keys in the paper's method order, then optimizer order: the same
    order in every table, legend and figure."""
    order = optimizer_order()

    def rank(key: tuple[str, str]) -> tuple[int, str, int, str]:
        m, o = key
        mi = METHOD_NAMES.index(m) if m in METHOD_NAMES else len(METHOD_NAMES)
        oi = order.index(o) if o in order else len(order)
        return (mi, m, oi, o)

    return sorted(set(keys), key=rank)


def _stat(values: Sequence[float | None]) -> tuple[float | None, float | None, int]:
    """(mean, sample std or None for one value, n) over the values that exist."""
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if not vals:
        return None, None, 0
    return float(np.mean(vals)), (float(np.std(vals, ddof=1)) if len(vals) > 1 else None), len(vals)


def _se_of_mean(values: Sequence[float | None]) -> float | None:
    """Standard error of the mean of independent estimates with these standard errors (all
    of them recorded, else None)."""
    if not values or any(v is None for v in values):
        return None
    return float(math.sqrt(sum(float(v) ** 2 for v in values)) / len(values))


def _add_stat(
    row: dict[str, Any],
    name: str,
    values: Sequence[float | None],
    se: Sequence[float | None] | None = None,
) -> None:
    mean, std, n = _stat(values)
    row[name], row[f"{name}_std"], row[f"{name}_n"] = mean, std, n
    if se is not None:
        row[f"{name}_se"] = _se_of_mean(se)


def table6_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per robot x simulator x preset x objective x method x optimizer x terrain:
    mean, sample standard deviation over seeds and count of every number (`<col>`,
    `<col>_std`, `<col>_n`); the design columns are named after the run's design space. Runs
    of different robots, simulators or presets are never averaged into one row."""
    groups: dict[tuple[tuple[str, str, str], str, str, str, str], list[RunFacts]] = defaultdict(
        list
    )
    for f in facts:
        if f.method != LANDSCAPE_METHOD:
            groups[(f.setting, f.objective, f.method, f.optimizer, f.terrain)].append(f)
    rows = []
    settings = sorted({k[0] for k in groups})
    objectives = ordered([k[1] for k in groups], objective_order())
    pairs = group_order([(k[2], k[3]) for k in groups])
    terrains = ordered([k[4] for k in groups], TERRAIN_ORDER)
    for setting, o, (m, opt), t in itertools.product(settings, objectives, pairs, terrains):
        group = groups.get((setting, o, m, opt, t))
        if group:
            rows.append(_table6_row(group))
    return rows


def _table6_row(group: Sequence[RunFacts]) -> dict[str, Any]:
    """The Table 6 row of one group of runs (one cell, its seeds); the columns in the order
    table6.csv lists them."""
    first = group[0]
    robot, simulator, preset = first.setting
    row: dict[str, Any] = {
        "robot": robot,
        "simulator": simulator,
        "preset": preset,
        "objective": first.objective,
        "method": first.method,
        "optimizer": first.optimizer,
        "terrain": first.terrain,
        "runs": len(group),
        "seeds": " ".join(str(f.run.get("seed")) for f in group),
        "policy": "; ".join(sorted({f.policy for f in group})),
        # which numerics trained and evaluated each run (coadapt_core.numerics)
        "numerics": "; ".join(sorted({numerics_cell(f.summary.get("numerics")) for f in group})),
    }
    _add_design(row, group)
    _add_outcomes(row, group)
    _add_reductions(row, group)
    row["sim2sim_note"] = "; ".join(sorted({f.sim2sim_note for f in group if f.sim2sim_note}))
    _add_verified(row, group)
    row["design_variables"] = " ".join(first.design_names)
    row["design_units"] = "|".join(first.design_units)
    row["design_discrete"] = " ".join(str(int(d)) for d in first.design_discrete)
    row["run_ids"] = " ".join(f.run["id"] for f in group)
    # the walking gate (coadapt_core/coadapt/reliability.py): runs whose policy did not walk
    bad = [f for f in group if f.summary.get("reliable") is False]
    row["unreliable_runs"] = len(bad)
    row["reliability"] = "; ".join(sorted({str(f.summary.get("reliability")) for f in bad}))
    return row


def _add_design(row: dict[str, Any], group: Sequence[RunFacts]) -> None:
    """The best design's variables over the runs, named as the first run's design space."""
    first = group[0]
    for i, name in enumerate(first.design_names):
        values = [
            f.best_design[i] if f.best_design and len(f.best_design) > i else None for f in group
        ]
        _add_stat(row, name, values)
        # a choice (a motor type): what each seed chose, not only its mean
        if i < len(first.design_discrete) and first.design_discrete[i]:
            row[f"{name}_choices"] = " ".join(
                "n/a" if v is None else str(round(float(v))) for v in values
            )


def _add_outcomes(row: dict[str, Any], group: Sequence[RunFacts]) -> None:
    """What the runs' final checks measured: costs, improvements under the run's cost rule and
    the paper's plain mean (eq. 4), fall rates, sim-to-sim and the common yardstick."""

    def summary(key: str) -> list[float | None]:
        return [as_float(f.summary.get(key)) for f in group]

    _add_stat(row, "best_cost", [f.best_cost for f in group], summary("best_cost_se"))
    _add_stat(row, "nominal_cost", [f.nominal_cost for f in group], summary("nominal_cost_se"))
    _add_stat(row, "improvement", [f.improvement for f in group], summary("improvement_se"))
    for name in ("improvement_plain", "best_fall_rate", "nominal_fall_rate"):
        _add_stat(row, name, summary(name), summary(f"{name}_se"))
    row["cost_rule"] = " ".join(
        sorted({str(f.summary.get("cost_rule") or "trimmed") for f in group})
    )
    _add_stat(row, "sim2sim_improvement", [f.sim2sim for f in group])
    for name, key in (
        ("common_improvement", "improvement"),
        ("common_improvement_plain", "improvement_plain"),
        ("common_fall_rate_difference", "fall_rate_difference"),
    ):
        _add_stat(
            row,
            name,
            [(f.common or {}).get(key) for f in group],
            [(f.common or {}).get(f"{key}_se") for f in group],
        )


def _add_verified(row: dict[str, Any], group: Sequence[RunFacts]) -> None:
    """`coadapt verify`'s figures of the runs that have them: the improvement with specialists
    and the universal policy's on the same scenarios, each with its SE, their difference and
    each run's verdict."""
    rows = [f.verified or {} for f in group]
    for name in ("specialist_improvement", "universal_improvement", "difference"):
        _add_stat(row, name, [r.get(name) for r in rows], [r.get(f"{name}_se") for r in rows])
    row["verdicts"] = "; ".join(str(r["verdict"]) for r in rows if r.get("verdict"))
    row["specialist_budget"] = " ".join(str(r["budget"]) for r in rows if r.get("budget"))


#: (column of the paper's measure, the improvement it restates): every improvement of a row as
#: the cost reduction 1 - c / c0 (coadapt_core.analysis.measures)
REDUCTIONS = (
    ("reduction", "improvement"),
    ("reduction_plain", "improvement_plain"),
    ("common_reduction", "common_improvement"),
    ("common_reduction_plain", "common_improvement_plain"),
    ("sim2sim_reduction", "sim2sim_improvement"),
)


def _own_improvements(f: RunFacts) -> dict[str, tuple[float | None, float | None]]:
    """One run's improvements in the objective's own measure, each with its SE (or None)."""
    s, common = f.summary, f.common or {}
    return {
        "improvement": (f.improvement, as_float(s.get("improvement_se"))),
        "improvement_plain": (
            as_float(s.get("improvement_plain")),
            as_float(s.get("improvement_plain_se")),
        ),
        "common_improvement": (common.get("improvement"), common.get("improvement_se")),
        "common_improvement_plain": (
            common.get("improvement_plain"),
            common.get("improvement_plain_se"),
        ),
        "sim2sim_improvement": (f.sim2sim, None),
    }


def _add_reductions(row: dict[str, Any], group: Sequence[RunFacts]) -> None:
    """The row's improvements as cost reductions 1 - c / c0 (the paper's measure): each run's
    restated with its SE (delta method), then mean and spread over the runs as any column;
    `reduction_differs` says whether the objective's own measure is another one."""
    objective = objective_named(group[0].objective)
    per_run = [_own_improvements(f) for f in group]
    for name, own in REDUCTIONS:
        pairs = [as_cost_reduction(objective, *r[own]) for r in per_run]
        _add_stat(
            row,
            name,
            [v for v, _ in pairs],
            None if own == "sim2sim_improvement" else [se for _, se in pairs],
        )
    row["reduction_differs"] = differs(objective)


T7_NUMBERS = (
    "interactions_training",
    "interactions_evaluation",
    "seconds_training",
    "seconds_evaluation",
    "designs_real",
    "designs_surrogate",
)


def table7_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per robot x simulator x preset x method x optimizer: mean, std and count over
    its runs (the paper reports averages); a pso and a mixed-pso run of one method are two
    rows, as in Table 6, and so are runs of different robots, simulators or presets."""
    groups: dict[tuple[tuple[str, str, str], str, str], list[RunFacts]] = defaultdict(list)
    for f in facts:
        if f.method != LANDSCAPE_METHOD:
            groups[(f.setting, f.method, f.optimizer)].append(f)
    rows = []
    keys = [
        (setting, m, opt)
        for setting in sorted({k[0] for k in groups})
        for m, opt in group_order([(k[1], k[2]) for k in groups if k[0] == setting])
    ]
    for setting, m, opt in keys:
        g = groups[(setting, m, opt)]
        row: dict[str, Any] = {
            "robot": setting[0],
            "simulator": setting[1],
            "preset": setting[2],
            "method": m,
            "optimizer": opt,
            "runs": len(g),
        }
        values = {
            "interactions_training": [f.train_interactions for f in g],
            "interactions_evaluation": [f.eval_interactions for f in g],
            "seconds_training": [f.train_seconds for f in g],
            "seconds_evaluation": [f.eval_seconds for f in g],
            "designs_real": [f.designs_real for f in g],
            "designs_surrogate": [f.designs_surrogate for f in g],
        }
        for name in T7_NUMBERS:
            _add_stat(row, name, values[name])
        row["run_ids"] = " ".join(f.run["id"] for f in g)
        rows.append(row)
    return rows


def method_label(method: str, optimizer: str | None = None) -> str:
    return METHOD_LABELS.get(method, method) + (f" [{optimizer}]" if optimizer else "")
