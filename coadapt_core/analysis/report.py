"""Reports from the store: the paper's Table 6 (best design, improvement, sim-to-sim
improvement per objective x method x terrain) and Table 7 (interactions and wall clock per
method) as Markdown and CSV, Fig. 6-style cost heat-maps, convergence curves, surrogate
error and Pareto fronts as PNG, and one report.html holding them all."""

from __future__ import annotations

import csv
import html
import itertools
import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.figures import (
    PANEL_H,
    panel_grid,
    pyplot,
    save_figure,
    spans_decades,
    tidy_axes,
)
from coadapt_core.analysis.surrogate_figure import figure_surrogate_quality
from coadapt_core.errors import UserError
from coadapt_core.methods import METHOD_NAMES, METHODS
from coadapt_core.pareto import pareto_mask
from coadapt_core.results.export import space_of_run
from coadapt_core.results.store import (
    LANDSCAPE_METHOD,
    TRANSFER_KIND,
    Evaluation,
    ResultsStore,
    best_of,
    run_folder_of,
)

#: the paper's row labels, and each method's marker and colour in the figures (the method registry's)
METHOD_LABELS = {m.name: m.label for m in METHODS.values()}
METHOD_MARKERS = {m.name: m.marker for m in METHODS.values()}
METHOD_COLORS = {m.name: m.color for m in METHODS.values()}
OBJECTIVE_LABELS = {"tracking": "Cmd", "power": "P", "torque": "τ"}
TERRAIN_ORDER = ("flat", "slope", "random")


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
    design_names: list[str] = field(default_factory=list)  # the run's design space, in order
    design_units: list[str] = field(default_factory=list)
    design_discrete: list[bool] = field(default_factory=list)

    @property
    def method(self) -> str:
        return self.run["method"]

    @property
    def optimizer(self) -> str:
        """The optimizer the run used."""
        return str(self.run.get("optimizer") or "unknown")

    @property
    def summary(self) -> dict[str, Any]:
        return self.run.get("summary") or {}

    @property
    def space_key(self) -> tuple[str, ...]:
        return tuple(self.design_names)

    @property
    def objective(self) -> str:
        return ",".join(self.run["objectives"])

    @property
    def terrain(self) -> str:
        return self.run["terrain"] or "flat"

    @property
    def setting(self) -> tuple[str, str, str]:
        """(robot, simulator, preset): runs that differ in any of them are never one row."""
        return (str(self.run.get("robot") or "?"), str(self.run.get("simulator") or "?"),
                str(self.run.get("preset") or "?"))

    @property
    def policy(self) -> str:
        """The starting policy, as the run recorded it: 'file (sha256 prefix)', 'none' (from
        scratch), or '?' for a run recorded before provenance existed."""
        config = self.run.get("config") if isinstance(self.run.get("config"), dict) else {}
        found = self.summary.get("policy") or config.get("policy")
        if not isinstance(found, dict):
            return "?"
        if found.get("source") == "none":
            return "none"
        return f"{found.get('file')} ({str(found.get('sha256') or '')[:12]})"


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
    summary = run["summary"] or {}
    best_design, best_cost = best_of(run, real)
    training = store.training(run["id"])
    dim = len(best_design) if best_design is not None else (len(real[0].design) if real else None)
    space = space_of_run(run, dim)
    variables = space["variables"] if space else [{"name": f"x{i}", "type": "continuous"} for i in range(dim or 0)]
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
        design_names=[str(v["name"]) for v in variables],
        design_units=[str(v.get("unit") or "") for v in variables],
        design_discrete=[v.get("type") == "discrete" for v in variables],
    )


