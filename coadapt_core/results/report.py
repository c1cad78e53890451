"""Reports from the store: the paper's Table 6 (best design, improvement, sim-to-sim
improvement per objective x method x terrain) and Table 7 (interactions and wall clock per
method) as Markdown and CSV, Fig. 6-style cost heat-maps, convergence curves, surrogate
error and Pareto fronts as PNG, and one report.html holding them all."""

from __future__ import annotations

import csv
import html
import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.errors import UserError
from coadapt_core.results.backends import (
    BackendFactory,
    BackendUnavailable,
    nominal_design,
    run_request,
    universal_policy_backend,
)
from coadapt_core.results.grid import METHODS
from coadapt_core.results.landscape import LANDSCAPE_METHOD
from coadapt_core.results.store import Evaluation, ResultsStore

#: the paper's row labels
METHOD_LABELS = {
    "ours": "Ours",
    "no-surrogate": "Ours w/o Surrogate",
    "no-real": "Ours w/o Real",
    "no-retrain": "Ours w/o Retraining",
    "bo-specialized": "BO",
}
OBJECTIVE_LABELS = {"tracking": "Cmd", "power": "P", "torque": "τ"}
TERRAIN_ORDER = ("flat", "slope", "random")
#: sim2sim rows are stored with this outer index: they belong to no iteration of the run
TRANSFER_OUTER = -1


@dataclass
class RunFacts:
    """What the tables need from one finished run, read from the store."""

    run: dict[str, Any]
    best_design: list[float] | None
    best_cost: float | None
    nominal_cost: float | None
    improvement: float | None
    train_interactions: int
    eval_interactions: int
    train_seconds: float
    eval_seconds: float
    designs_real: int
    designs_surrogate: int
    real: list[Evaluation] = field(default_factory=list)
    sim2sim: float | None = None
    sim2sim_note: str = ""

    @property
    def method(self) -> str:
        return self.run["method"]

    @property
    def objective(self) -> str:
        return ",".join(self.run["objectives"])

    @property
    def terrain(self) -> str:
        return self.run["terrain"] or "flat"


def select_runs(store: ResultsStore, selection: str | None) -> tuple[list[dict[str, Any]], str]:
    """Runs named by a grid id, a run id, or (None) every finished run; landscape runs are
    not part of the selection (they are looked up per objective and terrain)."""
    if selection is None:
        runs = store.list_runs(status="finished")
        title = "all finished runs"
    elif store.get_grid(selection) is not None:
        ids = {c["run_id"] for c in store.cells(selection).values() if c["run_id"]}
        runs = [r for r in store.list_runs(run_ids=sorted(ids)) if r["status"] == "finished"]
        title = f"grid {selection}"
    elif store.has_run(selection):
        runs = [store.get_run(selection)]
        title = f"run {selection}"
    else:
        grids = ", ".join(store.list_grids()[-3:]) or "none"
        raise UserError(
            f"'{selection}' is neither a run nor a grid in store {store.url} (recent grids: {grids})",
            field="run",
        )
    runs = [r for r in runs if r["method"] != LANDSCAPE_METHOD or selection is not None]
    if not runs:
        raise UserError(f"no finished runs to report in {title} of store {store.url}", field="run")
    return runs, title


def run_facts(store: ResultsStore, run: dict[str, Any]) -> RunFacts:
    evals = store.evaluations(run["id"])
    real = [e for e in evals if e.kind == "real"]
    surrogate = [e for e in evals if e.kind == "surrogate"]
    first = run["objectives"][0] if run["objectives"] else None
    summary = run["summary"] or {}
    best_design = summary.get("best_design")
    best_cost = summary.get("best_cost")
    if (best_design is None or best_cost is None) and real and first:
        best = min(real, key=lambda e: e.costs.get(first, math.inf))
        best_design, best_cost = best.design, best.costs.get(first)
    training = store.training(run["id"])
    return RunFacts(
        run=run,
        best_design=None if best_design is None else [float(x) for x in np.ravel(best_design)],
        best_cost=None if best_cost is None or isinstance(best_cost, list) else float(best_cost),
        nominal_cost=_float(summary.get("nominal_cost")),
        improvement=_float(summary.get("improvement")),
        train_interactions=int(sum(t["steps"] for t in training)),
        eval_interactions=int(sum(e.interactions for e in real)),
        train_seconds=float(sum(t["seconds"] for t in training)),
        eval_seconds=float(sum(e.seconds for e in real) + sum(e.seconds for e in surrogate)),
        designs_real=len(real),
        designs_surrogate=len(surrogate),
        real=real,
    )


