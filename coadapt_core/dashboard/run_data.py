"""A run's page and the comparison of runs: the run's report figures (`runs_data.report_cells`
on its full facts, `coadapt_core.analysis.facts.run_facts`), its convergence as the report
draws it (`report_figures.convergence_series`) with the final check +- SE, every evaluated
design (real and surrogate apart), the surrogate's error by round, the Pareto front with SEs
and hypervolume (`pareto_figure.pareto_points`, `pareto_report.pareto_rows`), the training
phases, the files of its folder, its configuration and the commands that resume it and hand
its design off."""

from __future__ import annotations

import math
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import RunFacts, as_float, run_facts
from coadapt_core.analysis.figures import cost_unit
from coadapt_core.analysis.pareto_figure import hv_text, pareto_points
from coadapt_core.analysis.pareto_report import pareto_rows
from coadapt_core.analysis.report_figures import convergence_series
from coadapt_core.dashboard.files import RunFolders
from coadapt_core.dashboard.runs_data import (
    progress_counts,
    progress_of,
    report_cells,
    warnings_of,
)
from coadapt_core.numerics import numerics_text
from coadapt_core.results.store import ResultsStore

#: the run's facts the page shows in its heading table
RUN_FIELDS = (
    "id",
    "status",
    "robot",
    "simulator",
    "method",
    "optimizer",
    "objectives",
    "terrain",
    "seed",
    "preset",
    "grid_id",
    "cell",
    "code_version",
    "git_commit",
    "run_dir",
    "created_at",
    "updated_at",
    "finished_at",
)
#: a training phase's measurements the page draws besides its reward, one chart per unit
#: (their scales differ tenfold): (unit, chart title, [(key, name)]) — the forward speed and
#: the velocity tracking error (mean |v_xy_cmd - v_xy|, `learning.iteration_stats`) in m/s,
#: the episode length in s
TRAINING_MEASURES = (
    (
        "m/s",
        "Training phases: forward speed and velocity tracking error",
        (("vx", "forward speed"), ("tracking_error", "tracking error |v_cmd − v|")),
    ),
    ("s", "Training phases: episode length", (("episode_length_s", "episode length"),)),
)
TRAINING_EXTRAS = tuple(key for _, _, series in TRAINING_MEASURES for key, _ in series)


def _finite(values: Any) -> list[float | None]:
    """JSON-safe numbers: NaN and infinities become null."""
    return [
        None if v is None or not math.isfinite(float(v)) else float(v)
        for v in np.ravel(np.asarray(values, dtype=float))
    ]


def _evaluations(facts_real: Any, others: Sequence[Any]) -> list[dict[str, Any]]:
    rows = []
    for e in [*facts_real, *others]:
        rows.append(
            {
                "outer": e.outer,
                "inner": e.inner,
                "idx": e.idx,
                "kind": e.kind,
                "design": _finite(e.design),
                "costs": {k: _finite([v])[0] for k, v in (e.costs or {}).items()},
                "surrogate_error": {
                    k: _finite([v])[0] for k, v in (e.surrogate_error or {}).items()
                },
                "interactions": e.interactions,
                "simulator": e.simulator,
            }
        )
    rows.sort(key=lambda r: (r["outer"], r["inner"], r["kind"], r["idx"]))
    return rows


def _surrogate_error(facts: RunFacts) -> list[dict[str, Any]]:
    """The relative surrogate error (%) of each real evaluation the surrogate also scored,
    by outer iteration: what the report's surrogate_error.png plots, per round."""
    out = []
    for e in facts.real:
        for objective, err in (e.surrogate_error or {}).items():
            real = e.costs.get(objective)
            if real is not None and math.isfinite(real) and real != 0 and math.isfinite(err):
                out.append(
                    {"outer": e.outer, "objective": objective, "percent": 100 * err / abs(real)}
                )
    return out


def _convergence(store: ResultsStore, facts: RunFacts) -> dict[str, Any]:
    """Best in-run real cost so far against interactions (the report's convergence.png) and
    the final check of the returned design +- its SE."""
    if len(facts.run["objectives"]) > 1:
        note = "a run of several objectives has no single best cost: see its Pareto front"
        return {"x": [], "y": [], "final": None, "note": note}
    if not facts.run["objectives"] or not facts.real:
        return {"x": [], "y": [], "final": None, "note": "no real evaluation recorded yet"}
    x, y = convergence_series(store, facts)
    final = None
    summary = facts.summary
    if facts.best_cost is not None and summary.get("best_cost") is not None:
        # as the run folder's convergence.png: the final check sits after the curve by the
        # check's own interactions, the nominal design's final-check cost is a line
        final = {
            "cost": facts.best_cost,
            "se": as_float(summary.get("best_cost_se")),
            "interactions": int(as_float(summary.get("final_interactions")) or 0),
            "nominal": facts.nominal_cost,
            "nominal_se": as_float(summary.get("nominal_cost_se")),
        }
    objective = facts.run["objectives"][0]
    unit = cost_unit(objective, [summary])
    return {
        "x": _finite(x),
        "y": _finite(y),
        "final": final,
        "note": "",
        "y_label": f"{objective} cost per step{unit}",
    }


