"""Our figures beside the paper's (Du et al. 2025, Tables 6, 7 and 9; the data is
`coadapt_core.analysis.paper`), with a verdict per cell. `coadapt report` writes them as
paper_comparison.md, paper_table6.csv, paper_order.csv, paper_table7.csv, paper_table9.csv
and a section of report.html.

Verdicts (docs/reproduction.md restates them):

- design direction: each of thigh and shank is longer than nominal (scale above
  1 + `NOMINAL_BAND`), shorter (below 1 - `NOMINAL_BAND`) or at nominal; a cell *agrees* when
  every variable has the paper's direction, *disagrees* when one is longer where the paper's
  is shorter or the other way round, and is *undecided* when the only differences involve a
  value at nominal.
- improvement: *within* when the paper's figure lies within 2 standard errors of our mean
  (SE over seeds: sample standard deviation / sqrt(n); one run: the SE its final check
  recorded), widened by the paper's rounding (0.05 percentage points); else *above* or
  *below* the paper's. Checked for the improvement under the run's cost rule, under the plain
  mean (the paper's eq. 4, where the runs recorded it) and sim-to-sim.
- method order, per objective and terrain: the pairs of methods both tables hold, ordered by
  improvement; a pair the paper ties is not counted; a reversed pair is *clear* when our two
  means differ by more than 2 combined SE.
- Table 7: each method's interactions and wall clock as a ratio to the paper's method in the
  same table (the paper's hardware and scale differ from ours; ratios compare), paired per
  cell: each run against the paper's method's run of the same objective, terrain and seed,
  mean ± SE over the pairs; the verdict says whether it costs more or less than the paper's
  method, as in the paper, or is within 2 SE of equal.
"""

from __future__ import annotations

import csv
import html
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.paper import PaperTables, paper_tables
from coadapt_core.analysis.paper_cost import Z, table7_comparison
from coadapt_core.analysis.paper_figure import figure_beside_paper
from coadapt_core.analysis.tables import REDUCTIONS
from coadapt_core.methods import METHODS

#: a design scale within this of 1.0 is "at nominal" (the paper prints two decimals: 0.98-1.02)
NOMINAL_BAND = 0.025
#: half the paper's last printed digit of a percentage (5.8 %: 5.75-5.85 %)
PAPER_ROUNDING = 0.0005

#: the common yardstick (coadapt_core.experiments.yardstick): every run's best design and its
#: nominal design with the run's own policy on one common scenario set, under the run's rule
#: and the plain mean, with the paired fall-rate difference
COMMON_COLUMNS = (
    "common_improvement",
    "common_improvement_se",
    "common_improvement_verdict",
    "common_improvement_plain",
    "common_improvement_plain_se",
    "common_improvement_plain_verdict",
    "common_fall_rate_difference",
    "common_fall_rate_difference_se",
)
#: the objective's own measure beside the paper's (1 - c / c0), where the two differ (tracking)
OWN_COLUMNS = (
    "measure_differs",
    "improvement_own",
    "improvement_own_se",
    "improvement_plain_own",
    "improvement_plain_own_se",
    "common_improvement_own",
    "common_improvement_own_se",
    "common_improvement_plain_own",
    "common_improvement_plain_own_se",
)
T6_COLUMNS = (
    "objective",
    "method",
    "optimizer",
    "terrain",
    "runs",
    "seeds",
    "thigh",
    "thigh_se",
    "paper_thigh",
    "shank",
    "shank_se",
    "paper_shank",
    "direction",
    "improvement",
    "improvement_se",
    "paper_improvement",
    "improvement_verdict",
    "improvement_plain",
    "improvement_plain_se",
    "improvement_plain_verdict",
    *COMMON_COLUMNS,
    "sim2sim_improvement",
    "sim2sim_improvement_se",
    "paper_sim2sim_improvement",
    "sim2sim_verdict",
    *OWN_COLUMNS,
    "sim2sim_improvement_own",
)
ORDER_COLUMNS = (
    "objective",
    "terrain",
    "measure",
    "methods",
    "paper_order",
    "our_order",
    "pairs",
    "reversed",
    "clear_reversals",
    "verdict",
)
T7_COLUMNS = (
    "method",
    "optimizer",
    "runs",
    "pairs",
    "interactions_training",
    "interactions_evaluation",
    "seconds_training",
    "seconds_evaluation",
    "interactions_ratio",
    "interactions_ratio_se",
    "paper_interactions_ratio",
    "interactions_verdict",
    "evaluation_ratio",
    "evaluation_ratio_se",
    "paper_evaluation_ratio",
    "time_pairs",
    "time_ratio",
    "time_ratio_se",
    "paper_time_ratio",
    "time_verdict",
    "speed_time_ratio",
    "speed_time_ratio_se",
    "speed_time_verdict",
    "paper_interactions_training",
    "paper_interactions_evaluation",
    "paper_hours_training",
    "paper_hours_evaluation",
)
T9_COLUMNS = (
    "objective",
    "method",
    "optimizer",
    "terrain",
    "runs",
    "seeds",
    "thigh",
    "thigh_se",
    "paper_thigh",
    "shank",
    "shank_se",
    "paper_shank",
    "direction",
    "hip_motor",
    "paper_hip_motor",
    "hip_motor_verdict",
    "knee_motor",
    "paper_knee_motor",
    "knee_motor_verdict",
    "improvement",
    "improvement_se",
    "paper_improvement",
    "improvement_verdict",
    "improvement_plain",
    "improvement_plain_se",
    "improvement_plain_verdict",
    *COMMON_COLUMNS,
    *OWN_COLUMNS,
)


