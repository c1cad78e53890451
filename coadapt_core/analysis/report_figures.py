"""The report's figures: Fig. 6-style cost heat-maps, convergence curves, surrogate error,
Pareto fronts and the runs' videos, each a list of (PNG path, caption)."""

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
    PANEL_H,
    panel_grid,
    pyplot,
    save_figure,
    spans_decades,
    tidy_axes,
)
from coadapt_core.analysis.tables import group_order, method_label, optimizer_order, ordered
from coadapt_core.methods import METHOD_NAMES
from coadapt_core.pareto import pareto_mask
from coadapt_core.results.export import space_of_run
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
    from matplotlib.colors import LogNorm

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
            if not panels:
                continue
            fig, axes = panel_grid(plt, len(panels), height=PANEL_H + 0.6)
            sources, drew_star, drew_methods = [], False, set()
            for ax, (o, d) in zip(axes, panels, strict=True):
                values = d["grid"] if d["kind"] == "landscape" else d["values"]
                log = spans_decades(values)
                norm = (
                    LogNorm(vmin=float(np.nanmin(values)), vmax=float(np.nanmax(values)))
                    if log
                    else None
                )
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
                    drew_star = True
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
                fig.colorbar(mesh, ax=ax, label=f"real {o} cost" + (" (log scale)" if log else ""))
                keys = group_order(
                    [
                        (f.method, f.optimizer)
                        for f in runs
                        if f.objective == o
                        and f.terrain == t
                        and f.space_key == names
                        and f.best_design
                    ]
                )
                for rank, (m, opt) in enumerate(keys):
                    pts = np.array(
                        [
                            f.best_design[:2]
                            for f in runs
                            if (f.method, f.optimizer) == (m, opt)
                            and f.objective == o
                            and f.terrain == t
                            and f.space_key == names
                            and f.best_design
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
                    drew_methods.add(m)
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
            path = out / f"heatmap_{t}{suffix}.png"
            kinds = {d["kind"] for _, d in panels}
            what = []
            if "landscape" in kinds:
                what.append("a landscape run's grid of real costs (one cell per evaluated design)")
            if "scatter" in kinds:
                what.append(
                    "every real evaluation of the runs as a dot coloured by its cost"
                    + (" (motor types differ between dots)" if len(names) > 2 else "")
                )
            caption = (
                f"Real cost on {t} terrain over ({names[0]}, {names[1]}); lighter = lower cost. Panels show "
                + " and ".join(what)
                + "."
            )
            if drew_methods:
                caption += " Hollow markers: each method's best design, one per seed."
            if drew_star:
                caption += " Star: the landscape grid's lowest cost."
            written += save_figure(
                plt, fig, path, caption + " Sources: " + "; ".join(sources) + "."
            )
    return written


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
    from matplotlib.lines import Line2D

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
                color = METHOD_COLORS.get(m, "black")
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
                    marker=METHOD_MARKERS.get(m, "x"),
                    markersize=7,
                    color=color,
                    markerfacecolor=color if optimizer_style(opt)[1] else "none",
                    linestyle="none",
                )
                _final_check_bar(ax, f, x[-1], unit, color)
        ax.set_xlabel(f"environment interactions ({unit_name})")
        ax.set_ylabel(f"best in-run {o} cost so far\n(square: final check +- SE)")
        if spans_decades([y for _, ys in series.values() for y in ys]):
            ax.set_yscale("log")
        ax.set_title(f"{o} on {t}", fontsize=10)
        tidy_axes(ax)
    # one legend for the whole figure, in the tables' order: the same in every panel
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
    fig.legend(
        handles=handles, loc="lower center", ncol=min(3, len(handles)), fontsize=8, frameon=False
    )
    fig.tight_layout(rect=(0, 0.06 + 0.03 * math.ceil(len(handles) / 3), 1, 1))
    return save_figure(
        plt,
        fig,
        out / "convergence.png",
        "Convergence: best in-run estimate of the real cost found so far "
        "against environment interactions spent (training + real evaluation), one line per run; colour and "
        "marker shape = method, line style and marker fill = optimizer; the marker sits at the run's last "
        "evaluation. The error bar after it is the final check: the run's returned design re-evaluated on "
        "fresh paired scenarios, +- its standard error (the number the run reports; in-run estimates of "
        "the best design are biased low by its selection).",
        layout=False,
    )


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
        ax.set_xlabel(f"real {key[0]} cost")
        ax.set_ylabel("(surrogate − real) / |real|  [%]")
        ax.legend(fontsize=7)
        tidy_axes(ax)
    return save_figure(
        plt,
        fig,
        out / "surrogate_error.png",
        "Pseudo-critic surrogate error relative to the real cost of the same design (paper Fig. 4, "
        "right), one panel per objective and terrain. Sign: (surrogate − real) / |real|, so a point "
        "above the zero line is a design the surrogate scored worse (costlier) than it is; below, better.",
    )


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
        ax.set_xlabel(f"{o1} cost")
        ax.set_ylabel(f"{o2} cost")
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
        "Pareto fronts of multi-objective runs. Red: the front "
        f"({'; '.join(sorted(sources))}), each design with its final-check costs +- standard error and its "
        "index for `coadapt handoff RUN --pick N`; the same designs `coadapt run` printed and the store "
        "holds. Diamond: the design the run returns (Table 6's, the lowest first cost); cross: the nominal "
        "design in the same final check. Grey: the in-run "
        "estimates of the real rounds, on fewer and other scenarios than the final check, so noisier and, "
        "for the designs the optimizer kept, biased low by that selection: grey points below the front "
        "do not beat it. Title: the front's hypervolume +- SE (costs relative to the nominal design's, "
        "up to 2 in each; the nominal design alone has 1).",
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
                        f"Run {f.run['id']} ({method_label(f.method, f.optimizer)}, {f.objective} on "
                        f"{f.terrain}): the best design (left) and the nominal design (right) walking "
                        "with the run's final policy.",
                    )
                )
    return written[:12]
