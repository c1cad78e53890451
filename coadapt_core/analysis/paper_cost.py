"""Table 7 beside the paper's: each method's interactions, evaluation interactions and wall
clock as a ratio to the paper's method, paired per cell (the same objective, terrain and seed)
with mean ± SE over the pairs; `paper_comparison` writes it beside Tables 6 and 9."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from coadapt_core.analysis.paper import PaperTables, paper_tables
from coadapt_core.analysis.tables import _stat

#: a difference is beyond noise when larger than this many standard errors
Z = 2.0


def _cell_key(f: Any) -> tuple:
    """The cell a run answers: runs of two methods with the same key differ only by method."""
    return (f.setting, f.objective, f.terrain, f.run.get("seed"))


def _code(f: Any) -> str | None:
    """The commit a run's code came from, None when unknown or modified ("+dirty"): wall
    clocks compare only between runs of the same code, which a speed-up changes."""
    commit = str(f.run.get("git_commit") or "")
    return commit if commit and not commit.endswith("+dirty") else None


def paired_cost_ratios(
    facts: Sequence[Any], reference: str
) -> dict[tuple[tuple[str, str, str], str, str], dict[str, Any]]:
    """Per (setting, method, optimizer): each run's interactions, evaluation interactions and
    wall clock (training + evaluation) as a ratio to the reference method's run of the same
    cell (setting, objective, terrain, seed; several reference runs of a cell are averaged),
    then mean ± SE over the pairs. The wall clock pairs only runs made by the same code (the
    same clean git commit; `time_pairs` counts them); `speed_time_ratio` sets it at equal
    machine speed: each wall clock divided by the run's own seconds per training interaction
    (work every training method does alike), so a run made while the machine was busier is
    not charged for it (None for a run that does not train). Pairing cancels what the cells differ
    in (terrain, objective, seed); the SE shows what is left, the machine's load included."""

    def totals(f: Any) -> tuple[float, float]:
        return float(f.train_interactions + f.eval_interactions), float(f.eval_interactions)

    def times(f: Any) -> tuple[float, float | None]:
        """(wall seconds, the same at equal machine speed: wall seconds over the run's own
        seconds per training interaction, None for a run that did not train)."""
        wall = float(f.train_seconds + f.eval_seconds)
        speed = (
            f.train_seconds / f.train_interactions
            if f.train_interactions and f.train_seconds
            else None
        )
        return wall, (wall / speed if speed else None)

    by_cell: dict[tuple, list[tuple[float, float]]] = {}
    by_code: dict[tuple, list[tuple[float, float | None]]] = {}
    for f in facts:
        if f.method == reference:
            by_cell.setdefault(_cell_key(f), []).append(totals(f))
            if _code(f):
                by_code.setdefault((_cell_key(f), _code(f)), []).append(times(f))
    ref = {k: tuple(sum(v[i] for v in vs) / len(vs) for i in range(2)) for k, vs in by_cell.items()}
    ref_time = {
        k: tuple(_stat([v[i] for v in vs])[0] for i in range(2)) for k, vs in by_code.items()
    }
    ratios: dict[tuple[tuple[str, str, str], str, str], list[list[float | None]]] = {}
    for f in facts:
        r = ref.get(_cell_key(f))
        if r is None:
            continue
        row: list[float | None] = [m / b if b else None for m, b in zip(totals(f), r, strict=True)]
        t = ref_time.get((_cell_key(f), _code(f)), (None, None)) if _code(f) else (None, None)
        row += [m / b if m is not None and b else None for m, b in zip(times(f), t, strict=True)]
        ratios.setdefault((f.setting, f.method, f.optimizer), []).append(row)
    out = {}
    for key, rows in ratios.items():
        stats: dict[str, Any] = {
            "pairs": len(rows),
            "time_pairs": sum(row[2] is not None for row in rows),
        }
        for i, name in enumerate(
            ("interactions_ratio", "evaluation_ratio", "time_ratio", "speed_time_ratio")
        ):
            mean, std, n = _stat([row[i] for row in rows])
            stats[name], stats[f"{name}_se"] = mean, None if std is None else std / math.sqrt(n)
        out[key] = stats
    return out


