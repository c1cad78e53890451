"""A grid's page: its cells by state (with the cells that ran again, on a cluster or after a
failure) and the comparison tables as `coadapt report` computes them: Table 6 and Table 7
(`coadapt_core.analysis.tables`) over the grid's finished runs, and Tables 6, 7 and 9
beside the paper's (`coadapt_core.analysis.paper_comparison`, `paper_display`)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

from coadapt_core.analysis.facts import (
    METHOD_LABELS,
    RunFacts,
    objective_labels,
    run_facts,
    transfer_improvement,
    verified_improvement,
    yardstick_improvement,
)
from coadapt_core.analysis.paper import paper_tables
from coadapt_core.analysis.paper_comparison import (
    order_comparison,
    table6_comparison,
    table9_comparison,
)
from coadapt_core.analysis.paper_cost import table7_comparison
from coadapt_core.analysis.paper_display import display_tables, how_to_read
from coadapt_core.analysis.table_markdown import (
    cell,
    design_columns,
    design_header,
    result_cells,
    specialist_cell,
)
from coadapt_core.analysis.tables import table6_rows, table7_rows
from coadapt_core.errors import UserError
from coadapt_core.results.schema import LANDSCAPE_METHOD
from coadapt_core.results.store import ResultsStore

#: a table as the page draws it: (title, header, rows of cells)
Table = tuple[str, list[str], list[list[str]]]


def _table6(t6: Sequence[dict[str, Any]]) -> Table:
    design = design_columns(t6)
    head = ["objective", "method", "optimizer", "terrain", "runs"]
    head += [design_header(n, u) for n, u, _ in design]
    head += ["best cost", "nominal cost", "improvement", "improvement (plain mean)"]
    head += ["fall rate best / nominal", "with specialists (universal): verdict"]
    rows = []
    for r in t6:
        cells = [
            r["objective"],
            METHOD_LABELS.get(r["method"], r["method"]),
            r["optimizer"],
            r["terrain"],
            str(r["runs"]),
        ]
        rows.append(cells + result_cells(r, design) + [specialist_cell(r)])
    return "Table 6 — optimization results", head, rows


def _table7(t7: Sequence[dict[str, Any]]) -> Table:
    head = ["method", "optimizer", "runs", "interactions training", "interactions evaluation"]
    head += ["wall clock training (s)", "wall clock evaluation (s)", "designs real"]
    head += ["designs surrogate"]
    rows = [
        [
            METHOD_LABELS.get(r["method"], r["method"]),
            r["optimizer"],
            str(r["runs"]),
            cell(r, "interactions_training", spec=".4g"),
            cell(r, "interactions_evaluation", spec=".4g"),
            cell(r, "seconds_training", spec=".4g"),
            cell(r, "seconds_evaluation", spec=".4g"),
            cell(r, "designs_real", spec=".0f"),
            cell(r, "designs_surrogate", spec=".0f"),
        ]
        for r in t7
    ]
    return "Table 7 — computational cost", head, rows


def _beside_paper(t6: Sequence[dict[str, Any]], facts: Sequence[RunFacts]) -> dict[str, Any]:
    """Tables 6, 7 and 9 beside the paper's and how to read them, as report.html has them."""
    paper = paper_tables()
    continuous = [f for f in facts if not any(f.design_discrete)]
    rows6 = table6_comparison(t6, paper)
    rows9 = table9_comparison(t6, paper)
    tables = display_tables(
        rows6,
        order_comparison(rows6, paper),
        table7_comparison(table7_rows(continuous), continuous, paper),
        rows9,
        objective_labels(),
    )
    return {"tables": [list(t) for t in tables], "reading": how_to_read(paper, rows6, rows9)}


def grid_page(store: ResultsStore, grid_id: str) -> dict[str, Any]:
    """Everything a grid's page shows."""
    grid = store.get_grid(grid_id)
    if grid is None:
        raise UserError(f"grid '{grid_id}' is not in the store", field="grid")
    cells = sorted(store.cells(grid_id).values(), key=lambda c: c["cell"])
    ids = sorted({c["run_id"] for c in cells if c["run_id"]})
    runs = {r["id"]: r for r in store.list_runs(run_ids=ids)} if ids else {}
    finished = [r for r in runs.values() if r["status"] == "finished"]
    facts = [run_facts(store, r) for r in finished if r["method"] != LANDSCAPE_METHOD]
    for f in facts:
        # the sim-to-sim and common-yardstick columns as far as the store holds their rows
        f.common = yardstick_improvement(store, f.run["id"], f.objective)
        f.sim2sim, f.sim2sim_note = transfer_improvement(store, f)
        f.verified = verified_improvement(store, f.run["id"])  # `coadapt verify`'s rows
    t6 = table6_rows(facts)
    return {
        "grid": {"id": grid_id, "created_at": grid["created_at"]},
        "states": dict(Counter(c["status"] for c in cells)),
        "cells": [
            {
                "cell": c["cell"],
                "status": c["status"],
                "attempts": int(c["attempts"] or 0),
                "ran_again": int(c["attempts"] or 0) > 1,
                "run_id": c["run_id"],
                "run_status": (runs.get(c["run_id"]) or {}).get("status"),
                "last_error": c["last_error"] or "",
            }
            for c in cells
        ],
        "tables": [list(_table6(t6)), list(_table7(table7_rows(facts)))] if facts else [],
        "paper": _beside_paper(t6, facts) if facts else None,
    }
