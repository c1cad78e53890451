"""Table 7 beside the paper's: each method's interactions, evaluation interactions and wall
clock as a ratio to the paper's method, paired per cell (the same objective, terrain and seed)
with mean ± SE over the pairs; `paper_comparison` writes it beside Tables 6 and 9."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from coadapt_core.analysis.paper import PaperTables, paper_tables

#: a difference is beyond noise when larger than this many standard errors
Z = 2.0


def _cell_key(f: Any) -> tuple:
    """The cell a run answers: runs of two methods with the same key differ only by method."""
    return (f.setting, f.objective, f.terrain, f.run.get("seed"))


def paired_cost_ratios(facts: Sequence[Any], reference: str) -> dict[tuple[tuple[str, str, str], str, str], dict[str, Any]]:
    """Per (setting, method, optimizer): each run's interactions, evaluation interactions and
    wall clock (training + evaluation) as a ratio to the reference method's run of the same
    cell (setting, objective, terrain, seed; several reference runs of a cell are averaged),
    then mean ± SE over the pairs. Pairing cancels what the cells differ in (terrain,
    objective, seed); the SE shows what is left, the machine's load included."""
    def totals(f: Any) -> tuple[float, float, float]:
        return (float(f.train_interactions + f.eval_interactions), float(f.eval_interactions),
                float(f.train_seconds + f.eval_seconds))

    by_cell: dict[tuple, list[tuple[float, float, float]]] = {}
    for f in facts:
        if f.method == reference:
            by_cell.setdefault(_cell_key(f), []).append(totals(f))
    ref = {k: tuple(sum(v[i] for v in vs) / len(vs) for i in range(3)) for k, vs in by_cell.items()}
    ratios: dict[tuple[tuple[str, str, str], str, str], list[list[float | None]]] = {}
    for f in facts:
        r = ref.get(_cell_key(f))
        if r is None:
            continue
        mine = totals(f)
        ratios.setdefault((f.setting, f.method, f.optimizer), []).append(
            [m / b if b else None for m, b in zip(mine, r, strict=True)])
    out = {}
    for key, rows in ratios.items():
        stats: dict[str, Any] = {"pairs": len(rows)}
        for i, name in enumerate(("interactions_ratio", "evaluation_ratio", "time_ratio")):
            vals = [row[i] for row in rows if row[i] is not None]
            stats[name] = sum(vals) / len(vals) if vals else None
            stats[f"{name}_se"] = (math.sqrt(sum((v - stats[name]) ** 2 for v in vals) / (len(vals) - 1) / len(vals))
                                   if len(vals) > 1 else None)
        out[key] = stats
    return out


def table7_comparison(t7: Sequence[dict[str, Any]], paper: PaperTables | None = None,
                      facts: Sequence[Any] | None = None) -> list[dict[str, Any]]:
    """Each table7 row of a paper method: our interactions and wall clock as a ratio to the
    paper's method's, beside the paper's ratios, and whether it costs more or less than the
    paper's method as in the paper. With the runs' `facts`, the ratios are paired per cell
    (`paired_cost_ratios`: mean ± SE over the pairs, the verdict only beyond 2 SE); without,
    ratios of the rows' means (no SE)."""
    paper = paper or paper_tables()
    rows = [r for r in t7 if r["method"] in paper.table7]
    pref = paper.table7[paper.reference_method]
    paired = None if facts is None else paired_cost_ratios(facts, paper.reference_method)

    def total(r: dict[str, Any] | None, a: str, b: str) -> float | None:
        if r is None or r.get(a) is None or r.get(b) is None:
            return None
        return float(r[a]) + float(r[b])

    def ratio(x: float | None, y: float | None) -> float | None:
        return None if x is None or not y else x / y

    out = []
    for r in rows:
        p = paper.table7[r["method"]]
        row: dict[str, Any] = {k: r.get(k) for k in ("method", "optimizer", "runs", "interactions_training",
                                                     "interactions_evaluation", "seconds_training", "seconds_evaluation")}
        for k in ("interactions_training", "interactions_evaluation", "hours_training", "hours_evaluation"):
            row[f"paper_{k}"] = p[k]
        same = r["method"] == paper.reference_method
        setting = (str(r.get("robot")), str(r.get("simulator")), str(r.get("preset")))
        if paired is not None:
            stats = ({"pairs": r["runs"], "interactions_ratio": 1.0, "evaluation_ratio": 1.0, "time_ratio": 1.0}
                     if same else paired.get((setting, r["method"], r["optimizer"]), {"pairs": 0}))
            for k in ("interactions_ratio", "evaluation_ratio", "time_ratio"):
                row[k], row[f"{k}_se"] = stats.get(k), stats.get(f"{k}_se")
            row["pairs"] = stats["pairs"]
        else:
            ref = next((x for x in rows if x["method"] == paper.reference_method
                        and (str(x.get("robot")), str(x.get("simulator")), str(x.get("preset"))) == setting), None)
            row["interactions_ratio"] = ratio(total(r, "interactions_training", "interactions_evaluation"),
                                              total(ref, "interactions_training", "interactions_evaluation"))
            row["evaluation_ratio"] = ratio(r.get("interactions_evaluation"),
                                            None if ref is None else ref.get("interactions_evaluation"))
            row["time_ratio"] = ratio(total(r, "seconds_training", "seconds_evaluation"),
                                      total(ref, "seconds_training", "seconds_evaluation"))
        row["paper_interactions_ratio"] = p["interactions_total"] / pref["interactions_total"]
        row["paper_evaluation_ratio"] = p["interactions_evaluation"] / pref["interactions_evaluation"]
        row["paper_time_ratio"] = p["hours_total"] / pref["hours_total"]
        for name in ("interactions", "time"):
            row[f"{name}_verdict"] = "reference" if same else _ratio_verdict(
                row[f"{name}_ratio"], row[f"paper_{name}_ratio"], row.get(f"{name}_ratio_se"), paired is not None)
        out.append(row)
    return out


def _ratio_verdict(ours: float | None, paper: float, se: float | None = None, paired: bool = False) -> str:
    if ours is None:
        return "n/a (no run of the paper's method)" if not paired else "n/a (no cell shared with the paper's method)"
    side = "costlier" if paper > 1 else "cheaper" if paper < 1 else "equal"
    if paired and se is not None and abs(ours - 1.0) <= Z * se:
        return f"within {Z:g} SE of equal, the paper's is {side}"
    mine = "costlier" if ours > 1 else "cheaper" if ours < 1 else "equal"
    note = " (no SE)" if paired and se is None else ""
    return (f"{side} as in the paper" if side == mine else f"{mine}, the paper's is {side}") + note
