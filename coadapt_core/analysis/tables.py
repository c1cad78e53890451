"""The report's tables: the paper's Table 6 (best design, improvement, sim-to-sim
improvement per objective x method x terrain) and Table 7 (interactions and wall clock per
method), as rows, Markdown and CSV, with the orders and statistics they share."""

from __future__ import annotations

import csv
import itertools
import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import (
    METHOD_LABELS,
    TERRAIN_ORDER,
    RunFacts,
    as_float,
    objective_labels,
    objective_order,
)
from coadapt_core.analysis.measures import as_cost_reduction, differs, objective_named
from coadapt_core.methods import METHOD_NAMES
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


def _mean(values: Sequence[float | None]) -> float | None:
    return _stat(values)[0]


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
        if not group:
            continue
        robot, simulator, preset = setting
        row: dict[str, Any] = {
            "robot": robot,
            "simulator": simulator,
            "preset": preset,
            "objective": o,
            "method": m,
            "optimizer": opt,
            "terrain": t,
            "runs": len(group),
            "seeds": " ".join(str(f.run.get("seed")) for f in group),
            "policy": "; ".join(sorted({f.policy for f in group})),
        }
        names = group[0].design_names
        for i, name in enumerate(names):
            values = [
                f.best_design[i] if f.best_design and len(f.best_design) > i else None
                for f in group
            ]
            _add_stat(row, name, values)
            # a choice (a motor type): what each seed chose, not only its mean
            if i < len(group[0].design_discrete) and group[0].design_discrete[i]:
                row[f"{name}_choices"] = " ".join(
                    "n/a" if v is None else str(round(float(v))) for v in values
                )
        _add_stat(
            row,
            "best_cost",
            [f.best_cost for f in group],
            [as_float(f.summary.get("best_cost_se")) for f in group],
        )
        _add_stat(
            row,
            "nominal_cost",
            [f.nominal_cost for f in group],
            [as_float(f.summary.get("nominal_cost_se")) for f in group],
        )
        _add_stat(
            row,
            "improvement",
            [f.improvement for f in group],
            [as_float(f.summary.get("improvement_se")) for f in group],
        )
        # the paper's plain mean (eq. 4) and the fall rates beside the run's cost rule
        _add_stat(
            row,
            "improvement_plain",
            [as_float(f.summary.get("improvement_plain")) for f in group],
            [as_float(f.summary.get("improvement_plain_se")) for f in group],
        )
        _add_stat(
            row,
            "best_fall_rate",
            [as_float(f.summary.get("best_fall_rate")) for f in group],
            [as_float(f.summary.get("best_fall_rate_se")) for f in group],
        )
        _add_stat(
            row,
            "nominal_fall_rate",
            [as_float(f.summary.get("nominal_fall_rate")) for f in group],
            [as_float(f.summary.get("nominal_fall_rate_se")) for f in group],
        )
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
        _add_reductions(row, group)
        row["sim2sim_note"] = "; ".join(sorted({f.sim2sim_note for f in group if f.sim2sim_note}))
        row["design_variables"] = " ".join(names)
        row["design_units"] = "|".join(group[0].design_units)
        row["design_discrete"] = " ".join(str(int(d)) for d in group[0].design_discrete)
        row["run_ids"] = " ".join(f.run["id"] for f in group)
        # the walking gate (coadapt_core/coadapt/reliability.py): runs whose policy did not walk
        bad = [f for f in group if f.summary.get("reliable") is False]
        row["unreliable_runs"] = len(bad)
        row["reliability"] = "; ".join(sorted({str(f.summary.get("reliability")) for f in bad}))
        rows.append(row)
    return rows


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


#: what the tables say about how runs are grouped into rows
POOLING_NOTE = (
    "Runs of different robots, simulators or presets are never averaged together: each combination "
    "is a row of its own (Robot, Simulator, Preset columns)."
)

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


def _fmt(value: float | None, spec: str = ".2f", pct: bool = False) -> str:
    if value is None:
        return "n/a"
    return f"{100 * value:.1f}%" if pct else format(value, spec)


