"""The runs page's numbers: one page of runs (sorted and filtered in the database, so a store
of 10 000 runs answers in milliseconds), each with its state, progress, setting, best
design, improvement +- SE and fall-rate difference as `coadapt report` computes them
(`coadapt_core.analysis.tables.table6_rows` on the run's facts, formatted by
`table_markdown.cell`), its warnings, and the grids with their cells by state."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa

from coadapt_core.analysis.facts import RunFacts, as_float
from coadapt_core.analysis.table_markdown import cell, design_cell
from coadapt_core.analysis.tables import table6_rows
from coadapt_core.results.export import space_of_run
from coadapt_core.results.rows import Evaluation, best_of, run_dict
from coadapt_core.results.schema import evaluations, grid_cells, runs, training_phases
from coadapt_core.results.store import ResultsStore

#: runs on one page of the runs table
PAGE_SIZE = 100
#: columns the runs table sorts by in the database ("improvement" is sorted after reading)
SORTS = {
    "created": runs.c.created_at,
    "updated": runs.c.updated_at,
    "id": runs.c.id,
    "status": runs.c.status,
    "robot": runs.c.robot,
    "method": runs.c.method,
    "optimizer": runs.c.optimizer,
    "objectives": runs.c.objectives,
    "terrain": runs.c.terrain,
    "seed": runs.c.seed,
}
#: columns the search box looks in
SEARCHED = ("id", "method", "optimizer", "objectives", "terrain", "robot", "grid_id", "cell")
#: evaluation kinds of the co-adaptation loop itself (progress counts these)
LOOP_KINDS = ("real", "surrogate")


def light_facts(run: dict[str, Any], real: Sequence[Evaluation] = ()) -> RunFacts:
    """A run's facts as far as the runs table needs them: what its summary recorded (its
    best design from `real` while it has none); the costs of interactions are left at 0."""
    summary = run.get("summary") or {}
    design, cost = best_of(run, list(real))
    space = space_of_run(run, len(design) if design is not None else None)
    variables = (
        space["variables"] if space else [{"name": f"x{i}"} for i in range(len(design or []))]
    )
    return RunFacts(
        run=run,
        best_design=None if design is None else [float(x) for x in design],
        best_cost=as_float(cost) if not isinstance(cost, list) else None,
        nominal_cost=as_float(summary.get("nominal_cost")),
        improvement=as_float(summary.get("improvement")),
        train_interactions=0,
        eval_interactions=0,
        train_seconds=0.0,
        eval_seconds=0.0,
        designs_real=0,
        designs_surrogate=0,
        design_names=[str(v["name"]) for v in variables],
        design_units=[str(v.get("unit") or "") for v in variables],
        design_discrete=[v.get("type") == "discrete" for v in variables],
    )


def points_cell(difference: float | None, se: float | None) -> str:
    """A fall-rate difference (best - nominal, a share) in percentage points, signed, as the
    CLI says it ("+1.6 ± 0.5 points SE (n=1)"): a difference of two rates is no percentage
    of anything."""
    if difference is None or not math.isfinite(difference):
        return "n/a"
    text = f"{100 * difference:+.1f}"
    if se is not None and math.isfinite(se):
        return f"{text} ± {100 * se:.1f} points SE (n=1)"
    return f"{text} points (n=1)"


def report_cells(facts: RunFacts) -> dict[str, Any]:
    """The run's figures as the report's Table 6 shows them: best design (per variable),
    best and nominal cost, improvement under the cost rule and the plain mean, fall rates and
    the fall-rate difference, each 'value +- SE (n=1)' where the run recorded an SE."""
    rows = table6_rows([facts])  # none for a landscape run
    row = rows[0] if rows else {}
    summary = facts.summary
    return {
        "best_design": [
            [name, design_cell(row, name, discrete)]
            for name, discrete in zip(facts.design_names, facts.design_discrete, strict=False)
            if row.get(f"{name}_n")
        ],
        "best_cost": cell(row, "best_cost", spec=".5g"),
        "nominal_cost": cell(row, "nominal_cost", spec=".5g"),
        "improvement": cell(row, "improvement", pct=True),
        "improvement_plain": cell(row, "improvement_plain", pct=True),
        "fall_rates": cell(row, "best_fall_rate", pct=True)
        + " / "
        + cell(row, "nominal_fall_rate", pct=True),
        "fall_rate_difference": points_cell(
            as_float(summary.get("fall_rate_difference")),
            as_float(summary.get("fall_rate_difference_se")),
        ),
        "reduction": cell(row, "reduction", pct=True) if row.get("reduction_differs") else "",
    }


def warnings_of(run: dict[str, Any]) -> list[str]:
    """What the run says to know before trusting it: its walking verdict and its warnings."""
    summary = run.get("summary") or {}
    out = []
    if summary.get("reliable") is False:
        out.append(f"unreliable: {summary.get('reliability') or 'the policy does not walk'}")
    out += [str(w) for w in summary.get("warnings") or [] if w]
    return out


def progress_of(
    run: dict[str, Any], done: dict[str, Any] | None, now: float | None = None
) -> dict[str, Any]:
    """Phase (outer iteration k of N), interactions so far and, for a running run, an ETA
    from the rate of its finished outer iterations; `done` is `progress_counts`' entry."""
    done = done or {}
    total = run.get("config", {}).get("outer_iterations")
    total = int(total) if isinstance(total, int | float) and total > 0 else None
    outer = done.get("outer")
    interactions = int(done.get("interactions") or 0)
    summary = run.get("summary") or {}
    if isinstance(summary.get("interactions"), int | float):
        interactions = int(summary["interactions"])
    eta = None
    if run.get("status") == "running" and total and outer is not None and outer > 0:
        elapsed = (now or time.time()) - float(run["created_at"])
        eta = max(0.0, elapsed * (total - outer) / outer)
    phase = "" if outer is None else f"outer {min(outer + 1, total or outer + 1)}/{total or '?'}"
    return {"phase": phase, "interactions": interactions, "eta_seconds": eta}


