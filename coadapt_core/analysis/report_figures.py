"""The report's figures: convergence curves, surrogate error and the runs' videos, each a
list of (PNG path, caption); the heat-maps are `heatmap_figure`, the Pareto fronts
`pareto_figure`. `optimizer_style` gives every figure the same line per optimizer."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import (
    METHOD_COLORS,
    METHOD_LABELS,
    METHOD_MARKERS,
    TERRAIN_ORDER,
    RunFacts,
    objective_order,
)
from coadapt_core.analysis.figures import (
    cost_unit,
    panel_grid,
    pyplot,
    save_figure,
    spans_decades,
    tidy_axes,
)
from coadapt_core.analysis.tables import group_order, method_label, optimizer_order, ordered
from coadapt_core.methods import METHOD_NAMES
from coadapt_core.results.rows import run_folder_of
from coadapt_core.results.schema import LANDSCAPE_METHOD
from coadapt_core.results.store import ResultsStore

LINESTYLES = ("-", (0, (5, 2)), (0, (3, 1, 1, 1)), (0, (1, 1.2)))


def optimizer_style(name: str) -> tuple[Any, bool]:
    """(line style, marker filled) of an optimizer: by its place in `optimizer_order`, styles
    in turn and every second one filled."""
    order = optimizer_order()
    i = order.index(name) if name in order else len(order)
    return LINESTYLES[i % len(LINESTYLES)], i % 2 == 1


def convergence_series(store: ResultsStore, f: RunFacts) -> tuple[np.ndarray, np.ndarray]:
    """(cumulative interactions [k], best real cost so far [k]) in recording order: training
    phases add their steps, each real evaluation its interactions."""
    first = f.run["objectives"][0]
    events = [(t["created_at"], int(t["steps"]), None) for t in store.training(f.run["id"])]
    events += [(e.created_at, e.interactions, e.costs.get(first)) for e in f.real]
    events.sort(key=lambda x: x[0])
    total, best, xs, ys = 0, math.inf, [], []
    for _, inter, cost in events:
        total += inter
        if cost is not None and math.isfinite(cost):
            best = min(best, cost)
            xs.append(total)
            ys.append(best)
    return np.array(xs, dtype=float), np.array(ys, dtype=float)


def figure_convergence(
    store: ResultsStore, facts: Sequence[RunFacts], out: Path
) -> list[tuple[Path, str]]:
    plt = pyplot()
    runs = [f for f in facts if f.method != LANDSCAPE_METHOD and f.real and "," not in f.objective]
    objectives = objective_order()
    keys = sorted(
        {(f.objective, f.terrain) for f in runs},
        key=lambda k: (objectives.index(k[0]) if k[0] in objectives else 9, k[1]),
    )
    if not keys:
        return []
    series = {f.run["id"]: convergence_series(store, f) for f in runs}
    most = max((x.max(initial=0.0) for x, _ in series.values()), default=0.0)
    unit, unit_name = (1e6, "million") if most >= 1e5 else (1e3, "thousand")
    fig, axes = panel_grid(plt, len(keys))
    groups = group_order([(f.method, f.optimizer) for f in runs])
    for ax, (o, t) in zip(axes, keys, strict=True):
        for m, opt in groups:
            for f in runs:
                if (f.method, f.optimizer, f.objective, f.terrain) != (m, opt, o, t):
                    continue
                x, y = series[f.run["id"]]
                if len(x) == 0:
                    continue
                _draw_curve(ax, f, x, y, unit, opt)
        ax.set_xlabel(f"environment interactions ({unit_name})")
        ax.set_ylabel(f"{o} cost per step{cost_unit(o, [f.summary for f in runs])}")
        if spans_decades([y for _, ys in series.values() for y in ys]):
            ax.set_yscale("log")
        ax.set_title(f"{o} on {t}", fontsize=10)
        tidy_axes(ax)
    _method_legend(fig, groups, _reading_handles())
    return save_figure(
        plt,
        fig,
        out / "convergence.png",
        "Convergence: best in-run estimate of the real cost found so far against environment "
        "interactions spent (training + real evaluation), one line per run; colour and marker "
        "shape = method, line style and marker fill = optimizer; the marker sits at the run's "
        "last evaluation. The square after it is the final check: the run's returned design "
        "re-evaluated on fresh paired scenarios, +- its standard error (the number the run "
        "reports). It sits above the curve because the in-run estimates come from fewer "
        "scenarios, the run's own, and the lowest of many noisy estimates is biased low by its "
        "selection. The dotted line is the nominal design's cost in the same final check.",
        layout=False,
    )


def _reading_handles() -> list[Any]:
    """Legend entries that say what each mark of a convergence panel is."""
    from matplotlib.lines import Line2D

    grey = "0.35"
    return [
        Line2D([], [], color=grey, label="in-run best (own scenarios, biased low)"),
        Line2D(
            [],
            [],
            color=grey,
            marker="s",
            markerfacecolor="white",
            linestyle="none",
            label="final check +- SE (fresh scenarios)",
        ),
        Line2D([], [], color=grey, linestyle=":", label="nominal design (final check)"),
    ]


def _draw_curve(ax: Any, f: RunFacts, x: np.ndarray, y: np.ndarray, unit: float, opt: str) -> None:
    """One run's convergence: the best cost so far as a step line, a marker at its last
    evaluation (colour and shape: method; line style and fill: optimizer), its final check."""
    color = METHOD_COLORS.get(f.method, "black")
    ax.step(
        x / unit,
        y,
        where="post",
        color=color,
        alpha=0.85,
        linewidth=1.6,
        linestyle=optimizer_style(opt)[0],
    )
    ax.plot(
        x[-1:] / unit,
        y[-1:],
        marker=METHOD_MARKERS.get(f.method, "x"),
        markersize=7,
        color=color,
        markerfacecolor=color if optimizer_style(opt)[1] else "none",
        linestyle="none",
    )
    _final_check_bar(ax, f, x[-1], unit, color)
    if f.nominal_cost is not None and math.isfinite(f.nominal_cost):
        ax.axhline(f.nominal_cost, color=color, linestyle=":", linewidth=1.2, alpha=0.9)


def _method_legend(fig: Any, groups: Sequence[tuple[str, str]], extra: Sequence[Any] = ()) -> None:
    """One legend for the whole figure, in the tables' order: the same in every panel;
    `extra` handles (what each mark is) after the methods."""
    from matplotlib.lines import Line2D

    handles = [
        Line2D(
            [],
            [],
            color=METHOD_COLORS.get(m, "black"),
            linestyle=optimizer_style(opt)[0],
            marker=METHOD_MARKERS.get(m, "x"),
            markerfacecolor=METHOD_COLORS.get(m, "black") if optimizer_style(opt)[1] else "none",
            label=method_label(m, opt),
        )
        for m, opt in groups
    ]
    handles += list(extra)
    # the marks' entries are long: one column on a one-panel figure
    ncol = (1 if fig.get_figwidth() < 6 else 2) if extra else min(3, len(handles))
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.06 + 0.035 * math.ceil(len(handles) / ncol), 1, 1))


def _final_check_bar(ax: Any, f: RunFacts, x_end: float, unit: float, color: Any) -> None:
    """The run's final-check cost of its returned design (+- its SE), after the in-run curve."""
    cost, se = f.summary.get("best_cost"), f.summary.get("best_cost_se")
    if not isinstance(cost, int | float) or not math.isfinite(cost):
        return
    x = (x_end + float(f.summary.get("final_interactions") or 0)) / unit
    err = se if isinstance(se, int | float) and math.isfinite(se) else None
    ax.errorbar(
        [x],
        [cost],
        yerr=None if err is None else [err],
        fmt="s",
        color=color,
        markerfacecolor="white",
        markersize=6,
        capsize=3,
        linewidth=1.2,
    )