# -- numbers ------------------------------------------------------------------------------------
def se_of(row: dict[str, Any], name: str) -> float | None:
    """Standard error of a table6 row's mean `name`: std / sqrt(n) over seeds; one run: the
    SE it recorded (`<name>_se`), else None."""
    n = int(row.get(f"{name}_n") or 0)
    std = row.get(f"{name}_std")
    if n >= 2 and std is not None:
        return float(std) / math.sqrt(n)
    if n == 1 and row.get(f"{name}_se") is not None:
        return float(row[f"{name}_se"])
    return None


def direction(scale: float | None) -> str | None:
    """'longer', 'shorter' or 'nominal' (within `NOMINAL_BAND` of 1.0); None when unknown."""
    if scale is None or not math.isfinite(scale):
        return None
    if scale > 1.0 + NOMINAL_BAND:
        return "longer"
    if scale < 1.0 - NOMINAL_BAND:
        return "shorter"
    return "nominal"


def direction_verdict(ours: dict[str, float | None], paper: dict[str, float]) -> str:
    """'agrees', 'disagrees (thigh)' (the variables whose direction is the opposite of the
    paper's), 'undecided (shank at nominal)' or 'n/a'."""
    opposite, undecided = [], []
    for name, value in paper.items():
        a, b = direction(ours.get(name)), direction(value)
        if a is None:
            return "n/a"
        if a != b:
            (undecided if "nominal" in (a, b) else opposite).append(name)
    if opposite:
        return f"disagrees ({', '.join(opposite)})"
    if undecided:
        return f"undecided ({', '.join(undecided)} at nominal)"
    return "agrees"


def value_verdict(mean: float | None, se: float | None, paper: float | None) -> str:
    """'within' (the paper's figure within Z SE of our mean, plus its rounding), 'above' or
    'below' (ours against the paper's), 'above (no SE)' when our spread is unknown, 'n/a'."""
    if mean is None or paper is None:
        return "n/a"
    diff = mean - paper
    if se is None:
        return (
            ("above" if diff > 0 else "below") + " (no SE)"
            if abs(diff) > PAPER_ROUNDING
            else "within (no SE)"
        )
    if abs(diff) <= Z * se + PAPER_ROUNDING:
        return "within"
    return "above" if diff > 0 else "below"


def _paper_key_vars(paper: PaperTables, *names: str) -> dict[str, str]:
    return {n: paper.design_variables[n] for n in names}


def _kind(row: dict[str, Any], paper: PaperTables) -> str | None:
    """'table6' for a row of the paper robot's continuous space, 'table9' for its mixed space,
    None for any other row (another robot, a composite objective)."""
    names = row.get("design_variables", "").split()
    discrete = [d == "1" for d in row.get("design_discrete", "").split()]
    cont = _paper_key_vars(paper, "thigh", "shank")
    if not all(v in names for v in cont.values()):
        return None
    motors = _paper_key_vars(paper, "hip_motor", "knee_motor")
    if any(discrete):
        return "table9" if all(v in names for v in motors.values()) else None
    return "table6"


def _design(row: dict[str, Any], var: str) -> tuple[float | None, float | None]:
    return row.get(var), se_of(row, var)


