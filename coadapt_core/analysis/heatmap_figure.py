"""The report's Fig. 6-style cost heat-maps: per terrain and design space, one panel per
objective, a landscape run's grid of real costs where one exists, else the runs' evaluated
designs as dots coloured by their real cost, with each method's best designs on top."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import (
    METHOD_COLORS,
    METHOD_MARKERS,
    TERRAIN_ORDER,
    RunFacts,
    objective_order,
)
from coadapt_core.analysis.figures import (
    PANEL_H,
    cost_unit,
    panel_grid,
    pyplot,
    save_figure,
    spans_decades,
)
from coadapt_core.analysis.tables import group_order, method_label, ordered
from coadapt_core.results.export import space_of_run
from coadapt_core.results.schema import LANDSCAPE_METHOD
from coadapt_core.results.store import ResultsStore


def _space_slug(names: Sequence[str]) -> str:
    return "+".join(names)


def _landscape_for(
    store: ResultsStore, objective: str, terrain: str, names: Sequence[str]
) -> dict[str, Any] | None:
    """The latest finished landscape over this objective, terrain and design space."""
    found = []
    for r in store.list_runs(method=LANDSCAPE_METHOD, terrain=terrain, status="finished"):
        if not (r["objectives"] and objective in r["objectives"]):
            continue
        space = space_of_run(r, 2)
        land_names = [v["name"] for v in space["variables"]] if space else ["x0", "x1"]
        if list(land_names[:2]) == list(names[:2]) and len(names) == 2:
            found.append(r)
    return found[-1] if found else None


def heatmap_data(
    store: ResultsStore,
    facts: Sequence[RunFacts],
    objective: str,
    terrain: str,
    names: Sequence[str],
) -> dict[str, Any] | None:
    """What one panel draws for an objective, terrain and design space: a landscape grid
    ("grid": [n_b, n_a] indexed [second variable, first]) when a landscape run exists,
    else the evaluated designs as points ("points" [n, 2], "values" [n]); None when
    neither exists."""
    names = list(names)
    land = _landscape_for(store, objective, terrain, names)
    if land is not None:
        rows = store.evaluations(land["id"], kind="real")
        pts = np.array([e.design[:2] for e in rows])  # [n*n, 2]
        vals = np.array([e.costs[objective] for e in rows])
        a, b = np.unique(pts[:, 0]), np.unique(pts[:, 1])
        grid = np.full((len(b), len(a)), np.nan)
        for (x, y), v in zip(pts, vals, strict=True):
            grid[np.searchsorted(b, y), np.searchsorted(a, x)] = v
        return {
            "kind": "landscape",
            "a": a,
            "b": b,
            "grid": grid,
            "optimum": pts[int(np.argmin(vals))],
            "source": f"landscape run {land['id']} ({len(a)}x{len(b)} real evaluations)",
        }
    pts, vals = [], []
    for f in facts:
        if f.objective == objective and f.terrain == terrain and list(f.design_names) == names:
            for e in f.real:
                if (
                    objective in e.costs
                    and len(e.design) >= 2
                    and math.isfinite(e.costs[objective])
                ):
                    pts.append(e.design[:2])
                    vals.append(e.costs[objective])
    if not pts:
        return None
    return {
        "kind": "scatter",
        "points": np.array(pts),
        "values": np.array(vals),
        "source": f"{len(pts)} real evaluations of the runs (each with its own run's policy)",
    }


def figure_heatmaps(
    store: ResultsStore, facts: Sequence[RunFacts], out: Path
) -> list[tuple[Path, str]]:
    """One PNG per terrain and design space, one panel per objective: the landscape grid when
    one exists, else the designs the runs evaluated, coloured by their real cost."""
    plt = pyplot()
    written = []
    runs = [
        f for f in facts if f.method != LANDSCAPE_METHOD and "," not in f.objective
    ]  # fronts go to pareto.png
    objectives = ordered([f.objective for f in runs], objective_order())
    spaces = sorted({f.space_key for f in runs if len(f.space_key) >= 2}, key=lambda k: (len(k), k))
    for names in spaces:
        for t in ordered([f.terrain for f in runs], TERRAIN_ORDER):
            panels = [(o, heatmap_data(store, runs, o, t, names)) for o in objectives]
            panels = [(o, d) for o, d in panels if d is not None]
            if panels:
                written += _heatmap_figure(plt, runs, panels, t, names, out)
    return written


def _heatmap_figure(
    plt: Any,
    runs: Sequence[RunFacts],
    panels: Sequence[tuple[str, dict[str, Any]]],
    t: str,
    names: Sequence[str],
    out: Path,
) -> list[tuple[Path, str]]:
    """The heat-map of terrain `t` over the design space `names`: one panel per (objective,
    `heatmap_data`), each method's best designs on top."""
    fig, axes = panel_grid(plt, len(panels), height=PANEL_H + 0.6)
    sources, drew_star, drew_methods = [], False, set()
    for ax, (o, d) in zip(axes, panels, strict=True):
        drew_star = _draw_costs(fig, ax, o, d) or drew_star
        mine = [f for f in runs if f.objective == o and f.terrain == t and f.space_key == names]
        drew_methods |= _draw_best_designs(ax, mine)
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
        ax.set_title(
            f"{o} on {t}"
            + (" (landscape grid)" if d["kind"] == "landscape" else " (evaluated designs)"),
            fontsize=10,
        )
        ax.legend(
            loc="upper center",
            bbox_to_anchor=(0.5, -0.16),
            ncol=2,
            fontsize=7,
            frameon=False,
        )
        sources.append(f"{o}: {d['source']}")
    # a two-variable space is the figure's own name; a larger one (motor types too) is named
    suffix = "" if len(names) == 2 else "_" + _space_slug(names)
    caption = _heatmap_caption(t, names, {d["kind"] for _, d in panels}, drew_methods, drew_star)
    return save_figure(
        plt,
        fig,
        out / f"heatmap_{t}{suffix}.png",
        caption + " Sources: " + "; ".join(sources) + ".",
    )


