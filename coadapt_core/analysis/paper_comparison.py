"""Our figures beside the paper's (Du et al. 2025, Tables 6, 7 and 9; the data is
`coadapt_core.analysis.paper`), with a verdict per cell. `coadapt report` writes them as
paper_comparison.md, paper_table6.csv, paper_order.csv, paper_table7.csv, paper_table9.csv
and a section of report.html.

Verdicts (docs/reproduction.md restates them; the rules are `paper_verdicts`):

- design direction: each of thigh and shank longer than nominal, shorter or at nominal; a
  cell agrees, disagrees or is undecided (`paper_verdicts.direction_verdict`).
- improvement: *within* when the paper's figure lies within 2 standard errors of our mean,
  widened by the paper's rounding; else *above* or *below* the paper's
  (`paper_verdicts.value_verdict`). Checked for the improvement under the run's cost rule,
  under the plain mean (the paper's eq. 4, where the runs recorded it) and sim-to-sim.
- method order, per objective and terrain: the pairs of methods both tables hold, ordered by
  improvement; a pair the paper ties is not counted; a reversed pair is *clear* when our two
  means differ by more than 2 combined SE.
- Table 7: each method's interactions and wall clock as a ratio to the paper's method in the
  same table (the paper's hardware and scale differ from ours; ratios compare), paired per
  cell: each run against the paper's method's run of the same objective, terrain and seed,
  mean ± SE over the pairs; the verdict says whether it costs more or less than the paper's
  method, as in the paper, or is within 2 SE of equal (`paper_cost`).

The cells as people read them are `paper_display`; the CSV columns `paper_csv`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.paper import PaperTables, paper_tables
from coadapt_core.analysis.paper_cost import Z, table7_comparison
from coadapt_core.analysis.paper_csv import (
    ORDER_COLUMNS,
    T6_COLUMNS,
    T7_COLUMNS,
    T9_COLUMNS,
    write_columns,
)
from coadapt_core.analysis.paper_display import (
    comparison_html,
    comparison_markdown,
    display_tables,
    figure_html,
    how_to_read,
)
from coadapt_core.analysis.paper_figure import figure_beside_paper
from coadapt_core.analysis.paper_verdicts import (
    MEASURES,
    direction_verdict,
    se_of,
    value_verdict,
)
from coadapt_core.analysis.tables import REDUCTIONS


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


def _design_rows(
    t6: Sequence[dict[str, Any]], paper: PaperTables, kind: str
) -> Iterator[tuple[dict[str, Any], dict[str, Any], dict[str, Any]]]:
    """(table6 row, the paper's cell, our comparison row so far) for each table6 row the
    paper's `kind` table ("table6" or "table9") has a cell for: the row's keys, both designs
    and the direction verdict."""
    cells = getattr(paper, kind)
    for r in t6:
        key = (r["objective"], r["method"], r["terrain"])
        if _kind(r, paper) != kind or key not in cells:
            continue
        p = cells[key]
        row: dict[str, Any] = {
            k: r[k] for k in ("objective", "method", "optimizer", "terrain", "runs", "seeds")
        }
        for col in ("thigh", "shank"):
            row[col], row[f"{col}_se"] = _design(r, paper.design_variables[col])
            row[f"paper_{col}"] = p[col]
        row["direction"] = direction_verdict(
            {c: row[c] for c in ("thigh", "shank")}, {c: p[c] for c in ("thigh", "shank")}
        )
        yield r, p, row


# -- Table 6 ------------------------------------------------------------------------------------
def table6_comparison(
    t6: Sequence[dict[str, Any]], paper: PaperTables | None = None
) -> list[dict[str, Any]]:
    """One row per table6 row the paper's Table 6 has a cell for: ours, the paper's, verdicts."""
    paper = paper or paper_tables()
    out = []
    for r, p, row in _design_rows(t6, paper, "table6"):
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


# -- Table 9 ------------------------------------------------------------------------------------
def table9_comparison(
    t6: Sequence[dict[str, Any]], paper: PaperTables | None = None
) -> list[dict[str, Any]]:
    """One row per table6 row of the paper robot's mixed space that Table 9 has a cell for."""
    paper = paper or paper_tables()
    out = []
    for r, p, row in _design_rows(t6, paper, "table9"):
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
        write_columns(out / name, columns, rows)
        files[name] = out / name
    figure = next(iter(figure_beside_paper(rows6, out, objective_labels)), None)
    if figure is not None:
        files[figure[0].name] = figure[0]
    tables = display_tables(rows6, order, rows7, rows9, objective_labels or {})
    reading = how_to_read(paper, rows6, rows9)
    (out / "paper_comparison.md").write_text(comparison_markdown(tables, reading, figure))
    files["paper_comparison.md"] = out / "paper_comparison.md"
    section = comparison_html(tables, reading)
    if figure is not None:
        section += "\n" + figure_html(*figure)
    return files, section
