"""Reports from the store: the paper's Table 6 (best design, improvement, sim-to-sim
improvement per objective x method x terrain) and Table 7 (interactions and wall clock per
method) as Markdown and CSV, Fig. 6-style cost heat-maps, convergence curves, surrogate
error and Pareto fronts as PNG, and one report.html holding them all.

The parts live beside it: each run's facts and the shared labels in `facts`, the tables in
`tables` (as Markdown and CSV: `table_markdown`), the figures in `report_figures`,
`heatmap_figure` and `pareto_figure`; their public names are imported here too."""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.facts import (
    METHOD_LABELS,
    RunFacts,
    objective_labels,
    run_facts,
    select_runs,
    transfer_improvement,
    verified_improvement,
    yardstick_improvement,
)
from coadapt_core.analysis.heatmap_figure import figure_heatmaps
from coadapt_core.analysis.pareto_figure import figure_pareto, hv_text
from coadapt_core.analysis.pareto_report import figure_pareto_seeds, pareto_markdown, pareto_rows
from coadapt_core.analysis.report_figures import (
    figure_convergence,
    figure_surrogate_error,
    figure_videos,
)
from coadapt_core.analysis.surrogate_figure import figure_surrogate_quality
from coadapt_core.analysis.table_markdown import (
    POOLING_NOTE,
    cell,
    common_cell,
    design_cell,
    design_columns,
    design_header,
    reduction_cell,
    table6_markdown,
    table7_markdown,
    table7_units,
    unreliable_mark,
    write_csv,
)
from coadapt_core.analysis.tables import table6_rows, table7_rows
from coadapt_core.results.schema import LANDSCAPE_METHOD
from coadapt_core.results.store import ResultsStore

__all__ = ["write_report"]

#: the steps of a report, as `progress` hears of them: reading runs, the figures, done
REPORT_STEPS = 7
#: report.html's style sheet
_STYLE = (
    "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
    "table{border-collapse:collapse;margin:1em 0;font-size:90%}"
    "td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
    "th{background:#eee}.scroll{overflow-x:auto}img{max-width:100%;height:auto}"
    "figure{margin:1.5em 0}figcaption{color:#444;font-size:90%;max-width:60em}</style>"
)