def _draw_costs(fig: Any, ax: Any, o: str, d: dict[str, Any]) -> bool:
    """One panel's real costs of objective `o` (a landscape grid or evaluated designs) and its
    colour bar; True when it drew the grid's optimum (a star)."""
    from matplotlib.colors import LogNorm

    values = d["grid"] if d["kind"] == "landscape" else d["values"]
    log = spans_decades(values)
    norm = LogNorm(vmin=float(np.nanmin(values)), vmax=float(np.nanmax(values))) if log else None
    if d["kind"] == "landscape":
        # each grid cell one evaluated design: no interpolation between them
        mesh = ax.pcolormesh(
            d["a"], d["b"], d["grid"], cmap="viridis_r", norm=norm, shading="nearest"
        )
        ax.plot(
            *d["optimum"],
            marker="*",
            markerfacecolor="none",
            markeredgecolor="black",
            markeredgewidth=1.5,
            markersize=18,
            linestyle="none",
            label="grid optimum",
            zorder=5,
            clip_on=False,
        )
    else:
        mesh = ax.scatter(
            d["points"][:, 0],
            d["points"][:, 1],
            c=d["values"],
            cmap="viridis_r",
            norm=norm,
            s=14,
            linewidths=0,
        )
    fig.colorbar(
        mesh,
        ax=ax,
        label=f"real {o} cost per step{cost_unit(o)}" + (" (log scale)" if log else ""),
    )
    return d["kind"] == "landscape"


def _draw_best_designs(ax: Any, runs: Sequence[RunFacts]) -> set[str]:
    """Each method's best designs (one per seed) of the panel's `runs` as hollow markers, in
    the tables' order; returns the methods drawn."""
    drawn = set()
    keys = group_order([(f.method, f.optimizer) for f in runs if f.best_design])
    for rank, (m, opt) in enumerate(keys):
        pts = np.array(
            [
                f.best_design[:2]
                for f in runs
                if (f.method, f.optimizer) == (m, opt) and f.best_design
            ]
        )
        ax.scatter(
            pts[:, 0],
            pts[:, 1],
            marker=METHOD_MARKERS.get(m, "x"),
            s=200 - 30 * min(rank, 4),
            facecolors="none",
            edgecolors=METHOD_COLORS.get(m, "black"),
            linewidths=2.0,
            label=method_label(m, opt),
            zorder=3 + 0.1 * rank,
            clip_on=False,
        )
        drawn.add(m)
    return drawn


def _heatmap_caption(
    t: str, names: Sequence[str], kinds: set[str], drew_methods: set[str], drew_star: bool
) -> str:
    """What a heat-map shows: the panels' kinds (grid or dots) and the markers drawn."""
    what = []
    if "landscape" in kinds:
        what.append("a landscape run's grid of real costs (one cell per evaluated design)")
    if "scatter" in kinds:
        what.append(
            "every real evaluation of the runs as a dot coloured by its cost"
            + (" (motor types differ between dots)" if len(names) > 2 else "")
        )
    caption = (
        f"Real cost on {t} terrain over ({names[0]}, {names[1]}); lighter = lower cost. "
        "Panels show " + " and ".join(what) + "."
    )
    if drew_methods:
        caption += " Hollow markers: each method's best design, one per seed."
    if drew_star:
        caption += " Star: the landscape grid's lowest cost."
    return caption