def figure_surrogate_error(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    """Relative surrogate error against the real cost of the same design, one panel per
    objective and terrain (costs of different terrains differ by orders of magnitude)."""
    plt = pyplot()
    series: dict[tuple[str, str], list[tuple[float, float, str]]] = defaultdict(list)
    for f in facts:
        for e in f.real:
            for o, err in (e.surrogate_error or {}).items():
                real = e.costs.get(o)
                if real is not None and math.isfinite(real) and real != 0:
                    series[(o, f.terrain)].append((real, err / abs(real), f.method))
    if not series:
        return []
    objectives = objective_order()
    keys = sorted(
        series,
        key=lambda k: (
            objectives.index(k[0]) if k[0] in objectives else 9,
            TERRAIN_ORDER.index(k[1]) if k[1] in TERRAIN_ORDER else 9,
        ),
    )
    fig, axes = panel_grid(plt, len(keys))
    for ax, key in zip(axes, keys, strict=True):
        pts = series[key]
        for m in ordered({p[2] for p in pts}, METHOD_NAMES):
            xy = np.array([(p[0], 100 * p[1]) for p in pts if p[2] == m])
            ax.scatter(
                xy[:, 0],
                xy[:, 1],
                s=30,
                facecolors="none",
                linewidths=1.2,
                edgecolors=METHOD_COLORS.get(m, "black"),
                marker=METHOD_MARKERS.get(m, "x"),
                label=METHOD_LABELS.get(m, m),
            )
        ax.axhline(0.0, color="grey", linewidth=0.8)
        errs = np.array([100 * p[1] for p in pts])
        reals = np.array([p[0] for p in pts])
        if spans_decades(reals):
            ax.set_xscale("log")
        finite = np.isfinite(errs)
        if finite.any():
            lo, hi = np.percentile(errs[finite], [1, 99])
            pad = 0.1 * max(hi - lo, 1.0)
            ax.set_ylim(
                min(lo, 0.0) - pad, max(hi, 0.0) + pad
            )  # a few diverged points do not squash the rest
        clipped = int((finite & ((errs < ax.get_ylim()[0]) | (errs > ax.get_ylim()[1]))).sum())
        mean_abs = f"{np.abs(errs[finite]).mean():.3g} %" if finite.any() else "n/a"
        notes = (f", {clipped} off-scale" if clipped else "") + (
            f", {int((~finite).sum())} NaN" if not finite.all() else ""
        )
        ax.set_title(
            f"{key[0]} on {key[1]}: mean |error| {mean_abs}\n({int(finite.sum())} designs{notes})",
            fontsize=9,
        )
        ax.set_xlabel(f"real {key[0]} cost per step{cost_unit(key[0])}")
        ax.set_ylabel("(surrogate − real) / |real|  [%]")
        ax.legend(fontsize=7)
        tidy_axes(ax)
    return save_figure(
        plt,
        fig,
        out / "surrogate_error.png",
        "Pseudo-critic surrogate error relative to the real cost of the same design (paper Fig. "
        "4, right), one panel per objective and terrain. Sign: (surrogate − real) / |real|, so a "
        "point above the zero line is a design the surrogate scored worse (costlier) than it is; "
        "below, better.",
    )


def figure_videos(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    """Copy each run's best-vs-nominal video (written by `coadapt run`) next to the report."""
    import shutil

    written = []
    for f in facts:
        run_dir = run_folder_of(f.run)  # None for a row whose id or folder is not trustworthy
        if run_dir is None or f.method == LANDSCAPE_METHOD:
            continue
        for name in ("best_vs_nominal.gif",):
            src = run_dir / name
            if src.is_file() and not src.is_symlink():
                dst = out / f"video_{f.run['id']}.gif"
                shutil.copyfile(src, dst)
                written.append(
                    (
                        dst,
                        f"Run {f.run['id']} ({method_label(f.method, f.optimizer)}, {f.objective} "
                        f"on {f.terrain}): the best design (left) and the nominal design (right) "
                        "walking with the run's final policy.",
                    )
                )
    return written[:12]