def _float(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


# -- sim-to-sim (Table 6's last column) ---------------------------------------------------------
def sim_to_sim(
    store: ResultsStore,
    facts: RunFacts,
    *,
    simulator: str = "pybullet",
    agents: int = 8,
    steps: int = 400,
    factory: BackendFactory | None = None,
) -> tuple[float | None, str]:
    """Improvement of the best design over the nominal one when the run's final policy is
    evaluated on `simulator` (the paper transfers Isaac Gym -> PyBullet; we transfer the
    run's simulator -> PyBullet). Stored as kind "sim2sim" rows (idx 0 best, 1 nominal) and
    read back on later reports. Returns (improvement, note); improvement None = n/a."""
    run = facts.run
    if not run["objectives"] or facts.best_design is None:
        return None, "n/a: the run has no best design"
    first = run["objectives"][0]
    cached = [e for e in store.evaluations(run["id"], kind="sim2sim") if e.simulator == simulator]
    if len(cached) < 2:
        if run.get("simulator") == simulator:
            return None, f"n/a: the run itself used {simulator}"
        checkpoints = store.checkpoints(run["id"])
        checkpoint = (run["summary"] or {}).get("checkpoint") or (checkpoints[-1]["path"] if checkpoints else None)
        if checkpoint is None:
            return None, "n/a: the run recorded no policy checkpoint"
        if not Path(checkpoint).is_absolute() and run.get("run_dir"):
            # older rows hold paths relative to the folder the run was started from
            checkpoint = str(Path(run["run_dir"]).resolve().parent.parent / checkpoint)
        if not Path(checkpoint).exists():
            return None, f"n/a: checkpoint {checkpoint} is gone"
        try:
            backend, objectives = (factory or universal_policy_backend)(
                run_request(run, simulator=simulator, checkpoint=checkpoint, agents=agents)
            )
            best = np.asarray(facts.best_design, dtype=float)
            nominal = nominal_design(run_request(run).robot, best.shape[0])
            fit = backend.real_fitness(np.stack([best, nominal]), objectives, agents=agents, steps=steps, seed=int(run["seed"] or 0))
        except BackendUnavailable as exc:
            return None, f"n/a: {exc}"
        costs = np.asarray(fit.costs, dtype=float).reshape(2, -1)  # [2, M]
        names = [o.name for o in objectives]
        store.record_evaluations(
            run["id"],
            [
                {"outer": TRANSFER_OUTER, "inner": 0, "idx": i, "kind": "sim2sim", "design": d.tolist(),
                 "costs": dict(zip(names, costs[i].tolist(), strict=True)), "interactions": fit.interactions // 2,
                 "seconds": fit.seconds / 2, "simulator": simulator}
                for i, d in enumerate((best, nominal))
            ],
        )
        cached = [e for e in store.evaluations(run["id"], kind="sim2sim") if e.simulator == simulator]
    by_idx = {e.idx: e for e in cached}
    best_cost, nominal_cost = by_idx[0].costs[first], by_idx[1].costs[first]
    from coadapt_core.results.backends import objective_instances

    try:
        (objective,) = objective_instances([first])
        value = objective.improvement(best_cost, nominal_cost)
    except Exception:
        value = (nominal_cost - best_cost) / abs(nominal_cost) if nominal_cost else 0.0
    return float(value), f"{simulator}, {len(cached)} designs"


# -- tables ------------------------------------------------------------------------------------
def _ordered(values: Sequence[str], order: Sequence[str]) -> list[str]:
    known = [v for v in order if v in values]
    return known + sorted(v for v in set(values) if v not in order)


def _mean(values: Sequence[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals else None


def table6_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per objective x method x terrain, means over seeds."""
    groups: dict[tuple[str, str, str], list[RunFacts]] = defaultdict(list)
    for f in facts:
        if f.method != LANDSCAPE_METHOD:
            groups[(f.objective, f.method, f.terrain)].append(f)
    rows = []
    objectives = _ordered([k[0] for k in groups], list(OBJECTIVE_LABELS))
    methods = _ordered([k[1] for k in groups], METHODS)
    terrains = _ordered([k[2] for k in groups], TERRAIN_ORDER)
    for o in objectives:
        for m in methods:
            for t in terrains:
                group = groups.get((o, m, t))
                if not group:
                    continue
                designs = [f.best_design for f in group if f.best_design is not None]
                notes = sorted({f.sim2sim_note for f in group if f.sim2sim is None and f.sim2sim_note})
                rows.append(
                    {
                        "objective": o,
                        "method": m,
                        "terrain": t,
                        "runs": len(group),
                        "thigh": _mean([d[0] for d in designs]),
                        "shank": _mean([d[1] for d in designs if len(d) > 1]),
                        "best_cost": _mean([f.best_cost for f in group]),
                        "nominal_cost": _mean([f.nominal_cost for f in group]),
                        "improvement": _mean([f.improvement for f in group]),
                        "sim2sim_improvement": _mean([f.sim2sim for f in group]),
                        "sim2sim_note": "; ".join(notes),
                        "run_ids": " ".join(f.run["id"] for f in group),
                    }
                )
    return rows


def table7_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per method, means over its runs (the paper reports averages). A run with
    another optimizer than PSO (NSGA-II, mixed PSO) gets a row of its own, "ours [nsga2]":
    its costs are not the method's."""
    groups: dict[str, list[RunFacts]] = defaultdict(list)
    for f in facts:
        if f.method != LANDSCAPE_METHOD:
            groups[_method_key(f)].append(f)
    rows = []
    for m in _ordered(list(groups), METHODS):
        g = groups[m]
        rows.append(
            {
                "method": m,
                "runs": len(g),
                "interactions_training": float(np.mean([f.train_interactions for f in g])),
                "interactions_evaluation": float(np.mean([f.eval_interactions for f in g])),
                "seconds_training": float(np.mean([f.train_seconds for f in g])),
                "seconds_evaluation": float(np.mean([f.eval_seconds for f in g])),
                "designs_real": float(np.mean([f.designs_real for f in g])),
                "designs_surrogate": float(np.mean([f.designs_surrogate for f in g])),
            }
        )
    return rows


def _method_key(f: RunFacts) -> str:
    optimizer = f.run.get("optimizer")
    if f.method == "bo-specialized" or optimizer in (None, "", "pso"):
        return f.method
    return f"{f.method} [{optimizer}]"


def _label(method_key: str) -> str:
    method, _, rest = method_key.partition(" ")
    return f"{METHOD_LABELS.get(method, method)} {rest}".strip()


def _fmt(value: float | None, spec: str = ".2f", pct: bool = False) -> str:
    if value is None:
        return "n/a"
    return f"{100 * value:.1f}%" if pct else format(value, spec)


def table6_markdown(rows: Sequence[dict[str, Any]]) -> str:
    terrains = _ordered([r["terrain"] for r in rows], TERRAIN_ORDER)
    index = {(r["objective"], r["method"], r["terrain"]): r for r in rows}
    head = "| Objective | Method | " + " | ".join(
        f"{t.title()} thigh | {t.title()} shank | {t.title()} improvement | {t.title()} sim-to-sim" for t in terrains
    ) + " |"
    lines = [head, "|" + "---|" * (2 + 4 * len(terrains))]
    seen: list[tuple[str, str]] = []
    for r in rows:
        if (r["objective"], r["method"]) not in seen:
            seen.append((r["objective"], r["method"]))
    previous = None
    for o, m in seen:
        cells = [OBJECTIVE_LABELS.get(o, o) if o != previous else "", METHOD_LABELS.get(m, m)]
        previous = o
        for t in terrains:
            r = index.get((o, m, t))
            if r is None:
                cells += ["", "", "", ""]
            else:
                cells += [_fmt(r["thigh"]), _fmt(r["shank"]), _fmt(r["improvement"], pct=True), _fmt(r["sim2sim_improvement"], pct=True)]
        lines.append("| " + " | ".join(cells) + " |")
    notes = sorted({r["sim2sim_note"] for r in rows if r["sim2sim_improvement"] is None and r["sim2sim_note"]})
    if notes:
        lines += ["", "Sim-to-sim: " + "; ".join(notes) + "."]
    return "\n".join(lines) + "\n"


def table7_units(rows: Sequence[dict[str, Any]]) -> tuple[float, str, float, str]:
    """Interaction and time units: the paper's millions and hours, smaller ones when a
    table of smoke runs would print only zeros."""
    most_inter = max((r["interactions_training"] + r["interactions_evaluation"] for r in rows), default=0)
    most_sec = max((r["seconds_training"] + r["seconds_evaluation"] for r in rows), default=0)
    inter = (1e6, "million") if most_inter >= 1e5 else (1e3, "thousand")
    time_unit = (3600.0, "hour") if most_sec >= 360 else (60.0, "minute") if most_sec >= 6 else (1.0, "second")
    return inter[0], inter[1], time_unit[0], time_unit[1]


def table7_markdown(rows: Sequence[dict[str, Any]]) -> str:
    iu, iname, tu, tname = table7_units(rows)
    lines = [
        f"| Method | Interactions ({iname}, Training+Evaluation) | Wall clock time ({tname}, Training+Evaluation) | Designs evaluated (real+surrogate) | Runs |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        ti, ei = r["interactions_training"] / iu, r["interactions_evaluation"] / iu
        ts, es = r["seconds_training"] / tu, r["seconds_evaluation"] / tu
        lines.append(
            f"| {_label(r['method'])} | {ti + ei:.3g}({ti:.3g}+{ei:.3g}) | "
            f"{ts + es:.3g}({ts:.3g}+{es:.3g}) | {r['designs_real'] + r['designs_surrogate']:.0f}"
            f"({r['designs_real']:.0f}+{r['designs_surrogate']:.0f}) | {r['runs']} |"
        )
    return "\n".join(lines) + "\n"


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    columns = list(rows[0]) if rows else []
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: ("" if v is None else repr(v) if isinstance(v, float) else v) for k, v in r.items()})


# -- figures ------------------------------------------------------------------------------------
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only; no display on CI or cluster nodes
    import matplotlib.pyplot as plt

    return plt


def _spans_decades(values: Any, decades: float = 3.0) -> bool:
    """True when positive finite values spread over more than `decades` orders of magnitude:
    one diverged rollout (cost 1e10 next to 1e3) would flatten a linear axis, so such axes
    go logarithmic."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return v.size > 1 and bool((v > 0).all()) and float(v.max() / v.min()) > 10**decades


METHOD_MARKERS = {"ours": "o", "no-surrogate": "s", "no-real": "^", "no-retrain": "D", "bo-specialized": "P"}
METHOD_COLORS = {"ours": "tab:red", "no-surrogate": "tab:blue", "no-real": "tab:green", "no-retrain": "tab:purple",
                 "bo-specialized": "tab:orange"}
#: methods that share a seed share their first rounds: distinct dashes keep every curve visible
METHOD_LINESTYLES = {"ours": "-", "no-surrogate": (0, (5, 2)), "no-real": (0, (1, 1.5)), "no-retrain": "-.",
                     "bo-specialized": (0, (3, 1, 1, 1, 1, 1))}


def _landscape_for(store: ResultsStore, objective: str, terrain: str) -> dict[str, Any] | None:
    found = [
        r
        for r in store.list_runs(method=LANDSCAPE_METHOD, terrain=terrain, status="finished")
        if r["objectives"] and objective in r["objectives"]
    ]
    return found[-1] if found else None


def heatmap_data(
    store: ResultsStore, facts: Sequence[RunFacts], objective: str, terrain: str, resolution: int = 41
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str, np.ndarray | None] | None:
    """(thigh axis [n], shank axis [n], cost [n, n] indexed [shank, thigh], source label,
    grid optimum [2] or None) for one objective and terrain."""
    land = _landscape_for(store, objective, terrain)
    if land is not None:
        rows = store.evaluations(land["id"], kind="real")
        pts = np.array([e.design[:2] for e in rows])  # [n*n, 2]
        vals = np.array([e.costs[objective] for e in rows])
        a, b = np.unique(pts[:, 0]), np.unique(pts[:, 1])
        grid = np.full((len(b), len(a)), np.nan)
        for (x, y), v in zip(pts, vals, strict=True):
            grid[np.searchsorted(b, y), np.searchsorted(a, x)] = v
        optimum = pts[int(np.argmin(vals))]
        return a, b, grid, f"landscape run {land['id']} ({len(a)}x{len(b)} real evaluations)", optimum
    pts, vals = [], []
    for f in facts:
        if f.objective == objective and f.terrain == terrain:
            for e in f.real:
                if objective in e.costs and len(e.design) >= 2:
                    pts.append(e.design[:2])
                    vals.append(e.costs[objective])
    if len(pts) < 4:
        return None
    from scipy.interpolate import griddata

    pts_arr, vals_arr = np.array(pts), np.array(vals)
    a = np.linspace(0.5, 1.5, resolution)
    b = np.linspace(0.5, 1.5, resolution)
    aa, bb = np.meshgrid(a, b)  # [n, n] indexed [shank, thigh]
    try:
        grid = griddata(pts_arr, vals_arr, (aa, bb), method="linear")
    except Exception:  # degenerate (collinear) samples
        grid = np.full(aa.shape, np.nan)
    near = griddata(pts_arr, vals_arr, (aa, bb), method="nearest")
    grid = np.where(np.isnan(grid), near, grid)
    return a, b, grid, f"interpolated from {len(pts)} real evaluations of the runs (not a landscape run)", None


def figure_heatmaps(store: ResultsStore, facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    """One PNG per terrain, one panel per objective (Fig. 6 shows flat, three objectives)."""
    plt = _pyplot()
    written = []
    objectives = _ordered([f.objective for f in facts if f.method != LANDSCAPE_METHOD], list(OBJECTIVE_LABELS))
    objectives = [o for o in objectives if "," not in o]  # multi-objective runs have a Pareto front instead
    terrains = _ordered([f.terrain for f in facts], TERRAIN_ORDER)
    for t in terrains:
        panels = [(o, heatmap_data(store, facts, o, t)) for o in objectives]
        panels = [(o, d) for o, d in panels if d is not None]
        if not panels:
            continue
        fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 5.2), squeeze=False)
        sources = []
        for ax, (o, (a, b, grid, source, optimum)) in zip(axes[0], panels, strict=True):
            # lighter = lower cost, as in the paper's heat-maps
            log = _spans_decades(grid)
            norm = None
            if log:
                from matplotlib.colors import LogNorm

                norm = LogNorm(vmin=float(np.nanmin(grid)), vmax=float(np.nanmax(grid)))
            mesh = ax.pcolormesh(a, b, grid, cmap="viridis_r", norm=norm, shading="nearest" if len(a) < 20 else "gouraud")
            fig.colorbar(mesh, ax=ax, label=f"{o} cost" + (" (log scale)" if log else ""))
            if optimum is not None:  # hollow, on top, so a method's marker under it stays visible
                ax.plot(*optimum, marker="*", markerfacecolor="none", markeredgecolor="black", markeredgewidth=1.5,
                        markersize=22, linestyle="none", label="grid optimum", zorder=5, clip_on=False)
            methods = _ordered({f.method for f in facts if f.objective == o and f.terrain == t and f.best_design} - {LANDSCAPE_METHOD}, METHODS)
            for rank, m in enumerate(methods):
                pts = np.array([f.best_design[:2] for f in facts if f.method == m and f.objective == o and f.terrain == t and f.best_design])
                # hollow, shrinking markers: methods that found the same design show as nested outlines
                ax.scatter(pts[:, 0], pts[:, 1], marker=METHOD_MARKERS.get(m, "x"), s=320 - 60 * rank, facecolors="none",
                           edgecolors=METHOD_COLORS.get(m, "black"), linewidths=2.2, label=METHOD_LABELS.get(m, m), zorder=3 + 0.1 * rank,
                           clip_on=False)  # optima often sit on the range's edge
            ax.set_xlim(0.5, 1.5)
            ax.set_ylim(0.5, 1.5)
            ax.set_xlabel("thigh scale")
            ax.set_ylabel("shank scale")
            ax.set_title(f"{o} on {t}" + (" (landscape)" if optimum is not None else " (interpolated)"))
            # below the panel, so it hides no part of the map
            ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=3, fontsize=7, frameon=False)
            sources.append(f"{o}: {source}")
        fig.tight_layout()
        path = out / f"heatmap_{t}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append((path, f"Cost heat-maps on {t} terrain over (thigh, shank) scales; lighter = lower cost; "
                              f"markers: each method's best design (one per seed); star: the landscape grid optimum. Sources: "
                              + "; ".join(sources) + "."))
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
        if cost is not None:
            best = min(best, cost)
            xs.append(total)
            ys.append(best)
    return np.array(xs, dtype=float), np.array(ys, dtype=float)


def figure_convergence(store: ResultsStore, facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    plt = _pyplot()
    keys = sorted({(f.objective, f.terrain) for f in facts if f.method != LANDSCAPE_METHOD and f.real and "," not in f.objective},
                  key=lambda k: (list(OBJECTIVE_LABELS).index(k[0]) if k[0] in OBJECTIVE_LABELS else 9, k[1]))
    if not keys:
        return []
    most = max((convergence_series(store, f)[0].max(initial=0.0) for f in facts if f.real), default=0.0)
    unit, unit_name = (1e6, "million") if most >= 1e5 else (1e3, "thousand")
    cols = min(3, len(keys))
    rows = math.ceil(len(keys) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.8 * rows), squeeze=False)
    for ax, (o, t) in zip(axes.ravel(), keys, strict=False):
        labelled = set()
        for f in facts:
            if f.objective != o or f.terrain != t or f.method == LANDSCAPE_METHOD:
                continue
            x, y = convergence_series(store, f)
            if len(x) == 0:
                continue
            label = None if f.method in labelled else METHOD_LABELS.get(f.method, f.method)
            labelled.add(f.method)
            ax.step(x / unit, y, where="post", color=METHOD_COLORS.get(f.method, "black"), label=label, alpha=0.85,
                    linestyle=METHOD_LINESTYLES.get(f.method, "-"), linewidth=1.8)
        ax.set_xlabel(f"environment interactions ({unit_name})")
        ax.set_ylabel(f"best real {o} cost")
        if _spans_decades([y for line in ax.get_lines() for y in line.get_ydata()]):
            ax.set_yscale("log")
        ax.set_title(f"{o} on {t}")
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(keys):]:
        ax.axis("off")
    fig.tight_layout()
    path = out / "convergence.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [(path, "Convergence: best real cost found so far against environment interactions spent "
                   "(training + real evaluation), one line per run, coloured by method.")]


def figure_surrogate_error(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    """Surrogate error against real cost, for every real evaluation whose design the
    surrogate also scored."""
    plt = _pyplot()
    series: dict[str, list[tuple[float, float, str]]] = defaultdict(list)
    for f in facts:
        for e in f.real:
            for o, err in (e.surrogate_error or {}).items():
                if o in e.costs:
                    series[o].append((e.costs[o], err, f.method))
    if not series:
        return []
    fig, axes = plt.subplots(1, len(series), figsize=(5.2 * len(series), 4.0), squeeze=False)
    for ax, (o, pts) in zip(axes[0], sorted(series.items()), strict=True):
        for m in _ordered({p[2] for p in pts}, METHODS):
            xy = np.array([(p[0], p[1]) for p in pts if p[2] == m])
            # hollow markers of different shapes: coinciding designs of two methods stay visible
            ax.scatter(xy[:, 0], xy[:, 1], s=36, facecolors="none", linewidths=1.2,
                       edgecolors=METHOD_COLORS.get(m, "black"), marker=METHOD_MARKERS.get(m, "x"),
                       label=METHOD_LABELS.get(m, m))
        ax.axhline(0.0, color="grey", linewidth=0.8)
        errs = np.array([p[1] for p in pts])
        reals = np.array([p[0] for p in pts])
        if _spans_decades(reals):
            ax.set_xscale("log")
        if _spans_decades(np.abs(errs[np.isfinite(errs) & (errs != 0)])):
            # errors change sign: symmetric log, linear within the smallest error's decade
            ax.set_yscale("symlog", linthresh=float(np.nanmin(np.abs(errs[np.isfinite(errs) & (errs != 0)]))))
        finite = np.isfinite(errs)
        mean_abs = f"{np.abs(errs[finite]).mean():.3g}" if finite.any() else "n/a"
        missing = f", {int((~finite).sum())} NaN not drawn" if not finite.all() else ""
        ax.set_title(f"{o}: mean |error| {mean_abs} ({int(finite.sum())} designs{missing})", fontsize=9)
        ax.set_xlabel(f"real {o} cost")
        ax.set_ylabel("surrogate error (as recorded by the run)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "surrogate_error.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [(path, "Pseudo-critic surrogate error against the real cost of the same design (paper Fig. 4, right); "
                   "zero line = exact prediction.")]


def pareto_mask(costs: np.ndarray) -> np.ndarray:
    """[n] True where no other row is at least as good in every cost and better in one."""
    n = costs.shape[0]
    mask = np.ones(n, dtype=bool)
    for i in range(n):
        dominated = np.all(costs <= costs[i], axis=1) & np.any(costs < costs[i], axis=1)
        mask[i] = not dominated.any()
    return mask


def figure_pareto(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    plt = _pyplot()
    multi = [f for f in facts if len(f.run["objectives"]) >= 2 and f.real]
    if not multi:
        return []
    multi = multi[:6]
    fig, axes = plt.subplots(1, len(multi), figsize=(5.2 * len(multi), 4.2), squeeze=False)
    for ax, f in zip(axes[0], multi, strict=True):
        o1, o2 = f.run["objectives"][:2]
        costs = np.array([[e.costs[o1], e.costs[o2]] for e in f.real if o1 in e.costs and o2 in e.costs])
        mask = pareto_mask(costs)
        ax.scatter(costs[~mask, 0], costs[~mask, 1], s=12, color="lightgrey", label="evaluated")
        front = costs[mask][np.argsort(costs[mask][:, 0])]
        ax.plot(front[:, 0], front[:, 1], "o-", color="tab:red", label=f"Pareto front ({mask.sum()})")
        ax.set_xlabel(f"{o1} cost")
        ax.set_ylabel(f"{o2} cost")
        if _spans_decades(costs[:, 0]):
            ax.set_xscale("log")
        if _spans_decades(costs[:, 1]):
            ax.set_yscale("log")
        ax.set_title(f"{f.run['id']}\n{f.run['optimizer'] or ''} on {f.terrain}", fontsize=8)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "pareto.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [(path, "Pareto fronts of multi-objective (NSGA-II) runs: every real evaluation in grey, the non-dominated ones in red.")]


# -- the whole report -------------------------------------------------------------------------
def _html_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]], pct: Sequence[str] = ()) -> str:
    head = "".join(f"<th>{html.escape(label)}</th>" for _, label in columns)
    body = []
    for r in rows:
        cells = []
        for key, _ in columns:
            v = r.get(key)
            text = _fmt(v, pct=True) if key in pct else (_fmt(v, ".4g") if isinstance(v, float) else str(v if v is not None else "n/a"))
            cells.append(f"<td>{html.escape(text)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def write_report(
    store: ResultsStore,
    selection: str | None,
    out_dir: str | Path,
    *,
    sim2sim: bool = True,
    transfer_simulator: str = "pybullet",
    transfer_agents: int = 8,
    transfer_steps: int = 400,
    backend_factory: BackendFactory | None = None,
) -> dict[str, Path]:
    """Tables (Markdown + CSV), figures (PNG) and report.html for `selection` (a grid id, a
    run id, or None for every finished run). Returns the files written by name."""
    runs, title = select_runs(store, selection)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    facts = [run_facts(store, r) for r in runs]
    for f in facts:
        if f.method == LANDSCAPE_METHOD:
            continue
        if sim2sim:
            f.sim2sim, f.sim2sim_note = sim_to_sim(
                store, f, simulator=transfer_simulator, agents=transfer_agents, steps=transfer_steps, factory=backend_factory
            )
        else:
            f.sim2sim, f.sim2sim_note = None, "n/a: not requested (--no-sim-to-sim)"
    t6, t7 = table6_rows(facts), table7_rows(facts)
    files: dict[str, Path] = {}
    for name, rows, md in (("table6", t6, table6_markdown(t6)), ("table7", t7, table7_markdown(t7))):
        write_csv(out / f"{name}.csv", rows)
        (out / f"{name}.md").write_text(md)
        files[f"{name}.csv"] = out / f"{name}.csv"
        files[f"{name}.md"] = out / f"{name}.md"
    figures = (
        figure_heatmaps(store, facts, out)
        + figure_convergence(store, facts, out)
        + figure_surrogate_error(facts, out)
        + figure_pareto(facts, out)
    )
    for path, _ in figures:
        files[path.name] = path
    iu, iname, tu, tname = table7_units(t7)
    t7_html_rows = [
        {**r, "inter_t": r["interactions_training"] / iu, "inter_e": r["interactions_evaluation"] / iu,
         "time_t": r["seconds_training"] / tu, "time_e": r["seconds_evaluation"] / tu,
         "method": _label(r["method"])}
        for r in t7
    ]
    t6_html_rows = [{**r, "method": METHOD_LABELS.get(r["method"], r["method"])} for r in t6]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>coadapt report</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:2em auto}table{border-collapse:collapse;margin:1em 0}"
        "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eee}img{max-width:100%}"
        "figcaption{color:#444;font-size:90%}</style></head><body>",
        f"<h1>coadapt report — {html.escape(title)}</h1>",
        f"<p>Store: <code>{html.escape(store.url)}</code>; {len(runs)} runs. Numbers are means over seeds.</p>",
        "<h2>Table 6 — optimization results</h2>",
        _html_table(t6_html_rows, [("objective", "objective"), ("method", "method"), ("terrain", "terrain"), ("runs", "runs"),
                                   ("thigh", "thigh"), ("shank", "shank"), ("best_cost", "best cost"),
                                   ("nominal_cost", "nominal cost"), ("improvement", "improvement"),
                                   ("sim2sim_improvement", "sim-to-sim improvement"), ("sim2sim_note", "sim-to-sim")],
                    pct=("improvement", "sim2sim_improvement")),
        "<h2>Table 7 — computational cost</h2>",
        _html_table(t7_html_rows, [("method", "method"), ("runs", "runs"), ("inter_t", f"interactions training ({iname})"),
                                   ("inter_e", f"interactions evaluation ({iname})"), ("time_t", f"wall clock training ({tname})"),
                                   ("time_e", f"wall clock evaluation ({tname})"), ("designs_real", "designs real"),
                                   ("designs_surrogate", "designs surrogate")]),
        "<h2>Figures</h2>",
    ]
    for path, caption in figures:
        parts.append(f"<figure><img src='{html.escape(path.name)}' alt='{html.escape(path.stem)}'>"
                     f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    if not figures:
        parts.append("<p>No figures: the selected runs recorded no real evaluations.</p>")
    parts.append("</body></html>")
    (out / "report.html").write_text("\n".join(parts))
    files["report.html"] = out / "report.html"
    return files