def _html_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    head = "".join(f"<th>{html.escape(label)}</th>" for _, label in columns)
    body = []
    for r in rows:
        cells = "".join(f"<td>{html.escape(str(r.get(key, '')))}</td>" for key, _ in columns)
        body.append(f"<tr>{cells}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _table6_html(t6: Sequence[dict[str, Any]]) -> str:
    """Table 6 as an HTML table: one row per group, the design's columns after the group's."""
    design = design_columns(t6)
    rows = []
    for r in t6:
        row = {
            "robot": r["robot"],
            "simulator": r["simulator"],
            "preset": r["preset"],
            "policy": r.get("policy") or "?",
            "numerics": r.get("numerics") or "not recorded",
            "objective": r["objective"],
            "method": METHOD_LABELS.get(r["method"], r["method"]),
            "optimizer": r["optimizer"],
            "terrain": r["terrain"],
            "runs": r["runs"],
            "best_cost": cell(r, "best_cost", spec=".5g"),
            "nominal_cost": cell(r, "nominal_cost", spec=".5g"),
            "improvement": cell(r, "improvement", pct=True) + unreliable_mark(r),
            "improvement_plain": cell(r, "improvement_plain", pct=True),
            "falls": cell(r, "best_fall_rate", pct=True)
            + " / "
            + cell(r, "nominal_fall_rate", pct=True),
            "common": common_cell(r),
            "reduction": reduction_cell(r),
            "sim2sim": cell(r, "sim2sim_improvement", pct=True),
            "sim2sim_note": r["sim2sim_note"],
        }
        row.update({f"d:{n}": design_cell(r, n, d) if f"{n}_n" in r else "" for n, _, d in design})
        rows.append(row)
    return _html_table(
        rows,
        [
            ("robot", "robot"),
            ("simulator", "simulator"),
            ("preset", "preset"),
            ("objective", "objective"),
            ("method", "method"),
            ("optimizer", "optimizer"),
            ("terrain", "terrain"),
            ("runs", "runs"),
        ]
        + [(f"d:{n}", design_header(n, u)) for n, u, _ in design]
        + [
            ("best_cost", "best cost"),
            ("nominal_cost", "nominal cost"),
            ("improvement", "improvement"),
            ("improvement_plain", "improvement (plain mean)"),
            ("falls", "fall rate best / nominal"),
            ("common", "common scenarios: improvement / plain mean / fall-rate difference"),
            (
                "reduction",
                "paper's measure 1 - c/c0 where it differs: run's cost / plain mean / "
                "common / common plain mean",
            ),
            ("sim2sim", "sim-to-sim improvement"),
            ("sim2sim_note", "sim-to-sim note"),
            ("policy", "starting policy"),
            ("numerics", "numerics"),
        ],
    )


def _table7_html(t7: Sequence[dict[str, Any]]) -> str:
    """Table 7 as an HTML table, interactions and wall clock in the units the Markdown uses."""
    iu, iname, tu, tname = table7_units(t7)
    rows = [
        {
            "robot": r["robot"],
            "simulator": r["simulator"],
            "preset": r["preset"],
            "method": METHOD_LABELS.get(r["method"], r["method"]),
            "optimizer": r["optimizer"],
            "runs": r["runs"],
            "inter_t": cell(r, "interactions_training", scale=iu),
            "inter_e": cell(r, "interactions_evaluation", scale=iu),
            "time_t": cell(r, "seconds_training", scale=tu),
            "time_e": cell(r, "seconds_evaluation", scale=tu),
            "designs_real": cell(r, "designs_real", spec=".0f"),
            "designs_surrogate": cell(r, "designs_surrogate", spec=".0f"),
        }
        for r in t7
    ]
    return _html_table(
        rows,
        [
            ("robot", "robot"),
            ("simulator", "simulator"),
            ("preset", "preset"),
            ("method", "method"),
            ("optimizer", "optimizer"),
            ("runs", "runs"),
            ("inter_t", f"interactions training ({iname})"),
            ("inter_e", f"interactions evaluation ({iname})"),
            ("time_t", f"wall clock training ({tname})"),
            ("time_e", f"wall clock evaluation ({tname})"),
            ("designs_real", "designs real"),
            ("designs_surrogate", "designs surrogate"),
        ],
    )


def _report_html(
    store: ResultsStore,
    title: str,
    n_runs: int,
    t6: Sequence[dict[str, Any]],
    t7: Sequence[dict[str, Any]],
    paper_html: str,
    figures: Sequence[tuple[Path, str]],
) -> str:
    """report.html: the two tables, the paper comparison and every figure with its caption."""
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>coadapt report</title>",
        _STYLE + "</head><body>",
        f"<h1>coadapt report — {html.escape(title)}</h1>",
        f"<p>Store: <code>{html.escape(store.url)}</code>; {n_runs} runs. Each number is the mean "
        "± sample standard deviation over the runs (seeds) of its row, with how many runs had it "
        f"(n); one row per method and optimizer. {html.escape(POOLING_NOTE)} A single run shows "
        "its own standard error (SE) when it recorded one.</p>",
        "<h2>Table 6 — optimization results</h2>",
        "<div class='scroll'>" + _table6_html(t6) + "</div>",
        "<h2>Table 7 — computational cost</h2>",
        _table7_html(t7),
        paper_html,
        "<h2>Figures</h2>",
    ]
    for path, caption in figures:
        parts.append(
            f"<figure><img src='{html.escape(path.name)}' alt='{html.escape(path.stem)}'>"
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )
    if not figures:
        parts.append("<p>No figures: the selected runs recorded no real evaluations.</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _add_transfer(
    store: ResultsStore,
    facts: Sequence[RunFacts],
    sim2sim: bool,
    simulator: str | None,
    notes: dict[str, str] | None,
) -> None:
    """Each run's sim-to-sim improvement and note, and its common-yardstick figures, as far as
    the store holds their rows (landscapes have none)."""
    for f in facts:
        if f.method == LANDSCAPE_METHOD:
            continue
        f.common = yardstick_improvement(store, f.run["id"], f.objective)
        f.verified = verified_improvement(store, f.run["id"])
        if sim2sim:
            f.sim2sim, f.sim2sim_note = transfer_improvement(
                store, f, simulator, (notes or {}).get(f.run["id"], "")
            )
        else:
            f.sim2sim, f.sim2sim_note = None, "n/a: not requested (--no-sim-to-sim)"