def progress_counts(store: ResultsStore, run_ids: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Per run: the highest outer iteration with rows and the interactions spent (training
    steps plus the loop's evaluations), in two grouped queries."""
    if not run_ids:
        return {}
    ids = list(run_ids)
    e = evaluations.c
    t = training_phases.c
    out: dict[str, dict[str, Any]] = {i: {"outer": None, "interactions": 0} for i in ids}
    with store.engine.connect() as conn:
        for run_id, outer, inter in conn.execute(
            sa.select(e.run_id, sa.func.max(e.outer), sa.func.sum(e.interactions))
            .where(e.run_id.in_(ids) & e.kind.in_(LOOP_KINDS))
            .group_by(e.run_id)
        ):
            out[run_id].update(outer=outer, interactions=int(inter or 0))
        for run_id, outer, steps in conn.execute(
            sa.select(t.run_id, sa.func.max(t.outer), sa.func.sum(t.steps))
            .where(t.run_id.in_(ids))
            .group_by(t.run_id)
        ):
            mine = out[run_id]
            mine["outer"] = max(x for x in (mine["outer"], outer) if x is not None)
            mine["interactions"] += int(steps or 0)
    return out


def _where(query: sa.Select, q: str, status: str, grid: str) -> sa.Select:
    if status:
        query = query.where(runs.c.status == status)
    if grid:
        query = query.where(runs.c.grid_id == grid)
    if q:
        query = query.where(
            sa.or_(*(runs.c[name].contains(q, autoescape=True) for name in SEARCHED))
        )
    return query


def _page_rows(
    store: ResultsStore, query: sa.Select, sort: str, descending: bool, page: int
) -> list[dict[str, Any]]:
    """The runs of one page, sorted by `sort` (in the database, or by improvement here)."""
    with store.engine.connect() as conn:
        if sort == "improvement":
            ids = conn.execute(query.with_only_columns(runs.c.id, runs.c.summary)).all()

            def key(row: Any) -> float:
                value = as_float(((_summary_of(row[1])) or {}).get("improvement"))
                return -math.inf if value is None else value

            ordered = sorted(ids, key=key, reverse=descending)
            chosen = [r[0] for r in ordered[page * PAGE_SIZE : (page + 1) * PAGE_SIZE]]
            found = {
                r["id"]: run_dict(r)
                for r in conn.execute(sa.select(runs).where(runs.c.id.in_(chosen))).mappings()
            }
            return [found[i] for i in chosen if i in found]
        column = SORTS[sort]
        order = column.desc() if descending else column.asc()
        tie = runs.c.id.desc() if descending else runs.c.id.asc()
        query = query.order_by(order, tie).limit(PAGE_SIZE).offset(page * PAGE_SIZE)
        return [run_dict(r) for r in conn.execute(query).mappings()]


def _summary_of(text: str | None) -> dict[str, Any] | None:
    try:
        value = json.loads(text) if text else None
    except ValueError:
        return None
    return value if isinstance(value, dict) else None


def runs_page(
    store: ResultsStore,
    *,
    q: str = "",
    status: str = "",
    grid: str = "",
    sort: str = "created",
    descending: bool = True,
    page: int = 0,
) -> dict[str, Any]:
    """One page of the runs table with the counts by state and the grids."""
    sort = sort if sort in SORTS or sort == "improvement" else "created"
    base = _where(sa.select(runs), q, status, grid)
    with store.engine.connect() as conn:
        total = conn.execute(
            sa.select(sa.func.count()).select_from(base.with_only_columns(runs.c.id).subquery())
        ).scalar_one()
        states = dict(
            conn.execute(sa.select(runs.c.status, sa.func.count()).group_by(runs.c.status)).all()
        )
    page = max(0, min(page, max(0, (total - 1) // PAGE_SIZE)))
    chosen = _page_rows(store, base, sort, descending, page)
    counts = progress_counts(store, [r["id"] for r in chosen])
    now = time.time()
    rows = []
    for run in chosen:
        real = store.evaluations(run["id"], kind="real") if not run.get("summary") else []
        facts = light_facts(run, real)
        rows.append(
            {
                **{k: run.get(k) for k in ("id", "status", "robot", "method", "optimizer")},
                **{k: run.get(k) for k in ("terrain", "seed", "preset", "grid_id", "cell")},
                "objectives": ",".join(run["objectives"]),
                "created_at": run["created_at"],
                "updated_at": run["updated_at"],
                "progress": progress_of(run, counts.get(run["id"]), now),
                "report": report_cells(facts),
                "warnings": warnings_of(run),
            }
        )
    return {
        "total": total,
        "page": page,
        "pages": max(1, math.ceil(total / PAGE_SIZE)),
        "page_size": PAGE_SIZE,
        "states": states,
        "rows": rows,
        "grids": grid_states(store),
        "now": now,
    }


def grid_states(store: ResultsStore) -> list[dict[str, Any]]:
    """Every grid with how many of its cells are in each state, newest first."""
    with store.engine.connect() as conn:
        counts = conn.execute(
            sa.select(grid_cells.c.grid_id, grid_cells.c.status, sa.func.count()).group_by(
                grid_cells.c.grid_id, grid_cells.c.status
            )
        ).all()
    by_grid: dict[str, dict[str, int]] = {g: {} for g in reversed(store.list_grids())}
    for grid_id, state, n in counts:
        by_grid.setdefault(grid_id, {})[state] = int(n)
    return [{"id": g, "cells": c} for g, c in by_grid.items()]