def cell(
    row: dict[str, Any], name: str, *, spec: str = ".3g", pct: bool = False, scale: float = 1.0
) -> str:
    """'mean ± std (n=k)' of an aggregated column; one run: 'value ± se SE (n=1)' when the
    run recorded a standard error, else 'value (n=1)'."""
    mean, std, n = row.get(name), row.get(f"{name}_std"), row.get(f"{name}_n", 0)
    if mean is None or not n:
        return "n/a"

    def fmt(v: float) -> str:
        return f"{100 * v / scale:.1f}%" if pct else format(v / scale, spec)

    if std is not None:
        return f"{fmt(mean)} ± {fmt(std)} (n={n})"
    se = row.get(f"{name}_se")
    if se is not None:
        return f"{fmt(mean)} ± {fmt(se)} SE (n={n})"
    return f"{fmt(mean)} (n={n})"


def design_header(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def design_cell(row: dict[str, Any], name: str, discrete: bool) -> str:
    if row.get(f"{name}_n", 0) == 1 and discrete and row.get(name) is not None:
        return f"{row[name]:.0f} (n=1)"  # a motor type is an integer
    return cell(row, name, spec=".3f")


def design_columns(rows: Sequence[dict[str, Any]]) -> list[tuple[str, str, bool]]:
    """(name, unit, discrete) of every design variable the rows name, in first-seen order."""
    out: list[tuple[str, str, bool]] = []
    for r in rows:
        names = r["design_variables"].split()
        units = r["design_units"].split("|") if r["design_units"] else [""] * len(names)
        flags = [d == "1" for d in r["design_discrete"].split()] or [False] * len(names)
        for n, u, d in zip(
            names, units + [""] * len(names), flags + [False] * len(names), strict=False
        ):
            if n not in [c[0] for c in out]:
                out.append((n, u, d))
    return out


def unreliable_mark(row: dict[str, Any]) -> str:
    """' UNRELIABLE (k of n runs: the policy does not walk)' for a row with runs below the
    walking gate, else ''."""
    k = int(row.get("unreliable_runs") or 0)
    return f" UNRELIABLE ({k} of {row['runs']} runs: the policy does not walk)" if k else ""


def common_cell(r: dict[str, Any]) -> str:
    """The common-yardstick figures of a Table 6 row, or 'n/a' when no run has them."""
    if not r.get("common_improvement_n"):
        return "n/a"
    return " / ".join(
        cell(r, name, pct=True)
        for name in (
            "common_improvement",
            "common_improvement_plain",
            "common_fall_rate_difference",
        )
    )


def reduction_cell(r: dict[str, Any]) -> str:
    """The row's improvements as cost reductions 1 - c / c0 (run's cost / plain mean / common
    scenarios / common plain mean), or 'same' when the objective's own measure is that already."""
    if not r.get("reduction_differs"):
        return "same"
    return " / ".join(cell(r, name, pct=True) for name, _ in REDUCTIONS[:4])


def table6_markdown(rows: Sequence[dict[str, Any]]) -> str:
    design = design_columns(rows)
    head = (
        ["Robot", "Simulator", "Preset", "Objective", "Method", "Optimizer", "Terrain", "Runs"]
        + [design_header(n, u) for n, u, _ in design]
        + [
            "Best cost",
            "Nominal cost",
            "Improvement",
            "Improvement (plain mean)",
            "Fall rate best / nominal",
            "Common scenarios: improvement / plain mean / fall-rate difference",
            "Paper's measure 1 - c/c0 where it differs: run's cost / plain mean / common / common plain mean",
            "Sim-to-sim improvement",
            "Sim-to-sim note",
            "Starting policy",
        ]
    )
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    labels = objective_labels()
    for r in rows:
        cells = [
            r["robot"],
            r["simulator"],
            r["preset"],
            labels.get(r["objective"], r["objective"]),
            METHOD_LABELS.get(r["method"], r["method"]),
            r["optimizer"],
            r["terrain"],
            str(r["runs"]),
        ]
        cells += [design_cell(r, n, d) if f"{n}_n" in r else "" for n, _, d in design]
        cells += [
            cell(r, "best_cost", spec=".5g"),
            cell(r, "nominal_cost", spec=".5g"),
            cell(r, "improvement", pct=True) + unreliable_mark(r),
            cell(r, "improvement_plain", pct=True),
            cell(r, "best_fall_rate", pct=True) + " / " + cell(r, "nominal_fall_rate", pct=True),
            common_cell(r),
            reduction_cell(r),
            cell(r, "sim2sim_improvement", pct=True),
            r["sim2sim_note"] or "",
            r.get("policy") or "?",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        POOLING_NOTE
        + " Each number: mean ± sample standard deviation over the runs (seeds) of the row, "
        "and how many runs had it (n); one run shows its own standard error (SE) when it recorded one. "
        "Improvement: lower cost than the nominal design, in the objective's own measure (in percent of the "
        "nominal cost, 1 - c/c0; an objective may define it otherwise: command tracking reports the reduction "
        "of its RMS error, 1 - √(c/c0), about half the cost reduction, and the column 'Paper's measure' "
        "restates it as 1 - c/c0, each run's SE carried by the delta method), under the run's cost "
        "rule (column `cost_rule` of table6.csv; docs/coadaptation.md) and under the paper's plain mean over "
        "the same scenarios; fall rate: share of the final check's scenarios in which the robot fell. Common "
        "scenarios: the run's best and nominal designs re-evaluated with the run's own policy on one scenario "
        "set shared by every run of the terrain and preset (the methods' common yardstick; fall-rate "
        "difference in points, paired). Starting "
        "policy: the policy file each run started from and the start of its SHA-256.",
    ]
    return "\n".join(lines) + "\n"


def table7_units(rows: Sequence[dict[str, Any]]) -> tuple[float, str, float, str]:
    """Interaction and time units: the paper's millions and hours, smaller ones when a
    table of smoke runs would print only zeros."""
    most_inter = max(
        ((r["interactions_training"] or 0) + (r["interactions_evaluation"] or 0) for r in rows),
        default=0,
    )
    most_sec = max(
        ((r["seconds_training"] or 0) + (r["seconds_evaluation"] or 0) for r in rows), default=0
    )
    inter = (1e6, "million") if most_inter >= 1e5 else (1e3, "thousand")
    time_unit = (
        (3600.0, "hour")
        if most_sec >= 360
        else (60.0, "minute")
        if most_sec >= 6
        else (1.0, "second")
    )
    return inter[0], inter[1], time_unit[0], time_unit[1]


def _sum_cell(r: dict[str, Any], a: str, b: str, unit: float, spec: str = ".3g") -> str:
    """'total ± std (a+b)': the paper's Training+Evaluation layout with the spread of the total."""
    ta, tb = (r[a] or 0.0) / unit, (r[b] or 0.0) / unit
    sa, sb = r.get(f"{a}_std"), r.get(f"{b}_std")
    spread = "" if sa is None or sb is None else f" ± {format(math.hypot(sa, sb) / unit, spec)}"
    return f"{format(ta + tb, spec)}{spread} ({format(ta, spec)}+{format(tb, spec)})"


def table7_markdown(rows: Sequence[dict[str, Any]]) -> str:
    iu, iname, tu, tname = table7_units(rows)
    lines = [
        f"| Robot | Simulator | Preset | Method | Optimizer | Runs | Interactions ({iname}, Training+Evaluation) | "
        f"Wall clock time ({tname}, Training+Evaluation) | Designs evaluated (real+surrogate) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['robot']} | {r['simulator']} | {r['preset']} | "
            f"{METHOD_LABELS.get(r['method'], r['method'])} | {r['optimizer']} | {r['runs']} | "
            f"{_sum_cell(r, 'interactions_training', 'interactions_evaluation', iu)} | "
            f"{_sum_cell(r, 'seconds_training', 'seconds_evaluation', tu)} | "
            f"{_sum_cell(r, 'designs_real', 'designs_surrogate', 1.0, '.0f')} |"
        )
    lines += [
        "",
        POOLING_NOTE
        + " Means over the runs of each row (± sample standard deviation of the total when "
        "a row has two or more runs).",
    ]
    return "\n".join(lines) + "\n"


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    columns: list[str] = []
    for r in rows:
        columns.extend(k for k in r if k not in columns)
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        for r in rows:
            writer.writerow(
                {
                    k: ("" if v is None else repr(v) if isinstance(v, float) else v)
                    for k, v in r.items()
                }
            )