# -- Table 6 ------------------------------------------------------------------------------------
def table6_comparison(
    t6: Sequence[dict[str, Any]], paper: PaperTables | None = None
) -> list[dict[str, Any]]:
    """One row per table6 row the paper's Table 6 has a cell for: ours, the paper's, verdicts."""
    paper = paper or paper_tables()
    out = []
    for r in t6:
        key = (r["objective"], r["method"], r["terrain"])
        if _kind(r, paper) != "table6" or key not in paper.table6:
            continue
        p = paper.table6[key]
        row: dict[str, Any] = {
            k: r[k] for k in ("objective", "method", "optimizer", "terrain", "runs", "seeds")
        }
        for col in ("thigh", "shank"):
            row[col], row[f"{col}_se"] = _design(r, paper.design_variables[col])
            row[f"paper_{col}"] = p[col]
        row["direction"] = direction_verdict(
            {c: row[c] for c in ("thigh", "shank")}, {c: p[c] for c in ("thigh", "shank")}
        )
        _improvements(row, r, p.get("improvement"), p.get("sim2sim_improvement"))
        out.append(row)
    return out


def _like_for_like(row: dict[str, Any], r: dict[str, Any], name: str) -> None:
    """row[name] (and its SE): the table6 row's improvement `name` in the paper's measure, the
    cost reduction 1 - c / c0 (`REDUCTIONS`; a row without it: the improvement as it is), and
    row[name + '_own']: the objective's own measure beside it."""
    paper_measure = dict((own, red) for red, own in REDUCTIONS).get(name)
    src = paper_measure if paper_measure and r.get(f"{paper_measure}_n") else name
    row[name], row[f"{name}_se"] = r.get(src), se_of(r, src)
    row[f"{name}_own"], row[f"{name}_own_se"] = r.get(name), se_of(r, name)


def _improvements(
    row: dict[str, Any],
    r: dict[str, Any],
    paper_imp: float | None,
    paper_s2s: float | None = None,
    *,
    sim2sim: bool = True,
) -> None:
    """Our improvements beside the paper's, each judged in the paper's measure (1 - c / c0),
    the objective's own measure kept beside (`<name>_own`; they differ for command tracking)."""
    row["measure_differs"] = bool(r.get("reduction_differs"))
    _like_for_like(row, r, "improvement")
    row["paper_improvement"] = paper_imp
    row["improvement_verdict"] = value_verdict(row["improvement"], row["improvement_se"], paper_imp)
    _like_for_like(row, r, "improvement_plain")
    row["improvement_plain_verdict"] = value_verdict(
        row["improvement_plain"], row["improvement_plain_se"], paper_imp
    )
    for name in ("common_improvement", "common_improvement_plain"):
        _like_for_like(row, r, name)
        row[f"{name}_verdict"] = value_verdict(row[name], row[f"{name}_se"], paper_imp)
    row["common_fall_rate_difference"] = r.get("common_fall_rate_difference")
    row["common_fall_rate_difference_se"] = se_of(r, "common_fall_rate_difference")
    if sim2sim:
        _like_for_like(row, r, "sim2sim_improvement")
        row["paper_sim2sim_improvement"] = paper_s2s
        row["sim2sim_verdict"] = value_verdict(
            row["sim2sim_improvement"], row["sim2sim_improvement_se"], paper_s2s
        )


