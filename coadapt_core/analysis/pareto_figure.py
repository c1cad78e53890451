"""pareto.png: the Pareto fronts of multi-objective runs, each design of a front with its
final-check costs +- SE beside the run's in-run estimates, the design the run returns and the
nominal design; `pareto_points` is what a panel draws, shared with `pareto_report`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import RunFacts
from coadapt_core.analysis.figures import (
    PANEL_H,
    cost_unit,
    panel_grid,
    pyplot,
    save_figure,
    spans_decades,
    tidy_axes,
)
from coadapt_core.pareto import pareto_mask


def pareto_points(f: RunFacts) -> dict[str, Any]:
    """What pareto.png draws for a multi-objective run: every in-run real evaluation
    ("evaluated" [n, 2]), the front ("front" [F, 2], first two objectives; "front_se" [F, 2]
    or None), the index of the design the run returned ("returned"), the front's
    hypervolume with its SE and where the front comes from. The front is the run's stored
    final front (the one `coadapt run` printed) when it has one."""
    o1, o2 = f.run["objectives"][:2]
    evaluated = np.array(
        [[e.costs[o1], e.costs[o2]] for e in f.real if o1 in e.costs and o2 in e.costs]
    ).reshape(-1, 2)
    stored = f.summary.get("pareto_front")
    front_se, hv, hv_se = None, None, None
    if isinstance(stored, dict) and stored.get("costs"):
        front = np.array([[c[o1], c[o2]] for c in stored["costs"]], dtype=float)
        designs = np.array(stored["designs"], dtype=float)
        if isinstance(stored.get("costs_se"), list) and len(stored["costs_se"]) == len(front):
            front_se = np.array(
                [[c.get(o1, np.nan), c.get(o2, np.nan)] for c in stored["costs_se"]], dtype=float
            )
        hv, hv_se = stored.get("hypervolume"), stored.get("hypervolume_se")
        source = "the run's final front (real re-evaluation)"
    else:
        mask = pareto_mask(evaluated)
        front = evaluated[mask]
        designs = np.array([e.design for e in f.real if o1 in e.costs and o2 in e.costs])[mask]
        source = "non-dominated real evaluations (the run stored no final front)"
    order = np.lexsort(front.T[::-1]) if len(front) else np.arange(0)
    returned = None
    best = f.summary.get("best_costs") or {}
    if len(front) and o1 in best and o2 in best:
        hit = np.flatnonzero(np.isclose(front[order], [best[o1], best[o2]]).all(axis=1))
        returned = int(hit[0]) if len(hit) else None
    return {
        "objectives": (o1, o2),
        "evaluated": evaluated,
        "front": front[order],
        "designs": designs[order],
        "front_se": None if front_se is None else front_se[order],
        "returned": returned,
        "hypervolume": hv,
        "hypervolume_se": hv_se,
        "source": source,
        "nominal": _nominal_point(f, o1, o2),
    }


def _nominal_point(f: RunFacts, o1: str, o2: str) -> tuple[float, float] | None:
    nominal = f.summary.get("nominal_costs") or {}
    point = (nominal.get(o1), nominal.get(o2))
    return point if all(isinstance(v, int | float) and math.isfinite(v) for v in point) else None


def hv_text(hv: Any, se: Any) -> str:
    """'hypervolume 1.23 +- 0.04' (or without the SE when none was measured); '' without one."""
    if not isinstance(hv, int | float) or not math.isfinite(hv):
        return ""
    if isinstance(se, int | float) and math.isfinite(se):
        return f"hypervolume {hv:.3f} +- {se:.3f}"
    return f"hypervolume {hv:.3f} (no SE: no per-scenario costs)"


def _draw_front(ax: Any, d: dict[str, Any]) -> None:
    """One run's panel: in-run estimates in grey, the re-evaluated front with its error bars
    and each design's --pick index, the returned design as a diamond."""
    o1, _ = d["objectives"]
    front = d["front"]
    ax.scatter(
        d["evaluated"][:, 0],
        d["evaluated"][:, 1],
        s=12,
        color="lightgrey",
        label="in-run estimates (real rounds, other scenarios)",
    )
    label = f"front, final check +- SE ({len(front)} design{'' if len(front) == 1 else 's'})"
    if d["front_se"] is not None:
        ax.errorbar(
            front[:, 0],
            front[:, 1],
            xerr=d["front_se"][:, 0],
            yerr=d["front_se"][:, 1],
            fmt="o-",
            color="tab:red",
            capsize=3,
            markersize=5,
            label=label,
        )
    else:
        ax.plot(front[:, 0], front[:, 1], "o-", color="tab:red", label=label.replace(" +- SE", ""))
    for j, (x, y) in enumerate(front):
        ax.annotate(
            str(j), (x, y), textcoords="offset points", xytext=(5, 5), fontsize=7, color="tab:red"
        )
    if d["nominal"] is not None:
        ax.plot(
            *d["nominal"],
            marker="x",
            markersize=9,
            color="black",
            linestyle="none",
            label="nominal design (final check)",
        )
    if d["returned"] is not None:
        x, y = front[d["returned"]]
        ax.plot(
            x,
            y,
            marker="D",
            markersize=10,
            markerfacecolor="none",
            markeredgecolor="black",
            linestyle="none",
            label=f"returned design (front {d['returned']}: lowest {o1} cost)",
        )


def figure_pareto(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    plt = pyplot()
    multi = [
        f
        for f in facts
        if len(f.run["objectives"]) >= 2 and (f.real or f.summary.get("pareto_front"))
    ][:6]
    if not multi:
        return []
    fig, axes = panel_grid(plt, len(multi), height=PANEL_H + 0.4)
    sources = set()
    for ax, f in zip(axes, multi, strict=True):
        d = pareto_points(f)
        o1, o2 = d["objectives"]
        _draw_front(ax, d)
        ax.set_xlabel(f"{o1} cost per step{cost_unit(o1, [f.summary])}")
        ax.set_ylabel(f"{o2} cost per step{cost_unit(o2, [f.summary])}")
        both = np.vstack([d["evaluated"], d["front"]])
        if spans_decades(both[:, 0]):
            ax.set_xscale("log")
        if spans_decades(both[:, 1]):
            ax.set_yscale("log")
        hv = hv_text(d["hypervolume"], d["hypervolume_se"])
        ax.set_title(
            f"{f.run['id']}\n{f.optimizer} on {f.terrain}" + (f"; {hv}" if hv else ""), fontsize=8
        )
        ax.legend(fontsize=7)
        tidy_axes(ax)
        sources.add(d["source"])
    return save_figure(
        plt,
        fig,
        out / "pareto.png",
        f"Pareto fronts of multi-objective runs. Red: the front ({'; '.join(sorted(sources))}), "
        "each design with its final-check costs +- standard error and its index for `coadapt "
        "handoff RUN --pick N`; the same designs `coadapt run` printed and the store holds. "
        "Diamond: the design the run returns (Table 6's, the lowest first cost); cross: the "
        "nominal design in the same final check. Grey: the in-run estimates of the real rounds, "
        "on fewer and other scenarios than the final check, so noisier and, for the designs the "
        "optimizer kept, biased low by that selection: grey points below the front do not beat "
        "it. Title: the front's hypervolume +- SE (costs relative to the nominal design's, up to "
        "2 in each; the nominal design alone has 1).",
    )