def _float(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


# -- sim-to-sim (Table 6's last column) ---------------------------------------------------------
def transfer_improvement(store: ResultsStore, facts: RunFacts, simulator: str | None = None,
                         note: str = "") -> tuple[float | None, str]:
    """(improvement of the best design over the nominal one, note) from the run's transfer
    rows (kind "sim2sim", idx 0 best, 1 nominal, written by `coadapt_core.experiments.transfer`)
    on `simulator` (None: any). Without rows: (None, `note`, or that there are none). Reads
    only: the report never runs a simulation."""
    run = facts.run
    rows = [e for e in store.evaluations(run["id"], kind=TRANSFER_KIND) if simulator in (None, e.simulator)]
    by_idx = {e.idx: e for e in rows}
    first = run["objectives"][0] if run["objectives"] else None
    if first is None or 0 not in by_idx or 1 not in by_idx or first not in by_idx[0].costs:
        return None, note or "n/a: no sim-to-sim rows (`coadapt report --sim-to-sim` evaluates them)"
    best_cost, nominal_cost = by_idx[0].costs[first], by_idx[1].costs[first]
    try:
        from coadapt_core.plugins import get_registry

        value = get_registry().create("objective", first).improvement(best_cost, nominal_cost)
    except Exception:  # an objective plugin not installed here: the default definition
        value = (nominal_cost - best_cost) / abs(nominal_cost) if nominal_cost else 0.0
    return float(value), f"{by_idx[0].simulator}, {len(rows)} designs"


# -- tables ------------------------------------------------------------------------------------
def _ordered(values: Sequence[str], order: Sequence[str]) -> list[str]:
    known = [v for v in order if v in values]
    return known + sorted(v for v in set(values) if v not in order)


def optimizer_order() -> tuple[str, ...]:
    """Installed optimizers in the order of every table, legend and figure: the default one
    first (highest `default_rank`), then by name; one not installed here sorts after them."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    return tuple(sorted(registry.names("optimizer"),
                        key=lambda n: (-int(getattr(registry.get("optimizer", n), "default_rank", 0)), n)))


def _group_order(keys: Sequence[tuple[str, str]]) -> list[tuple[str, str]]:
    """(method, optimizer) keys in the paper's method order, then optimizer order: the same
    order in every table, legend and figure."""
    order = optimizer_order()

    def rank(key: tuple[str, str]) -> tuple[int, str, int, str]:
        m, o = key
        mi = METHOD_NAMES.index(m) if m in METHOD_NAMES else len(METHOD_NAMES)
        oi = order.index(o) if o in order else len(order)
        return (mi, m, oi, o)

    return sorted(set(keys), key=rank)


def _stat(values: Sequence[float | None]) -> tuple[float | None, float | None, int]:
    """(mean, sample std or None for one value, n) over the values that exist."""
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if not vals:
        return None, None, 0
    return float(np.mean(vals)), (float(np.std(vals, ddof=1)) if len(vals) > 1 else None), len(vals)


def _mean(values: Sequence[float | None]) -> float | None:
    return _stat(values)[0]


def _se_of_mean(values: Sequence[float | None]) -> float | None:
    """Standard error of the mean of independent estimates with these standard errors (all
    of them recorded, else None)."""
    if not values or any(v is None for v in values):
        return None
    return float(math.sqrt(sum(float(v) ** 2 for v in values)) / len(values))


def _add_stat(row: dict[str, Any], name: str, values: Sequence[float | None], se: Sequence[float | None] | None = None) -> None:
    mean, std, n = _stat(values)
    row[name], row[f"{name}_std"], row[f"{name}_n"] = mean, std, n
    if se is not None:
        row[f"{name}_se"] = _se_of_mean(se)


def table6_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per robot x simulator x preset x objective x method x optimizer x terrain:
    mean, sample standard deviation over seeds and count of every number (`<col>`,
    `<col>_std`, `<col>_n`); the design columns are named after the run's design space. Runs
    of different robots, simulators or presets are never averaged into one row."""
    groups: dict[tuple[tuple[str, str, str], str, str, str, str], list[RunFacts]] = defaultdict(list)
    for f in facts:
        if f.method != LANDSCAPE_METHOD:
            groups[(f.setting, f.objective, f.method, f.optimizer, f.terrain)].append(f)
    rows = []
    settings = sorted({k[0] for k in groups})
    objectives = _ordered([k[1] for k in groups], list(OBJECTIVE_LABELS))
    pairs = _group_order([(k[2], k[3]) for k in groups])
    terrains = _ordered([k[4] for k in groups], TERRAIN_ORDER)
    for setting, o, (m, opt), t in itertools.product(settings, objectives, pairs, terrains):
        group = groups.get((setting, o, m, opt, t))
        if not group:
            continue
        robot, simulator, preset = setting
        row: dict[str, Any] = {"robot": robot, "simulator": simulator, "preset": preset,
                               "objective": o, "method": m, "optimizer": opt, "terrain": t, "runs": len(group),
                               "seeds": " ".join(str(f.run.get("seed")) for f in group),
                               "policy": "; ".join(sorted({f.policy for f in group}))}
        names = group[0].design_names
        for i, name in enumerate(names):
            _add_stat(row, name, [f.best_design[i] if f.best_design and len(f.best_design) > i else None for f in group])
        _add_stat(row, "best_cost", [f.best_cost for f in group], [_float(f.summary.get("best_cost_se")) for f in group])
        _add_stat(row, "nominal_cost", [f.nominal_cost for f in group],
                  [_float(f.summary.get("nominal_cost_se")) for f in group])
        _add_stat(row, "improvement", [f.improvement for f in group],
                  [_float(f.summary.get("improvement_se")) for f in group])
        # the paper's plain mean (eq. 4) and the fall rates beside the run's cost rule
        _add_stat(row, "improvement_plain", [_float(f.summary.get("improvement_plain")) for f in group],
                  [_float(f.summary.get("improvement_plain_se")) for f in group])
        _add_stat(row, "best_fall_rate", [_float(f.summary.get("best_fall_rate")) for f in group],
                  [_float(f.summary.get("best_fall_rate_se")) for f in group])
        _add_stat(row, "nominal_fall_rate", [_float(f.summary.get("nominal_fall_rate")) for f in group],
                  [_float(f.summary.get("nominal_fall_rate_se")) for f in group])
        row["cost_rule"] = " ".join(sorted({str(f.summary.get("cost_rule") or "trimmed") for f in group}))
        _add_stat(row, "sim2sim_improvement", [f.sim2sim for f in group])
        row["sim2sim_note"] = "; ".join(sorted({f.sim2sim_note for f in group if f.sim2sim_note}))
        row["design_variables"] = " ".join(names)
        row["design_units"] = "|".join(group[0].design_units)
        row["design_discrete"] = " ".join(str(int(d)) for d in group[0].design_discrete)
        row["run_ids"] = " ".join(f.run["id"] for f in group)
        # the walking gate (coadapt_core/coadapt/reliability.py): runs whose policy did not walk
        bad = [f for f in group if f.summary.get("reliable") is False]
        row["unreliable_runs"] = len(bad)
        row["reliability"] = "; ".join(sorted({str(f.summary.get("reliability")) for f in bad}))
        rows.append(row)
    return rows


#: what the tables say about how runs are grouped into rows
POOLING_NOTE = ("Runs of different robots, simulators or presets are never averaged together: each combination "
                "is a row of its own (Robot, Simulator, Preset columns).")

T7_NUMBERS = ("interactions_training", "interactions_evaluation", "seconds_training", "seconds_evaluation",
              "designs_real", "designs_surrogate")


def table7_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per robot x simulator x preset x method x optimizer: mean, std and count over
    its runs (the paper reports averages); a pso and a mixed-pso run of one method are two
    rows, as in Table 6, and so are runs of different robots, simulators or presets."""
    groups: dict[tuple[tuple[str, str, str], str, str], list[RunFacts]] = defaultdict(list)
    for f in facts:
        if f.method != LANDSCAPE_METHOD:
            groups[(f.setting, f.method, f.optimizer)].append(f)
    rows = []
    keys = [(setting, m, opt) for setting in sorted({k[0] for k in groups})
            for m, opt in _group_order([(k[1], k[2]) for k in groups if k[0] == setting])]
    for setting, m, opt in keys:
        g = groups[(setting, m, opt)]
        row: dict[str, Any] = {"robot": setting[0], "simulator": setting[1], "preset": setting[2],
                               "method": m, "optimizer": opt, "runs": len(g)}
        values = {
            "interactions_training": [f.train_interactions for f in g],
            "interactions_evaluation": [f.eval_interactions for f in g],
            "seconds_training": [f.train_seconds for f in g],
            "seconds_evaluation": [f.eval_seconds for f in g],
            "designs_real": [f.designs_real for f in g],
            "designs_surrogate": [f.designs_surrogate for f in g],
        }
        for name in T7_NUMBERS:
            _add_stat(row, name, values[name])
        row["run_ids"] = " ".join(f.run["id"] for f in g)
        rows.append(row)
    return rows


def _label(method: str, optimizer: str | None = None) -> str:
    return METHOD_LABELS.get(method, method) + (f" [{optimizer}]" if optimizer else "")


def _fmt(value: float | None, spec: str = ".2f", pct: bool = False) -> str:
    if value is None:
        return "n/a"
    return f"{100 * value:.1f}%" if pct else format(value, spec)


def _cell(row: dict[str, Any], name: str, *, spec: str = ".3g", pct: bool = False, scale: float = 1.0) -> str:
    """'mean ± std (n=k)' of an aggregated column; one run: 'value ± se SE (n=1)' when the
    run recorded a standard error, else 'value (n=1)'."""
    mean, std, n = row.get(name), row.get(f"{name}_std"), row.get(f"{name}_n", 0)
    if mean is None or not n:
        return "n/a"

    def fmt(v: float) -> str:
        return f"{100 * v / scale:.1f}%" if pct else format(v / scale, spec)

    if std is not None:
        return f"{fmt(mean)} ± {fmt(std)} (n={n})"
    se = row.get(f"{name}_se")
    if se is not None:
        return f"{fmt(mean)} ± {fmt(se)} SE (n={n})"
    return f"{fmt(mean)} (n={n})"


def _design_header(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def _design_cell(row: dict[str, Any], name: str, discrete: bool) -> str:
    if row.get(f"{name}_n", 0) == 1 and discrete and row.get(name) is not None:
        return f"{row[name]:.0f} (n=1)"  # a motor type is an integer
    return _cell(row, name, spec=".3f")


def _design_columns(rows: Sequence[dict[str, Any]]) -> list[tuple[str, str, bool]]:
    """(name, unit, discrete) of every design variable the rows name, in first-seen order."""
    out: list[tuple[str, str, bool]] = []
    for r in rows:
        names = r["design_variables"].split()
        units = r["design_units"].split("|") if r["design_units"] else [""] * len(names)
        flags = [d == "1" for d in r["design_discrete"].split()] or [False] * len(names)
        for n, u, d in zip(names, units + [""] * len(names), flags + [False] * len(names), strict=False):
            if n not in [c[0] for c in out]:
                out.append((n, u, d))
    return out


def _unreliable_mark(row: dict[str, Any]) -> str:
    """' UNRELIABLE (k of n runs: the policy does not walk)' for a row with runs below the
    walking gate, else ''."""
    k = int(row.get("unreliable_runs") or 0)
    return f" UNRELIABLE ({k} of {row['runs']} runs: the policy does not walk)" if k else ""


def table6_markdown(rows: Sequence[dict[str, Any]]) -> str:
    design = _design_columns(rows)
    head = (["Robot", "Simulator", "Preset", "Objective", "Method", "Optimizer", "Terrain", "Runs"]
            + [_design_header(n, u) for n, u, _ in design]
            + ["Best cost", "Nominal cost", "Improvement", "Improvement (plain mean)", "Fall rate best / nominal",
               "Sim-to-sim improvement", "Sim-to-sim note", "Starting policy"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["robot"], r["simulator"], r["preset"],
                 OBJECTIVE_LABELS.get(r["objective"], r["objective"]), METHOD_LABELS.get(r["method"], r["method"]),
                 r["optimizer"], r["terrain"], str(r["runs"])]
        cells += [_design_cell(r, n, d) if f"{n}_n" in r else "" for n, _, d in design]
        cells += [_cell(r, "best_cost", spec=".5g"), _cell(r, "nominal_cost", spec=".5g"),
                  _cell(r, "improvement", pct=True) + _unreliable_mark(r), _cell(r, "improvement_plain", pct=True),
                  _cell(r, "best_fall_rate", pct=True) + " / " + _cell(r, "nominal_fall_rate", pct=True),
                  _cell(r, "sim2sim_improvement", pct=True), r["sim2sim_note"] or "", r.get("policy") or "?"]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", POOLING_NOTE + " Each number: mean ± sample standard deviation over the runs (seeds) of the row, "
              "and how many runs had it (n); one run shows its own standard error (SE) when it recorded one. "
              "Improvement: lower cost than the nominal design, in percent of the nominal cost, under the run's cost "
              "rule (column `cost_rule` of table6.csv; docs/coadaptation.md) and under the paper's plain mean over "
              "the same scenarios; fall rate: share of the final check's scenarios in which the robot fell. Starting "
              "policy: the policy file each run started from and the start of its SHA-256."]
    return "\n".join(lines) + "\n"


def table7_units(rows: Sequence[dict[str, Any]]) -> tuple[float, str, float, str]:
    """Interaction and time units: the paper's millions and hours, smaller ones when a
    table of smoke runs would print only zeros."""
    most_inter = max(((r["interactions_training"] or 0) + (r["interactions_evaluation"] or 0) for r in rows), default=0)
    most_sec = max(((r["seconds_training"] or 0) + (r["seconds_evaluation"] or 0) for r in rows), default=0)
    inter = (1e6, "million") if most_inter >= 1e5 else (1e3, "thousand")
    time_unit = (3600.0, "hour") if most_sec >= 360 else (60.0, "minute") if most_sec >= 6 else (1.0, "second")
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
        f"| Robot | Simulator | Preset | Method | Optimizer | Runs | Interactions ({iname}, Training+Evaluation) | "
        f"Wall clock time ({tname}, Training+Evaluation) | Designs evaluated (real+surrogate) |",
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
    lines += ["", POOLING_NOTE + " Means over the runs of each row (± sample standard deviation of the total when "
              "a row has two or more runs)."]
    return "\n".join(lines) + "\n"


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    columns: list[str] = []
    for r in rows:
        columns.extend(k for k in r if k not in columns)
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: ("" if v is None else repr(v) if isinstance(v, float) else v) for k, v in r.items()})


# -- figures ------------------------------------------------------------------------------------
#: the optimizer sets a run's line style and its marker's fill: two optimizers of one method
#: differ in both, the methods in colour and marker shape
LINESTYLES = ("-", (0, (5, 2)), (0, (3, 1, 1, 1)), (0, (1, 1.2)))


def optimizer_style(name: str) -> tuple[Any, bool]:
    """(line style, marker filled) of an optimizer: by its place in `optimizer_order`, styles
    in turn and every second one filled."""
    order = optimizer_order()
    i = order.index(name) if name in order else len(order)
    return LINESTYLES[i % len(LINESTYLES)], i % 2 == 1


def _space_slug(names: Sequence[str]) -> str:
    return "+".join(names)


def _landscape_for(store: ResultsStore, objective: str, terrain: str, names: Sequence[str]) -> dict[str, Any] | None:
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
    store: ResultsStore, facts: Sequence[RunFacts], objective: str, terrain: str, names: Sequence[str]
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
        return {"kind": "landscape", "a": a, "b": b, "grid": grid, "optimum": pts[int(np.argmin(vals))],
                "source": f"landscape run {land['id']} ({len(a)}x{len(b)} real evaluations)"}
    pts, vals = [], []
    for f in facts:
        if f.objective == objective and f.terrain == terrain and list(f.design_names) == names:
            for e in f.real:
                if objective in e.costs and len(e.design) >= 2 and math.isfinite(e.costs[objective]):
                    pts.append(e.design[:2])
                    vals.append(e.costs[objective])
    if not pts:
        return None
    return {"kind": "scatter", "points": np.array(pts), "values": np.array(vals),
            "source": f"{len(pts)} real evaluations of the runs (each with its own run's policy)"}


def figure_heatmaps(store: ResultsStore, facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    """One PNG per terrain and design space, one panel per objective: the landscape grid when
    one exists, else the designs the runs evaluated, coloured by their real cost."""
    plt = pyplot()
    from matplotlib.colors import LogNorm

    written = []
    runs = [f for f in facts if f.method != LANDSCAPE_METHOD and "," not in f.objective]  # fronts go to pareto.png
    objectives = _ordered([f.objective for f in runs], list(OBJECTIVE_LABELS))
    spaces = sorted({f.space_key for f in runs if len(f.space_key) >= 2}, key=lambda k: (len(k), k))
    for names in spaces:
        for t in _ordered([f.terrain for f in runs], TERRAIN_ORDER):
            panels = [(o, heatmap_data(store, runs, o, t, names)) for o in objectives]
            panels = [(o, d) for o, d in panels if d is not None]
            if not panels:
                continue
            fig, axes = panel_grid(plt, len(panels), height=PANEL_H + 0.6)
            sources, drew_star, drew_methods = [], False, set()
            for ax, (o, d) in zip(axes, panels, strict=True):
                values = d["grid"] if d["kind"] == "landscape" else d["values"]
                log = spans_decades(values)
                norm = LogNorm(vmin=float(np.nanmin(values)), vmax=float(np.nanmax(values))) if log else None
                if d["kind"] == "landscape":
                    # each grid cell one evaluated design: no interpolation between them
                    mesh = ax.pcolormesh(d["a"], d["b"], d["grid"], cmap="viridis_r", norm=norm, shading="nearest")
                    ax.plot(*d["optimum"], marker="*", markerfacecolor="none", markeredgecolor="black", markeredgewidth=1.5,
                            markersize=18, linestyle="none", label="grid optimum", zorder=5, clip_on=False)
                    drew_star = True
                else:
                    mesh = ax.scatter(d["points"][:, 0], d["points"][:, 1], c=d["values"], cmap="viridis_r", norm=norm,
                                      s=14, linewidths=0)
                fig.colorbar(mesh, ax=ax, label=f"real {o} cost" + (" (log scale)" if log else ""))
                keys = _group_order([(f.method, f.optimizer) for f in runs
                                     if f.objective == o and f.terrain == t and f.space_key == names and f.best_design])
                for rank, (m, opt) in enumerate(keys):
                    pts = np.array([f.best_design[:2] for f in runs if (f.method, f.optimizer) == (m, opt)
                                    and f.objective == o and f.terrain == t and f.space_key == names and f.best_design])
                    ax.scatter(pts[:, 0], pts[:, 1], marker=METHOD_MARKERS.get(m, "x"), s=200 - 30 * min(rank, 4),
                               facecolors="none", edgecolors=METHOD_COLORS.get(m, "black"), linewidths=2.0,
                               label=_label(m, opt), zorder=3 + 0.1 * rank, clip_on=False)
                    drew_methods.add(m)
                ax.set_xlabel(names[0])
                ax.set_ylabel(names[1])
                ax.set_title(f"{o} on {t}" + (" (landscape grid)" if d["kind"] == "landscape" else " (evaluated designs)"),
                             fontsize=10)
                ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=7, frameon=False)
                sources.append(f"{o}: {d['source']}")
            # a two-variable space is the figure's own name; a larger one (motor types too) is named
            suffix = "" if len(names) == 2 else "_" + _space_slug(names)
            path = out / f"heatmap_{t}{suffix}.png"
            kinds = {d["kind"] for _, d in panels}
            what = []
            if "landscape" in kinds:
                what.append("a landscape run's grid of real costs (one cell per evaluated design)")
            if "scatter" in kinds:
                what.append("every real evaluation of the runs as a dot coloured by its cost"
                            + (" (motor types differ between dots)" if len(names) > 2 else ""))
            caption = (f"Real cost on {t} terrain over ({names[0]}, {names[1]}); lighter = lower cost. Panels show "
                       + " and ".join(what) + ".")
            if drew_methods:
                caption += " Hollow markers: each method's best design, one per seed."
            if drew_star:
                caption += " Star: the landscape grid's lowest cost."
            written += save_figure(plt, fig, path, caption + " Sources: " + "; ".join(sources) + ".")
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


def figure_convergence(store: ResultsStore, facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    plt = pyplot()
    from matplotlib.lines import Line2D

    runs = [f for f in facts if f.method != LANDSCAPE_METHOD and f.real and "," not in f.objective]
    keys = sorted({(f.objective, f.terrain) for f in runs},
                  key=lambda k: (list(OBJECTIVE_LABELS).index(k[0]) if k[0] in OBJECTIVE_LABELS else 9, k[1]))
    if not keys:
        return []
    series = {f.run["id"]: convergence_series(store, f) for f in runs}
    most = max((x.max(initial=0.0) for x, _ in series.values()), default=0.0)
    unit, unit_name = (1e6, "million") if most >= 1e5 else (1e3, "thousand")
    fig, axes = panel_grid(plt, len(keys))
    groups = _group_order([(f.method, f.optimizer) for f in runs])
    for ax, (o, t) in zip(axes, keys, strict=True):
        for m, opt in groups:
            for f in runs:
                if (f.method, f.optimizer, f.objective, f.terrain) != (m, opt, o, t):
                    continue
                x, y = series[f.run["id"]]
                if len(x) == 0:
                    continue
                color = METHOD_COLORS.get(m, "black")
                ax.step(x / unit, y, where="post", color=color, alpha=0.85, linewidth=1.6,
                        linestyle=optimizer_style(opt)[0])
                ax.plot(x[-1:] / unit, y[-1:], marker=METHOD_MARKERS.get(m, "x"), markersize=7, color=color,
                        markerfacecolor=color if optimizer_style(opt)[1] else "none", linestyle="none")
        ax.set_xlabel(f"environment interactions ({unit_name})")
        ax.set_ylabel(f"best real {o} cost so far")
        if spans_decades([y for _, ys in series.values() for y in ys]):
            ax.set_yscale("log")
        ax.set_title(f"{o} on {t}", fontsize=10)
        tidy_axes(ax)
    # one legend for the whole figure, in the tables' order: the same in every panel
    handles = [Line2D([], [], color=METHOD_COLORS.get(m, "black"), linestyle=optimizer_style(opt)[0],
                      marker=METHOD_MARKERS.get(m, "x"), markerfacecolor=METHOD_COLORS.get(m, "black")
                      if optimizer_style(opt)[1] else "none", label=_label(m, opt)) for m, opt in groups]
    fig.legend(handles=handles, loc="lower center", ncol=min(3, len(handles)), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.06 + 0.03 * math.ceil(len(handles) / 3), 1, 1))
    return save_figure(plt, fig, out / "convergence.png", "Convergence: best real cost found so far against environment interactions spent "
                   "(training + real evaluation), one line per run; colour and marker shape = method, "
                   "line style and marker fill = optimizer; the marker sits at the run's last evaluation.", layout=False)


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
    keys = sorted(series, key=lambda k: (list(OBJECTIVE_LABELS).index(k[0]) if k[0] in OBJECTIVE_LABELS else 9,
                                         TERRAIN_ORDER.index(k[1]) if k[1] in TERRAIN_ORDER else 9))
    fig, axes = panel_grid(plt, len(keys))
    for ax, key in zip(axes, keys, strict=True):
        pts = series[key]
        for m in _ordered({p[2] for p in pts}, METHOD_NAMES):
            xy = np.array([(p[0], 100 * p[1]) for p in pts if p[2] == m])
            ax.scatter(xy[:, 0], xy[:, 1], s=30, facecolors="none", linewidths=1.2,
                       edgecolors=METHOD_COLORS.get(m, "black"), marker=METHOD_MARKERS.get(m, "x"),
                       label=METHOD_LABELS.get(m, m))
        ax.axhline(0.0, color="grey", linewidth=0.8)
        errs = np.array([100 * p[1] for p in pts])
        reals = np.array([p[0] for p in pts])
        if spans_decades(reals):
            ax.set_xscale("log")
        finite = np.isfinite(errs)
        if finite.any():
            lo, hi = np.percentile(errs[finite], [1, 99])
            pad = 0.1 * max(hi - lo, 1.0)
            ax.set_ylim(min(lo, 0.0) - pad, max(hi, 0.0) + pad)  # a few diverged points do not squash the rest
        clipped = int((finite & ((errs < ax.get_ylim()[0]) | (errs > ax.get_ylim()[1]))).sum())
        mean_abs = f"{np.abs(errs[finite]).mean():.3g} %" if finite.any() else "n/a"
        notes = (f", {clipped} off-scale" if clipped else "") + (f", {int((~finite).sum())} NaN" if not finite.all() else "")
        ax.set_title(f"{key[0]} on {key[1]}: mean |error| {mean_abs}\n({int(finite.sum())} designs{notes})", fontsize=9)
        ax.set_xlabel(f"real {key[0]} cost")
        ax.set_ylabel("(surrogate − real) / |real|  [%]")
        ax.legend(fontsize=7)
        tidy_axes(ax)
    return save_figure(plt, fig, out / "surrogate_error.png", "Pseudo-critic surrogate error relative to the real cost of the same design (paper Fig. 4, "
                   "right), one panel per objective and terrain. Sign: (surrogate − real) / |real|, so a point "
                   "above the zero line is a design the surrogate scored worse (costlier) than it is; below, better.")


def pareto_points(f: RunFacts) -> dict[str, Any]:
    """What pareto.png draws for a multi-objective run: every real evaluation ("evaluated"
    [n, 2]), the front ("front" [F, 2], first two objectives) and where it comes from. The
    front is the run's stored final front (the one `coadapt run` printed) when it has one."""
    o1, o2 = f.run["objectives"][:2]
    evaluated = np.array([[e.costs[o1], e.costs[o2]] for e in f.real if o1 in e.costs and o2 in e.costs]).reshape(-1, 2)
    stored = f.summary.get("pareto_front")
    if isinstance(stored, dict) and stored.get("costs"):
        front = np.array([[c[o1], c[o2]] for c in stored["costs"]], dtype=float)
        designs = np.array(stored["designs"], dtype=float)
        source = "the run's final front (real re-evaluation)"
    else:
        mask = pareto_mask(evaluated)
        front = evaluated[mask]
        designs = np.array([e.design for e in f.real if o1 in e.costs and o2 in e.costs])[mask]
        source = "non-dominated real evaluations (the run stored no final front)"
    order = np.lexsort(front.T[::-1]) if len(front) else np.arange(0)
    return {"objectives": (o1, o2), "evaluated": evaluated, "front": front[order], "designs": designs[order],
            "source": source}


def figure_pareto(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    plt = pyplot()
    multi = [f for f in facts if len(f.run["objectives"]) >= 2 and (f.real or f.summary.get("pareto_front"))][:6]
    if not multi:
        return []
    fig, axes = panel_grid(plt, len(multi), height=PANEL_H + 0.4)
    sources = set()
    for ax, f in zip(axes, multi, strict=True):
        d = pareto_points(f)
        o1, o2 = d["objectives"]
        ax.scatter(d["evaluated"][:, 0], d["evaluated"][:, 1], s=12, color="lightgrey", label="real evaluations during the run")
        ax.plot(d["front"][:, 0], d["front"][:, 1], "o-", color="tab:red", label=f"Pareto front ({len(d['front'])} designs)")
        best = f.summary.get("best_costs") or {}
        if o1 in best and o2 in best:
            ax.plot(best[o1], best[o2], marker="D", markersize=9, markerfacecolor="none", markeredgecolor="black",
                    linestyle="none", label="Table 6 design (lowest first cost)")
        ax.set_xlabel(f"{o1} cost")
        ax.set_ylabel(f"{o2} cost")
        both = np.vstack([d["evaluated"], d["front"]])
        if spans_decades(both[:, 0]):
            ax.set_xscale("log")
        if spans_decades(both[:, 1]):
            ax.set_yscale("log")
        ax.set_title(f"{f.run['id']}\n{f.optimizer} on {f.terrain}", fontsize=8)
        ax.legend(fontsize=7)
        tidy_axes(ax)
        sources.add(d["source"])
    return save_figure(plt, fig, out / "pareto.png", "Pareto fronts of multi-objective runs: grey, every real evaluation during the run; red, the "
                   f"front ({'; '.join(sorted(sources))}), the same designs `coadapt run` printed and the store holds; "
                   "diamond, the design Table 6 reports.")


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
                written.append((dst, f"Run {f.run['id']} ({_label(f.method, f.optimizer)}, {f.objective} on "
                                     f"{f.terrain}): the best design (left) and the nominal design (right) walking "
                                     "with the run's final policy."))
    return written[:12]


# -- the whole report -------------------------------------------------------------------------
def _html_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    head = "".join(f"<th>{html.escape(label)}</th>" for _, label in columns)
    body = []
    for r in rows:
        cells = "".join(f"<td>{html.escape(str(r.get(key, '')))}</td>" for key, _ in columns)
        body.append(f"<tr>{cells}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def write_report(
    store: ResultsStore,
    selection: str | None,
    out_dir: str | Path,
    *,
    sim2sim: bool = True,
    transfer_simulator: str | None = None,
    transfer_notes: dict[str, str] | None = None,
    progress: Any = None,
) -> dict[str, Path]:
    """Tables (Markdown + CSV), figures (PNG) and report.html for `selection` (a grid id, a
    run id, or None for every finished run). Returns the files written by name. The
    sim-to-sim column reads the runs' transfer rows on `transfer_simulator` (None: any;
    `coadapt_core.experiments.transfer` writes them), `transfer_notes` saying why a run has
    none. `progress(done, total, what)` hears of each step."""
    runs, title = select_runs(store, selection)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    facts = [run_facts(store, r) for r in runs]
    total = 7
    if progress is not None:
        progress(0, total, "reading runs")
    for f in facts:
        if f.method == LANDSCAPE_METHOD:
            continue
        if sim2sim:
            f.sim2sim, f.sim2sim_note = transfer_improvement(store, f, transfer_simulator,
                                                             (transfer_notes or {}).get(f.run["id"], ""))
        else:
            f.sim2sim, f.sim2sim_note = None, "n/a: not requested (--no-sim-to-sim)"
    t6, t7 = table6_rows(facts), table7_rows(facts)
    files: dict[str, Path] = {}
    for name, rows, md in (("table6", t6, table6_markdown(t6)), ("table7", t7, table7_markdown(t7))):
        write_csv(out / f"{name}.csv", rows)
        (out / f"{name}.md").write_text(md)
        files[f"{name}.csv"] = out / f"{name}.csv"
        files[f"{name}.md"] = out / f"{name}.md"
    # the paper's figures beside ours (coadapt_core/analysis/paper_comparison.py)
    from coadapt_core.analysis.paper_comparison import write_paper_comparison

    paper_files, paper_html = write_paper_comparison(
        t6, table7_rows([f for f in facts if not any(f.design_discrete)]), out, objective_labels=OBJECTIVE_LABELS)
    files.update(paper_files)
    figures: list[tuple[Path, str]] = []
    steps = (("heat-maps", lambda: figure_heatmaps(store, facts, out)),
             ("convergence", lambda: figure_convergence(store, facts, out)),
             ("surrogate error", lambda: figure_surrogate_error(facts, out)),
             ("surrogate quality", lambda: figure_surrogate_quality(facts, out)),
             ("Pareto fronts", lambda: figure_pareto(facts, out)),
             ("videos", lambda: figure_videos(facts, out)))
    for j, (what, draw) in enumerate(steps):
        if progress is not None:
            progress(1 + j, total, what)
        figures += draw()
    if progress is not None:
        progress(total, total, "done")
    for path, _ in figures:
        files[path.name] = path
    iu, iname, tu, tname = table7_units(t7)
    design = _design_columns(t6)
    t6_html = []
    for r in t6:
        row = {"robot": r["robot"], "simulator": r["simulator"], "preset": r["preset"], "policy": r.get("policy") or "?",
               "objective": r["objective"], "method": METHOD_LABELS.get(r["method"], r["method"]), "optimizer": r["optimizer"],
               "terrain": r["terrain"], "runs": r["runs"], "best_cost": _cell(r, "best_cost", spec=".5g"),
               "nominal_cost": _cell(r, "nominal_cost", spec=".5g"), "improvement": _cell(r, "improvement", pct=True) + _unreliable_mark(r),
               "improvement_plain": _cell(r, "improvement_plain", pct=True),
               "falls": _cell(r, "best_fall_rate", pct=True) + " / " + _cell(r, "nominal_fall_rate", pct=True),
               "sim2sim": _cell(r, "sim2sim_improvement", pct=True), "sim2sim_note": r["sim2sim_note"]}
        row.update({f"d:{n}": _design_cell(r, n, d) if f"{n}_n" in r else "" for n, _, d in design})
        t6_html.append(row)
    t7_html = [{"robot": r["robot"], "simulator": r["simulator"], "preset": r["preset"],
                "method": METHOD_LABELS.get(r["method"], r["method"]), "optimizer": r["optimizer"], "runs": r["runs"],
                "inter_t": _cell(r, "interactions_training", scale=iu), "inter_e": _cell(r, "interactions_evaluation", scale=iu),
                "time_t": _cell(r, "seconds_training", scale=tu), "time_e": _cell(r, "seconds_evaluation", scale=tu),
                "designs_real": _cell(r, "designs_real", spec=".0f"), "designs_surrogate": _cell(r, "designs_surrogate", spec=".0f")}
               for r in t7]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>coadapt report</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
        "table{border-collapse:collapse;margin:1em 0;font-size:90%}"
        "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eee}"
        ".scroll{overflow-x:auto}img{max-width:100%;height:auto}figure{margin:1.5em 0}figcaption{color:#444;font-size:90%;max-width:60em}"
        "</style></head><body>",
        f"<h1>coadapt report — {html.escape(title)}</h1>",
        f"<p>Store: <code>{html.escape(store.url)}</code>; {len(runs)} runs. Each number is the mean ± sample standard "
        "deviation over the runs (seeds) of its row, with how many runs had it (n); one row per method and optimizer. "
        f"{html.escape(POOLING_NOTE)} "
        "A single run shows its own standard error (SE) when it recorded one.</p>",
        "<h2>Table 6 — optimization results</h2>",
        "<div class='scroll'>" + _html_table(t6_html, [("robot", "robot"), ("simulator", "simulator"), ("preset", "preset"),
                              ("objective", "objective"), ("method", "method"), ("optimizer", "optimizer"),
                              ("terrain", "terrain"), ("runs", "runs")]
                    + [(f"d:{n}", _design_header(n, u)) for n, u, _ in design]
                    + [("best_cost", "best cost"), ("nominal_cost", "nominal cost"), ("improvement", "improvement"),
                       ("improvement_plain", "improvement (plain mean)"), ("falls", "fall rate best / nominal"),
                       ("sim2sim", "sim-to-sim improvement"), ("sim2sim_note", "sim-to-sim note"),
                       ("policy", "starting policy")]) + "</div>",
        "<h2>Table 7 — computational cost</h2>",
        _html_table(t7_html, [("robot", "robot"), ("simulator", "simulator"), ("preset", "preset"),
                              ("method", "method"), ("optimizer", "optimizer"), ("runs", "runs"),
                              ("inter_t", f"interactions training ({iname})"), ("inter_e", f"interactions evaluation ({iname})"),
                              ("time_t", f"wall clock training ({tname})"), ("time_e", f"wall clock evaluation ({tname})"),
                              ("designs_real", "designs real"), ("designs_surrogate", "designs surrogate")]),
        paper_html,
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