def order_comparison(
    rows6: Sequence[dict[str, Any]], paper: PaperTables | None = None
) -> list[dict[str, Any]]:
    """Per objective and terrain (and measure: the run's cost, the plain mean, both on the
    common scenario set), whether our
    methods order by improvement as the paper's do (`table6_comparison` rows in; a method
    with rows of several optimizers counts with its first, the tables' order)."""
    paper = paper or paper_tables()
    groups: dict[tuple[str, str], dict[str, dict[str, Any]]] = {}
    for r in rows6:
        groups.setdefault((r["objective"], r["terrain"]), {}).setdefault(r["method"], r)
    out = []
    for (objective, terrain), by_method in groups.items():
        for measure in MEASURES:
            rows = {m: r for m, r in by_method.items() if r.get(measure) is not None}
            if measure != "improvement" and len(rows) < 2:
                continue  # the runs did not record the plain mean, or have no common-yardstick rows
            methods = [m for m in paper.methods if m in rows]
            pv = {m: paper.table6[(objective, m, terrain)]["improvement"] for m in methods}
            row: dict[str, Any] = {
                "objective": objective,
                "terrain": terrain,
                "measure": measure,
                "methods": " ".join(methods),
                "paper_order": " > ".join(sorted(methods, key=lambda m: -pv[m])),
                "our_order": " > ".join(sorted(methods, key=lambda m: -rows[m][measure])),
            }
            pairs = reversed_ = clear = 0
            for i, a in enumerate(methods):
                for b in methods[i + 1 :]:
                    sign_paper = pv[a] - pv[b]
                    if abs(sign_paper) < 1e-12:
                        continue  # the paper ties them
                    pairs += 1
                    ours = rows[a][measure] - rows[b][measure]
                    if ours * sign_paper < 0:
                        reversed_ += 1
                        sa, sb = rows[a].get(f"{measure}_se"), rows[b].get(f"{measure}_se")
                        if sa is not None and sb is not None and abs(ours) > Z * math.hypot(sa, sb):
                            clear += 1
            row.update(pairs=pairs, reversed=reversed_, clear_reversals=clear)
            if pairs == 0:
                row["verdict"] = "n/a (fewer than two methods)"
            elif reversed_ == 0:
                row["verdict"] = "same order"
            else:
                row["verdict"] = f"{reversed_} of {pairs} pairs reversed ({clear} beyond {Z:g} SE)"
            out.append(row)
    return out


#: the improvements the method order is judged on, and how the tables name them
MEASURES = {
    "improvement": "run's cost",
    "improvement_plain": "plain mean",
    "common_improvement": "common scenarios",
    "common_improvement_plain": "common scenarios, plain mean",
}


# -- Table 9 ------------------------------------------------------------------------------------
def table9_comparison(
    t6: Sequence[dict[str, Any]], paper: PaperTables | None = None
) -> list[dict[str, Any]]:
    """One row per table6 row of the paper robot's mixed space that Table 9 has a cell for."""
    paper = paper or paper_tables()
    out = []
    for r in t6:
        key = (r["objective"], r["method"], r["terrain"])
        if _kind(r, paper) != "table9" or key not in paper.table9:
            continue
        p = paper.table9[key]
        row: dict[str, Any] = {
            k: r[k] for k in ("objective", "method", "optimizer", "terrain", "runs", "seeds")
        }
        for col in ("thigh", "shank"):
            row[col], row[f"{col}_se"] = _design(r, paper.design_variables[col])
            row[f"paper_{col}"] = p[col]
        row["direction"] = direction_verdict(
            {c: row[c] for c in ("thigh", "shank")}, {c: p[c] for c in ("thigh", "shank")}
        )
        for col in ("hip_motor", "knee_motor"):
            # a motor type is a choice: each seed's, and how many chose the paper's (a mean of
            # types 1 and 3 would read as type 2)
            chosen = [
                c
                for c in str(r.get(f"{paper.design_variables[col]}_choices") or "").split()
                if c != "n/a"
            ]
            row[col], row[f"paper_{col}"] = " ".join(chosen) or None, int(p[col])
            same = sum(int(c) == int(p[col]) for c in chosen)
            row[f"{col}_verdict"] = (
                "n/a"
                if not chosen
                else "same"
                if same == len(chosen)
                else "differs"
                if not same
                else f"same in {same} of {len(chosen)} seeds"
            )
        _improvements(row, r, p["improvement"], sim2sim=False)
        out.append(row)
    return out


# -- writing ------------------------------------------------------------------------------------
def _pct(v: float | None, se: float | None = None) -> str:
    if v is None:
        return "n/a"
    return f"{100 * v:.1f}%" + (f" ± {100 * se:.1f}" if se is not None else "")


def _num(v: float | None, se: float | None = None, spec: str = ".2f") -> str:
    if v is None:
        return "n/a"
    return format(v, spec) + (f" ± {format(se, spec)}" if se is not None else "")


def _common(r: dict[str, Any]) -> str:
    if r.get("common_improvement") is None:
        return "n/a (no common-scenario rows)"
    return (
        f"{_pct(r['common_improvement'], r['common_improvement_se'])}, "
        f"{_pct(r['common_improvement_plain'], r['common_improvement_plain_se'])}, "
        f"{_pct(r['common_fall_rate_difference'], r['common_fall_rate_difference_se'])}"
    )


#: the own-measure column's header: our improvements as the objective itself reports them
OWN_HEADER = (
    "Ours in the objective's own measure, where it differs (tracking: 1 - √(c/c0)): run's cost, plain mean, "
    "common, common plain mean"
)