def _pareto(facts: RunFacts) -> dict[str, Any] | None:
    """The run's front for two or more objectives: its points with SEs, every evaluated
    point, the returned design, the front's size and hypervolume +- SE (pareto.md's row)."""
    if len(facts.run["objectives"]) < 2 or not facts.real:
        return None
    points = pareto_points(facts)
    rows = [r for r in pareto_rows([facts]) if r["run"] == facts.run["id"]]
    front, front_se = points["front"], points["front_se"]
    return {
        "objectives": list(points["objectives"]),
        "front": [_finite(p) for p in front],
        "front_se": None if front_se is None else [_finite(p) for p in front_se],
        "designs": [_finite(d) for d in points["designs"]],
        "evaluated": [_finite(p) for p in points["evaluated"]],
        "returned": points["returned"],
        "nominal": None if points["nominal"] is None else _finite(points["nominal"]),
        "front_designs": rows[0]["front_designs"] if rows else len(front),
        "hypervolume": hv_text(points["hypervolume"], points["hypervolume_se"]) or "n/a",
        "source": points["source"],
    }


def _commands(run: dict[str, Any], folder: Path | None) -> dict[str, str]:
    """The commands that continue the run and hand its design off, as the CLI takes them."""
    where = str(folder) if folder is not None else run["id"]
    resume = f"coadapt run --resume {shlex.quote(where)}"
    handoff = f"coadapt handoff {shlex.quote(where)}"
    if len(run["objectives"]) >= 2:
        handoff += " --pick knee"
    return {"resume": resume, "handoff": handoff}


def _verification(store: ResultsStore, run_id: str) -> str:
    """`coadapt verify`'s verdict line of each verified design (the largest budget first),
    or 'not verified' (`coadapt_core.coadapt.verify`)."""
    rows = sorted(store.verifications([run_id]), key=lambda r: -int(r["budget"]))
    lines = [
        f"{(r['detail'] or {}).get('line') or r['verdict']} ({int(r['budget']):,} interactions "
        "per specialist)"
        for r in rows
    ]
    return "; ".join(lines) or "not verified"


def run_page(store: ResultsStore, folders: RunFolders, run_id: str) -> dict[str, Any]:
    """Everything a run's page shows, from the store and the run's folder."""
    run = store.get_run(run_id)
    facts = run_facts(store, run)
    others = [e for e in store.evaluations(run_id) if e.kind != "real"]
    counts = progress_counts(store, [run_id])
    folder = folders.folder_of(run)
    return {
        "run": {k: run.get(k) for k in RUN_FIELDS} | {"objectives": run["objectives"]},
        "design_names": facts.design_names,
        "design_units": facts.design_units,
        "report": report_cells(facts),
        "numerics": numerics_text(facts.summary.get("numerics")),
        "verification": _verification(store, run_id),
        "warnings": warnings_of(run),
        "progress": progress_of(run, counts.get(run_id)),
        "counts": {
            kind: sum(1 for e in [*facts.real, *others] if e.kind == kind)
            for kind in sorted({"real", *(e.kind for e in others)})
        },
        "evaluations": _evaluations(facts.real, others),
        "convergence": _convergence(store, facts),
        "surrogate_error": _surrogate_error(facts),
        "pareto": _pareto(facts),
        "training_measures": [
            {"unit": unit, "title": title, "series": [list(s) for s in series]}
            for unit, title, series in TRAINING_MEASURES
        ],
        "training": [
            {
                "outer": t["outer"],
                "idx": t["idx"],
                "steps": int(t["steps"]),
                "seconds": float(t["seconds"]),
                "final_reward": as_float(t["final_reward"]),
                # what the learner measured besides the reward (coadapt_core.learning.backend)
                **{k: as_float((t["extra"] or {}).get(k)) for k in TRAINING_EXTRAS},
            }
            for t in store.training(run_id)
        ],
        "files": folders.listing(run),
        "folder": folders.state(run),
        "config": run.get("config") or {},
        "commands": _commands(run, folder),
    }


def compare_page(store: ResultsStore, run_ids: Sequence[str]) -> dict[str, Any]:
    """Runs side by side: each one's setting, best design, costs and improvement +- SE as the
    report gives them, and its convergence."""
    out = []
    for run_id in run_ids:
        run = store.get_run(run_id)
        facts = run_facts(store, run)
        out.append(
            {
                "run": {k: run.get(k) for k in RUN_FIELDS} | {"objectives": run["objectives"]},
                "report": report_cells(facts),
                "warnings": warnings_of(run),
                "convergence": _convergence(store, facts),
                "evaluated": sum(1 for e in facts.real) + facts.designs_surrogate,
            }
        )
    return {"runs": out}