def _draw_figures(
    store: ResultsStore, facts: Sequence[RunFacts], out: Path, progress: Any
) -> list[tuple[Path, str]]:
    """Every figure of the report, in order, telling `progress` of each."""
    figures: list[tuple[Path, str]] = []
    steps = (
        ("heat-maps", lambda: figure_heatmaps(store, facts, out)),
        ("convergence", lambda: figure_convergence(store, facts, out)),
        ("surrogate error", lambda: figure_surrogate_error(facts, out)),
        ("surrogate quality", lambda: figure_surrogate_quality(facts, out)),
        ("Pareto fronts", lambda: figure_pareto(facts, out) + figure_pareto_seeds(facts, out)),
        ("videos", lambda: figure_videos(facts, out)),
    )
    for j, (what, draw) in enumerate(steps):
        if progress is not None:
            progress(1 + j, REPORT_STEPS, what)
        figures += draw()
    if progress is not None:
        progress(REPORT_STEPS, REPORT_STEPS, "done")
    return figures


def write_specialists(store: ResultsStore, run_ids: list[str], out: Path) -> dict[str, Path]:
    """specialists.md and .csv when the runs were verified: `coadapt verify`'s rows in the
    paper's Tables 4-5 layout, universal beside specialists (`analysis/specialists.py`)."""
    from coadapt_core.analysis.specialists import specialist_rows, specialists_markdown

    verified = specialist_rows(store, run_ids)
    if not verified:
        return {}
    write_csv(out / "specialists.csv", verified)
    (out / "specialists.md").write_text(specialists_markdown(verified))
    return {n: out / n for n in ("specialists.csv", "specialists.md")}


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
    if progress is not None:
        progress(0, REPORT_STEPS, "reading runs")
    _add_transfer(store, facts, sim2sim, transfer_simulator, transfer_notes)
    t6, t7 = table6_rows(facts), table7_rows(facts)
    files: dict[str, Path] = {}
    for name, rows, md in (
        ("table6", t6, table6_markdown(t6)),
        ("table7", t7, table7_markdown(t7)),
    ):
        write_csv(out / f"{name}.csv", rows)
        (out / f"{name}.md").write_text(md)
        files[f"{name}.csv"] = out / f"{name}.csv"
        files[f"{name}.md"] = out / f"{name}.md"
    # the paper's figures beside ours (coadapt_core/analysis/paper_comparison.py)
    from coadapt_core.analysis.paper_comparison import write_paper_comparison

    continuous = [f for f in facts if not any(f.design_discrete)]
    paper_files, paper_html = write_paper_comparison(
        t6, table7_rows(continuous), out, facts=continuous, objective_labels=objective_labels()
    )
    files.update(paper_files)
    files.update(write_specialists(store, [r["id"] for r in runs], out))  # Tables 4-5 layout
    fronts = pareto_rows(
        facts
    )  # multi-objective runs: hypervolume +- SE per run and per group of seeds
    if fronts:
        write_csv(out / "pareto.csv", fronts)
        (out / "pareto.md").write_text(pareto_markdown(fronts))
        files.update({"pareto.csv": out / "pareto.csv", "pareto.md": out / "pareto.md"})
    figures = _draw_figures(store, facts, out, progress)
    for path, _ in figures:
        files[path.name] = path
    if fronts:  # the hypervolume table beside the paper comparison
        paper_html += "<h2>Pareto fronts — hypervolume</h2>" + _html_table(
            [
                {
                    **r,
                    "hypervolume": hv_text(r["hypervolume"], r["hypervolume_se"]).removeprefix(
                        "hypervolume "
                    ),
                }
                for r in fronts
            ],
            [
                (k, k.replace("_", " "))
                for k in (
                    "method",
                    "optimizer",
                    "objectives",
                    "terrain",
                    "run",
                    "front_designs",
                    "hypervolume",
                )
            ],
        )
    (out / "report.html").write_text(
        _report_html(store, title, len(runs), t6, t7, paper_html, figures)
    )
    files["report.html"] = out / "report.html"
    return files