def _own(r: dict[str, Any]) -> str:
    if not r.get("measure_differs"):
        return "same"
    return ", ".join(
        _pct(r.get(f"{n}_own"), r.get(f"{n}_own_se"))
        for n in (
            "improvement",
            "improvement_plain",
            "common_improvement",
            "common_improvement_plain",
        )
    )


def _ratio(v: float | None, se: float | None = None) -> str:
    return "n/a" if v is None else f"{v:.2f}" if se is None else f"{v:.2f} ± {se:.2f}"


def _display(
    rows6: Sequence[dict[str, Any]],
    order: Sequence[dict[str, Any]],
    rows7: Sequence[dict[str, Any]],
    rows9: Sequence[dict[str, Any]],
    objectives: dict[str, str],
) -> list[tuple[str, list[str], list[list[str]]]]:
    """(title, header, cells) of each comparison table, shared by Markdown and HTML;
    methods by their table labels, objectives by `objectives` (name -> label)."""
    methods = {m.name: m.label for m in METHODS.values()}
    sections = []
    head6 = [
        "Objective",
        "Method",
        "Optimizer",
        "Terrain",
        "Runs",
        "Thigh ours / paper",
        "Shank ours / paper",
        "Direction",
        "Improvement (1 - c/c0) ours / paper",
        "Verdict",
        "Plain-mean improvement ours",
        "Verdict",
        "Common scenarios: improvement, plain mean, fall-rate difference",
        "Verdict (plain mean)",
        OWN_HEADER,
        "Sim-to-sim ours / paper",
        "Verdict",
    ]
    cells6 = [
        [
            objectives.get(r["objective"], r["objective"]),
            methods.get(r["method"], r["method"]),
            r["optimizer"],
            r["terrain"],
            str(r["runs"]),
            f"{_num(r['thigh'], r['thigh_se'])} / {r['paper_thigh']:.2f}",
            f"{_num(r['shank'], r['shank_se'])} / {r['paper_shank']:.2f}",
            r["direction"],
            f"{_pct(r['improvement'], r['improvement_se'])} / {_pct(r['paper_improvement'])}",
            r["improvement_verdict"],
            _pct(r["improvement_plain"], r["improvement_plain_se"]),
            r["improvement_plain_verdict"],
            _common(r),
            r["common_improvement_plain_verdict"],
            _own(r),
            f"{_pct(r['sim2sim_improvement'], r['sim2sim_improvement_se'])} / {_pct(r['paper_sim2sim_improvement'])}",
            r["sim2sim_verdict"],
        ]
        for r in rows6
    ]
    sections.append(("Table 6 beside the paper's", head6, cells6))
    head_o = ["Objective", "Terrain", "Measure", "Paper's order", "Our order", "Verdict"]
    cells_o = [
        [
            objectives.get(r["objective"], r["objective"]),
            r["terrain"],
            MEASURES.get(r["measure"], r["measure"]),
            " > ".join(methods.get(m, m) for m in r["paper_order"].split(" > ") if m),
            " > ".join(methods.get(m, m) for m in r["our_order"].split(" > ") if m),
            r["verdict"],
        ]
        for r in order
    ]
    sections.append(("Method order by improvement, per objective and terrain", head_o, cells_o))
    head7 = [
        "Method",
        "Optimizer",
        "Runs",
        "Pairs",
        "Interactions / paper's method: ours, paper",
        "Verdict",
        "Evaluation interactions / paper's method: ours, paper",
        "Wall-clock pairs (same code)",
        "Wall clock / paper's method: ours, paper",
        "Verdict",
        "Wall clock at equal machine speed: ours, paper",
        "Verdict",
    ]
    cells7 = [
        [
            methods.get(r["method"], r["method"]),
            str(r["optimizer"]),
            str(r["runs"]),
            str(r.get("pairs", "n/a")),
            f"{_ratio(r['interactions_ratio'], r.get('interactions_ratio_se'))}, {_ratio(r['paper_interactions_ratio'])}",
            r["interactions_verdict"],
            f"{_ratio(r['evaluation_ratio'], r.get('evaluation_ratio_se'))}, {_ratio(r['paper_evaluation_ratio'])}",
            str(r.get("time_pairs", "n/a")),
            f"{_ratio(r['time_ratio'], r.get('time_ratio_se'))}, {_ratio(r['paper_time_ratio'])}",
            r["time_verdict"],
            f"{_ratio(r['speed_time_ratio'], r.get('speed_time_ratio_se'))}, {_ratio(r['paper_time_ratio'])}",
            r["speed_time_verdict"],
        ]
        for r in rows7
    ]
    sections.append(
        (
            "Table 7 beside the paper's (ratios to the paper's method in the same table)",
            head7,
            cells7,
        )
    )
    head9 = [
        "Objective",
        "Terrain",
        "Optimizer",
        "Runs",
        "Thigh ours / paper",
        "Hip motor per seed, ours / paper",
        "Shank ours / paper",
        "Knee motor per seed, ours / paper",
        "Direction",
        "Improvement (1 - c/c0) ours / paper",
        "Verdict",
        "Plain-mean improvement ours",
        "Verdict",
        "Common scenarios: improvement, plain mean, fall-rate difference",
        "Verdict (plain mean)",
        OWN_HEADER,
    ]
    cells9 = [
        [
            objectives.get(r["objective"], r["objective"]),
            r["terrain"],
            r["optimizer"],
            str(r["runs"]),
            f"{_num(r['thigh'], r['thigh_se'])} / {r['paper_thigh']:.2f}",
            f"{r['hip_motor'] or 'n/a'} / {r['paper_hip_motor']} ({r['hip_motor_verdict']})",
            f"{_num(r['shank'], r['shank_se'])} / {r['paper_shank']:.2f}",
            f"{r['knee_motor'] or 'n/a'} / {r['paper_knee_motor']} ({r['knee_motor_verdict']})",
            r["direction"],
            f"{_pct(r['improvement'], r['improvement_se'])} / {_pct(r['paper_improvement'])}",
            r["improvement_verdict"],
            _pct(r["improvement_plain"], r["improvement_plain_se"]),
            r["improvement_plain_verdict"],
            _common(r),
            r["common_improvement_plain_verdict"],
            _own(r),
        ]
        for r in rows9
    ]
    sections.append(("Table 9 beside the paper's (mixed variables)", head9, cells9))
    return sections


