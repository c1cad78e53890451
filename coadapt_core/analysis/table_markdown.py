"""The report's tables as Markdown and CSV: Table 6's and Table 7's rows (`tables`) as cells
of 'mean ± std (n=k)', with their headers and the notes that say how to read them."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.facts import METHOD_LABELS, objective_labels
from coadapt_core.analysis.tables import REDUCTIONS

#: what the tables say about how runs are grouped into rows
POOLING_NOTE = (
    "Runs of different robots, simulators or presets are never averaged together: each combination "
    "is a row of its own (Robot, Simulator, Preset columns)."
)


def cell(
    row: dict[str, Any],
    name: str,
    *,
    spec: str = ".3g",
    pct: bool = False,
    scale: float = 1.0,
    points: bool = False,
) -> str:
    """'mean ± std (n=k)' of an aggregated column; one run: 'value ± se SE (n=1)' when the
    run recorded a standard error, else 'value (n=1)'. `points`: a difference of two rates in
    percentage points, signed ('+0.8 ± 0.8 points (n=3)'), as `coadapt run` says it."""
    mean, std, n = row.get(name), row.get(f"{name}_std"), row.get(f"{name}_n", 0)
    if mean is None or not n:
        return "n/a"

    def fmt(v: float) -> str:
        return f"{100 * v / scale:.1f}%" if pct else format(v / scale, spec)

    if points:
        spread = std if std is not None else row.get(f"{name}_se")
        text = f"{100 * mean:+.1f}" + ("" if spread is None else f" ± {100 * spread:.1f}")
        kind = " SE" if std is None and spread is not None else ""
        return f"{text} points{kind} (n={n})"
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
        [
            cell(r, "common_improvement", pct=True),
            cell(r, "common_improvement_plain", pct=True),
            cell(r, "common_fall_rate_difference", points=True),
        ]
    )


def specialist_cell(r: dict[str, Any]) -> str:
    """`coadapt verify`'s figures of a Table 6 row: the improvement with specialists, the
    universal policy's on the same scenarios and the verdicts; 'n/a' when no run has them."""
    if not r.get("specialist_improvement_n"):
        return "n/a"
    return (
        f"{cell(r, 'specialist_improvement', pct=True)} (universal "
        f"{cell(r, 'universal_improvement', pct=True)}): {r.get('verdicts') or ''}"
    )


def reduction_cell(r: dict[str, Any]) -> str:
    """The row's improvements as cost reductions 1 - c / c0 (run's cost / plain mean / common
    scenarios / common plain mean), or 'same' when the objective's own measure is that already."""
    if not r.get("reduction_differs"):
        return "same"
    return " / ".join(cell(r, name, pct=True) for name, _ in REDUCTIONS[:4])


def result_cells(r: dict[str, Any], design: Sequence[tuple]) -> list[str]:
    """A Table 6 row's design columns, costs, improvements and fall rates as text (the
    report's Markdown and the dashboard's grid page)."""
    cells = [design_cell(r, n, d) if f"{n}_n" in r else "" for n, _, d in design]
    return [
        *cells,
        cell(r, "best_cost", spec=".5g"),
        cell(r, "nominal_cost", spec=".5g"),
        cell(r, "improvement", pct=True) + unreliable_mark(r),
        cell(r, "improvement_plain", pct=True),
        cell(r, "best_fall_rate", pct=True) + " / " + cell(r, "nominal_fall_rate", pct=True),
    ]


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
            "Paper's measure 1 - c/c0 where it differs: run's cost / plain mean / common / common "
            "plain mean",
            "Sim-to-sim improvement",
            "Sim-to-sim note",
            "With specialists (universal): verdict",
            "Starting policy",
            "Numerics",
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
        cells += result_cells(r, design)
        cells += [
            common_cell(r),
            reduction_cell(r),
            cell(r, "sim2sim_improvement", pct=True),
            r["sim2sim_note"] or "",
            specialist_cell(r),
            r.get("policy") or "?",
            r.get("numerics") or "not recorded",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        POOLING_NOTE
        + " Each number: mean ± sample standard deviation over the runs (seeds) of the row, and "
        "how many runs had it (n); one run shows its own standard error (SE) when it recorded "
        "one. Improvement: lower cost than the nominal design, in the objective's own measure "
        "(in percent of the nominal cost, 1 - c/c0; an objective may define it otherwise: "
        "command tracking reports the reduction of its RMS error, 1 - √(c/c0), about half the "
        "cost reduction, and the column 'Paper's measure' restates it as 1 - c/c0, each run's "
        "SE carried by the delta method), under the run's cost rule (column `cost_rule` of "
        "table6.csv; docs/coadaptation.md) and under the paper's plain mean over the same "
        "scenarios; fall rate: share of the final check's scenarios in which the robot fell. "
        "Common scenarios: the run's best and nominal designs re-evaluated with the run's own "
        "policy on one scenario set shared by every run of the terrain and preset (the methods' "
        "common yardstick; fall-rate difference in points, paired). With specialists: "
        "`coadapt verify`'s improvement with a policy fine-tuned at each design from the run's "
        "universal one, the universal policy's on the same scenarios in brackets, and each "
        "run's verdict. Starting policy: the policy file each run started from and the start "
        "of its SHA-256. Numerics: the learner's precision in force (bf16 or float32), the "
        "device it ran on, torch's and the physics engine's versions; another CPU's answer may "
        "move within the SEs (README).",
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
        f"| Robot | Simulator | Preset | Method | Optimizer | Runs | Interactions ({iname}, "
        f"Training+Evaluation) | Wall clock time ({tname}, Training+Evaluation) | Designs "
        "evaluated (real+surrogate) |",
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
