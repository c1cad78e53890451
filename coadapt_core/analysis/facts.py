"""What a report knows of each run, read from the store: which runs a selection names,
each run's facts (best design, costs, interactions, sim-to-sim transfer), and the labels
and orders every table and figure share (methods from the method registry, objectives from
the objective plugins' declarations, terrains from their one declaration)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coadapt_core import sim_to_sim as sim2sim
from coadapt_core.analysis.measures import improvement_measure, objective_named
from coadapt_core.errors import UserError
from coadapt_core.methods import METHODS
from coadapt_core.results.export import space_of_run
from coadapt_core.results.rows import Evaluation, best_of
from coadapt_core.results.schema import COMMON_KIND, LANDSCAPE_METHOD, TRANSFER_KIND
from coadapt_core.results.store import ResultsStore
from coadapt_core.terrains import TERRAINS

#: the paper's row labels, and each method's marker and colour in the figures (from the
#: method registry)
METHOD_LABELS = {m.name: m.label for m in METHODS.values()}
METHOD_MARKERS = {m.name: m.marker for m in METHODS.values()}
METHOD_COLORS = {m.name: m.color for m in METHODS.values()}
#: terrains in the order of every table and figure
TERRAIN_ORDER = TERRAINS


def objective_order() -> tuple[str, ...]:
    """Installed objectives in the order of every table and figure: the order their plugins
    register them (the built-ins: tracking, power, torque, as the paper's Table 6); one not
    installed here sorts after them."""
    from coadapt_core.plugins import get_registry

    return tuple(get_registry().entries["objective"])


def objective_labels() -> dict[str, str]:
    """Objective name -> the short label its plugin declares for a table column
    (`Objective.short_label`); objectives declaring none are shown by name."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    labels = {
        name: str(getattr(registry.get("objective", name), "short_label", "") or "")
        for name in registry.entries["objective"]
    }
    return {name: label for name, label in labels.items() if label}


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
    # the common yardstick (coadapt_core.experiments.yardstick): improvements under the rule and
    # the plain mean with their SE, fall rates; None when the run has no such rows
    common: dict[str, float] | None = None
    # `coadapt verify` (coadapt_core.coadapt.verify): the first verified design of the run's
    # verification with the largest budget, a row of the store's verifications; None: none
    verified: dict[str, Any] | None = None
    design_names: list[str] = field(default_factory=list)  # the run's design space, in order
    design_units: list[str] = field(default_factory=list)
    design_discrete: list[bool] = field(default_factory=list)

    @property
    def method(self) -> str:
        return self.run["method"]

    @property
    def optimizer(self) -> str:
        """The optimizer the run used; `<optimizer>+<refiner>` when a refinement stage
        followed it (`refine_with`, coadapt/refine.py), a row of its own in every table."""
        name = str(self.run.get("optimizer") or "unknown")
        refiner = str((self.run.get("config") or {}).get("refine_with") or "").strip()
        return f"{name}+{refiner}" if refiner else name

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
        return (
            str(self.run.get("robot") or "?"),
            str(self.run.get("simulator") or "?"),
            str(self.run.get("preset") or "?"),
        )

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
            f"'{selection}' is neither a run nor a grid in store {store.url} (recent grids: "
            f"{grids})",
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
    variables = (
        space["variables"]
        if space
        else [{"name": f"x{i}", "type": "continuous"} for i in range(dim or 0)]
    )
    return RunFacts(
        run=run,
        best_design=None if best_design is None else [float(x) for x in np.ravel(best_design)],
        best_cost=None if best_cost is None or isinstance(best_cost, list) else float(best_cost),
        nominal_cost=as_float(summary.get("nominal_cost")),
        improvement=as_float(summary.get("improvement")),
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


def as_float(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


# -- sim-to-sim (Table 6's last column) ---------------------------------------------------------
def transfer_improvement(
    store: ResultsStore, facts: RunFacts, simulator: str | None = None, note: str = ""
) -> tuple[float | None, str]:
    """(improvement of the best design over the nominal one, note) from the run's transfer
    rows (kind "sim2sim", idx 0 best, 1 nominal, written by `coadapt_core.experiments.transfer`)
    on `simulator` (None: any). Without rows: (None, `note`, or that there are none). Reads
    only: the report never runs a simulation."""
    run = facts.run
    rows = [
        e
        for e in store.evaluations(run["id"], kind=TRANSFER_KIND)
        if simulator in (None, e.simulator)
    ]
    by_idx = {e.idx: e for e in rows}
    first = run["objectives"][0] if run["objectives"] else None
    if first is None or 0 not in by_idx or 1 not in by_idx or first not in by_idx[0].costs:
        return (
            None,
            note
            or "n/a: no sim-to-sim rows (`coadapt report` evaluates them unless --no-evaluate)",
        )
    read = sim2sim.reading(by_idx[0].costs, by_idx[1].costs, first)
    if read is not None:  # the protocol's figures: the answer, or why none, in one line
        rule = str((run.get("config") or {}).get("cost_rule") or "trimmed")
        measure = improvement_measure(objective_named(first))
        return read.answer, f"{by_idx[0].simulator}: {sim2sim.line(read, rule, measure)}"
    best_cost, nominal_cost = by_idx[0].costs[first], by_idx[1].costs[first]
    try:
        from coadapt_core.plugins import get_registry

        value = get_registry().create("objective", first).improvement(best_cost, nominal_cost)
    except Exception:  # an objective plugin not installed here: the default definition
        value = (nominal_cost - best_cost) / abs(nominal_cost) if nominal_cost else 0.0
    return float(value), f"{by_idx[0].simulator}, {len(rows)} designs"


# -- tables ------------------------------------------------------------------------------------


# -- the common yardstick (rows written by coadapt_core.experiments.yardstick) -----------------
def yardstick_improvement(
    store: ResultsStore, run_id: str, objective: str
) -> dict[str, float] | None:
    """The stored common-yardstick figures of one objective (improvement under the rule and
    under the plain mean, with SE; fall rates), or None when the run has no such rows."""
    rows = sorted(store.evaluations(run_id, kind=COMMON_KIND), key=lambda e: e.idx)
    if len(rows) < 2 or objective not in rows[0].costs:
        return None
    best, nominal = rows[0].costs, rows[1].costs
    keys = ("improvement", "improvement_se", "improvement_plain", "improvement_plain_se")
    if any(f"{objective}/{k}" not in best for k in keys):
        return None
    out = {k: float(best[f"{objective}/{k}"]) for k in keys}
    out.update(
        fall_rate=float(best.get("falls", np.nan)),
        nominal_fall_rate=float(nominal.get("falls", np.nan)),
        fall_rate_difference=float(best.get("falls/difference", np.nan)),
        fall_rate_difference_se=float(best.get("falls/difference_se", np.nan)),
    )
    return out


# -- with specialists (rows written by `coadapt verify`) ---------------------------------------
def verified_improvement(store: ResultsStore, run_id: str) -> dict[str, Any] | None:
    """The run's verification row with the largest budget (its first verified design: the
    best, or the chosen design of several objectives), else None."""
    rows = store.verifications([run_id])
    if not rows:
        return None
    top = max(int(r["budget"]) for r in rows)
    rows = [r for r in rows if int(r["budget"]) == top]
    first = next((r for r in rows if r["role"] in ("best", "chosen")), rows[0])
    return dict(first)