def _missing(
    rows6: Sequence[dict[str, Any]], rows9: Sequence[dict[str, Any]], paper: PaperTables
) -> tuple[int, int]:
    have6 = {(r["objective"], r["method"], r["terrain"]) for r in rows6}
    have9 = {(r["objective"], r["method"], r["terrain"]) for r in rows9}
    return len(set(paper.table6) - have6), len(set(paper.table9) - have9)


def _explanation(
    paper: PaperTables, rows6: Sequence[dict[str, Any]], rows9: Sequence[dict[str, Any]]
) -> str:
    miss6, miss9 = _missing(rows6, rows9, paper)
    return (
        f"Paper: {paper.citation}. Ours: mean ± standard error over seeds (sample std / √n; one run: the SE it "
        f"recorded). Direction: thigh and shank longer or shorter than nominal (a scale within {NOMINAL_BAND} of 1.0 "
        "counts as nominal), as the paper's or not. Improvement verdict: 'within' when the paper's figure lies within "
        f"{Z:g} SE of our mean (plus the paper's rounding), else ours is 'above' or 'below' it; the paper's improvement "
        "is a plain mean over its evaluation scenarios, so the plain-mean column is the like-for-like one. Every "
        "improvement here, and every verdict, is the paper's measure, the cost reduction 1 - c/c0 of the mean "
        "cost (tracking: of P_cmd = e_v² + e_w², eq. 6; the paper says it compares tracking by 'the tracking "
        "error', which we read as P_cmd); where an objective reports its own improvement otherwise "
        "(tracking: the reduction of the RMS error, 1 - √(c/c0), about half as large: the other reading), each "
        "run's figure is restated (its SE by the delta method) and its own is shown beside it. Common "
        "scenarios: each run's best design and its nominal design re-evaluated with the run's own policy on one "
        "scenario set shared by every run of a terrain and preset (one yardstick for all methods; fall-rate difference "
        "in points, paired). Sim-to-sim: "
        "the paper trains in Isaac Gym and transfers to PyBullet; we train in another simulator and transfer to a "
        "second one (the sim-to-sim column of Table 6). Table 7: the paper's hours are on its hardware at its scale; "
        "ratios to the paper's method compare: each run's against the paper's method's run of the same cell "
        "(objective, terrain, seed), mean ± SE over the pairs; a verdict of costlier or cheaper needs the ratio "
        f"{Z:g} SE away from 1; wall clocks pair only runs made by the same code (the same clean git commit: "
        f"a speed-up changes them) and carry the machine's load; at equal machine speed, each wall clock is divided by the "
        f"run's own seconds per training interaction, the machine's speed while it ran, measured on work every "
        f"training method does alike. Paper cells with no run here: {miss6} of {len(paper.table6)} "
        f"(Table 6), {miss9} of {len(paper.table9)} (Table 9): not yet run."
    )