def table7_comparison(
    t7: Sequence[dict[str, Any]], facts: Sequence[Any], paper: PaperTables | None = None
) -> list[dict[str, Any]]:
    """Each table7 row of a paper method: our interactions and wall clock as a ratio to the
    paper's method's, paired per cell over the runs' `facts` (`paired_cost_ratios`: mean ± SE
    over the pairs), beside the paper's ratios, and whether it costs more or less than the
    paper's method as in the paper (only beyond 2 SE)."""
    paper = paper or paper_tables()
    pref = paper.table7[paper.reference_method]
    paired = paired_cost_ratios(facts, paper.reference_method)
    out = []
    for r in (r for r in t7 if r["method"] in paper.table7):
        p = paper.table7[r["method"]]
        row: dict[str, Any] = {
            k: r.get(k)
            for k in (
                "method",
                "optimizer",
                "runs",
                "interactions_training",
                "interactions_evaluation",
                "seconds_training",
                "seconds_evaluation",
            )
        }
        for k in (
            "interactions_training",
            "interactions_evaluation",
            "hours_training",
            "hours_evaluation",
        ):
            row[f"paper_{k}"] = p[k]
        same = r["method"] == paper.reference_method
        setting = (str(r.get("robot")), str(r.get("simulator")), str(r.get("preset")))
        stats = (
            {
                "pairs": r["runs"],
                "time_pairs": r["runs"],
                "interactions_ratio": 1.0,
                "evaluation_ratio": 1.0,
                "time_ratio": 1.0,
                "speed_time_ratio": 1.0,
            }
            if same
            else paired.get((setting, r["method"], r["optimizer"]), {"pairs": 0})
        )
        for k in ("interactions_ratio", "evaluation_ratio", "time_ratio", "speed_time_ratio"):
            row[k], row[f"{k}_se"] = stats.get(k), stats.get(f"{k}_se")
        row["pairs"], row["time_pairs"] = stats["pairs"], stats.get("time_pairs", 0)
        row["paper_interactions_ratio"] = p["interactions_total"] / pref["interactions_total"]
        row["paper_evaluation_ratio"] = (
            p["interactions_evaluation"] / pref["interactions_evaluation"]
        )
        row["paper_time_ratio"] = p["hours_total"] / pref["hours_total"]
        row["paper_speed_time_ratio"] = row["paper_time_ratio"]
        for name in ("interactions", "time", "speed_time"):
            row[f"{name}_verdict"] = (
                "reference"
                if same
                else _ratio_verdict(
                    row[f"{name}_ratio"], row[f"paper_{name}_ratio"], row[f"{name}_ratio_se"]
                )
            )
        if not same and row["pairs"] and not row["time_pairs"]:
            row["time_verdict"] = row["speed_time_verdict"] = "n/a (no pair made by the same code)"
        elif not same and row["time_pairs"] and row["speed_time_ratio"] is None:
            row["speed_time_verdict"] = "n/a (no training to measure the machine's speed by)"
        out.append(row)
    return out


def _ratio_verdict(ours: float | None, paper: float, se: float | None) -> str:
    if ours is None:
        return "n/a (no cell shared with the paper's method)"
    side = "costlier" if paper > 1 else "cheaper" if paper < 1 else "equal"
    if se is not None and abs(ours - 1.0) <= Z * se:
        return f"within {Z:g} SE of equal, the paper's is {side}"
    mine = "costlier" if ours > 1 else "cheaper" if ours < 1 else "equal"
    note = " (no SE)" if se is None else ""
    return (f"{side} as in the paper" if side == mine else f"{mine}, the paper's is {side}") + note