def comparison_markdown(
    rows6,
    order,
    rows7,
    rows9,
    paper: PaperTables | None = None,
    objectives: dict[str, str] | None = None,
    figure: tuple[Path, str] | None = None,
) -> str:
    paper = paper or paper_tables()
    lines = ["# Beside the paper", ""]
    if figure is not None:
        lines += [f"![{figure[1]}]({figure[0].name})", ""]
    for title, head, cells in _display(rows6, order, rows7, rows9, objectives or {}):
        lines += [f"## {title}", ""]
        if not cells:
            lines += ["No run of this report has a cell in this table of the paper.", ""]
            continue
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(c) + " |" for c in cells]
        lines.append("")
    lines.append(_explanation(paper, rows6, rows9))
    return "\n".join(lines) + "\n"


def comparison_html(
    rows6,
    order,
    rows7,
    rows9,
    paper: PaperTables | None = None,
    objectives: dict[str, str] | None = None,
) -> str:
    paper = paper or paper_tables()
    parts = [
        "<h2>Beside the paper</h2>",
        f"<p>{html.escape(_explanation(paper, rows6, rows9))}</p>",
    ]
    for title, head, cells in _display(rows6, order, rows7, rows9, objectives or {}):
        parts.append(f"<h3>{html.escape(title)}</h3>")
        if not cells:
            parts.append("<p>No run of this report has a cell in this table of the paper.</p>")
            continue
        header = "".join(f"<th>{html.escape(h)}</th>" for h in head)
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in cells
        )
        parts.append(
            f"<div class='scroll'><table><thead><tr>{header}</tr></thead><tbody>{body}</tbody></table></div>"
        )
    return "\n".join(parts)


def _write_csv(path: Path, columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> None:
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns))
        writer.writeheader()
        for r in rows:
            writer.writerow(
                {
                    k: ("" if r.get(k) is None else repr(r[k]) if isinstance(r[k], float) else r[k])
                    for k in columns
                }
            )


def write_paper_comparison(
    t6: Sequence[dict[str, Any]],
    t7: Sequence[dict[str, Any]],
    out: Path,
    *,
    facts: Sequence[Any],
    objective_labels: dict[str, str] | None = None,
) -> tuple[dict[str, Path], str]:
    """Write the comparison files into `out` from the report's Table 6 rows and its Table 7
    rows over the runs of continuous design spaces (the paper's Table 7 covers its Table 6
    runs; `facts`, those runs, pair Table 7's ratios per cell); returns the files by name and
    the report.html section."""
    paper = paper_tables()
    rows6 = table6_comparison(t6, paper)
    order = order_comparison(rows6, paper)
    rows7 = table7_comparison(t7, facts, paper)
    rows9 = table9_comparison(t6, paper)
    files = {}
    for name, columns, rows in (
        ("paper_table6.csv", T6_COLUMNS, rows6),
        ("paper_order.csv", ORDER_COLUMNS, order),
        ("paper_table7.csv", T7_COLUMNS, rows7),
        ("paper_table9.csv", T9_COLUMNS, rows9),
    ):
        _write_csv(out / name, columns, rows)
        files[name] = out / name
    figure = next(iter(figure_beside_paper(rows6, out, objective_labels)), None)
    if figure is not None:
        files[figure[0].name] = figure[0]
    (out / "paper_comparison.md").write_text(
        comparison_markdown(rows6, order, rows7, rows9, paper, objective_labels, figure)
    )
    files["paper_comparison.md"] = out / "paper_comparison.md"
    section = comparison_html(rows6, order, rows7, rows9, paper, objective_labels)
    if figure is not None:
        section += (
            f"\n<figure><img src='{html.escape(figure[0].name)}' alt='{html.escape(figure[0].stem)}'>"
            f"<figcaption>{html.escape(figure[1])}</figcaption></figure>"
        )
    return files, section
