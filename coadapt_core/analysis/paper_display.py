"""The comparison beside the paper as people read it: the cells of each table (Table 6,
the method order, Table 7, Table 9) with its header, written as paper_comparison.md and as a
section of report.html, and the paragraph that says how to read them."""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.paper import PaperTables, paper_tables
from coadapt_core.analysis.paper_cost import Z
from coadapt_core.analysis.paper_verdicts import MEASURES, NOMINAL_BAND
from coadapt_core.methods import METHODS


def _pct(v: float | None, se: float | None = None) -> str:
    if v is None:
        return "n/a"
    return f"{100 * v:.1f}%" + (f" ± {100 * se:.1f}" if se is not None else "")


def _num(v: float | None, se: float | None = None, spec: str = ".2f") -> str:
    if v is None:
        return "n/a"
    return format(v, spec) + (f" ± {format(se, spec)}" if se is not None else "")


def _common(r: dict[str, Any]) -> str:
    if r.get("common_improvement") is None:
        return "n/a (no common-scenario rows)"
    return (
        f"{_pct(r['common_improvement'], r['common_improvement_se'])}, "
        f"{_pct(r['common_improvement_plain'], r['common_improvement_plain_se'])}, "
        f"{_pct(r['common_fall_rate_difference'], r['common_fall_rate_difference_se'])}"
    )


#: the own-measure column's header: our improvements as the objective itself reports them
OWN_HEADER = (
    "Ours in the objective's own measure, where it differs (tracking: 1 - √(c/c0)): run's cost, "
    "plain mean, common, common plain mean"
)


def _own(r: dict[str, Any]) -> str:
    if not r.get("measure_differs"):
        return "same"
    return ", ".join(
        _pct(r.get(f"{n}_own"), r.get(f"{n}_own_se"))
        for n in (
            "improvement",
            "improvement_plain",
            "common_improvement",
            "common_improvement_plain",
        )
    )


def _ratio(v: float | None, se: float | None = None) -> str:
    return "n/a" if v is None else f"{v:.2f}" if se is None else f"{v:.2f} ± {se:.2f}"


def _pct_beside(r: dict[str, Any], name: str) -> str:
    """'ours ± SE / paper's' of a percentage column `name` (its SE `<name>_se`, the paper's
    figure `paper_<name>`)."""
    return f"{_pct(r[name], r[f'{name}_se'])} / {_pct(r[f'paper_{name}'])}"


def _ratio_beside(r: dict[str, Any], name: str, paper: str) -> str:
    """'ours ± SE, paper's' of a Table 7 ratio `name` beside the paper's ratio `paper`."""
    return f"{_ratio(r[name], r.get(f'{name}_se'))}, {_ratio(r[paper])}"


def _design_beside(r: dict[str, Any], name: str) -> str:
    """'ours ± SE / paper's' of a continuous design variable (a scale, two decimals)."""
    return f"{_num(r[name], r[f'{name}_se'])} / {r[f'paper_{name}']:.2f}"


def _motor_beside(r: dict[str, Any], name: str) -> str:
    """Each seed's motor type / the paper's (the verdict): a choice, not a mean."""
    return f"{r[name] or 'n/a'} / {r[f'paper_{name}']} ({r[f'{name}_verdict']})"


#: the columns every improvement table shares: the paper's measure, the plain mean, the
#: common yardstick and the objective's own measure
IMPROVEMENT_HEAD = (
    "Improvement (1 - c/c0) ours / paper",
    "Verdict",
    "Plain-mean improvement ours",
    "Verdict",
    "Common scenarios: improvement, plain mean, fall-rate difference",
    "Verdict (plain mean)",
    OWN_HEADER,
)
HEAD6 = (
    "Objective",
    "Method",
    "Optimizer",
    "Terrain",
    "Runs",
    "Thigh ours / paper",
    "Shank ours / paper",
    "Direction",
    *IMPROVEMENT_HEAD,
    "Sim-to-sim ours / paper",
    "Verdict",
)
HEAD_ORDER = ("Objective", "Terrain", "Measure", "Paper's order", "Our order", "Verdict")
HEAD7 = (
    "Method",
    "Optimizer",
    "Runs",
    "Pairs",
    "Interactions / paper's method: ours, paper",
    "Verdict",
    "Evaluation interactions / paper's method: ours, paper",
    "Wall-clock pairs (same code)",
    "Wall clock / paper's method: ours, paper",
    "Verdict",
    "Wall clock at equal machine speed: ours, paper",
    "Verdict",
)
HEAD9 = (
    "Objective",
    "Terrain",
    "Optimizer",
    "Runs",
    "Thigh ours / paper",
    "Hip motor per seed, ours / paper",
    "Shank ours / paper",
    "Knee motor per seed, ours / paper",
    "Direction",
    *IMPROVEMENT_HEAD,
)


def _improvement_cells(r: dict[str, Any]) -> list[str]:
    """The cells under `IMPROVEMENT_HEAD` of a Table 6 or Table 9 comparison row."""
    return [
        _pct_beside(r, "improvement"),
        r["improvement_verdict"],
        _pct(r["improvement_plain"], r["improvement_plain_se"]),
        r["improvement_plain_verdict"],
        _common(r),
        r["common_improvement_plain_verdict"],
        _own(r),
    ]


def _cells6(r: dict[str, Any], objectives: dict[str, str], methods: dict[str, str]) -> list[str]:
    return [
        objectives.get(r["objective"], r["objective"]),
        methods.get(r["method"], r["method"]),
        r["optimizer"],
        r["terrain"],
        str(r["runs"]),
        _design_beside(r, "thigh"),
        _design_beside(r, "shank"),
        r["direction"],
        *_improvement_cells(r),
        _pct_beside(r, "sim2sim_improvement"),
        r["sim2sim_verdict"],
    ]


def _order_cells(
    r: dict[str, Any], objectives: dict[str, str], methods: dict[str, str]
) -> list[str]:
    def labels(order: str) -> str:
        return " > ".join(methods.get(m, m) for m in order.split(" > ") if m)

    return [
        objectives.get(r["objective"], r["objective"]),
        r["terrain"],
        MEASURES.get(r["measure"], r["measure"]),
        labels(r["paper_order"]),
        labels(r["our_order"]),
        r["verdict"],
    ]


def _cells7(r: dict[str, Any], methods: dict[str, str]) -> list[str]:
    return [
        methods.get(r["method"], r["method"]),
        str(r["optimizer"]),
        str(r["runs"]),
        str(r.get("pairs", "n/a")),
        _ratio_beside(r, "interactions_ratio", "paper_interactions_ratio"),
        r["interactions_verdict"],
        _ratio_beside(r, "evaluation_ratio", "paper_evaluation_ratio"),
        str(r.get("time_pairs", "n/a")),
        _ratio_beside(r, "time_ratio", "paper_time_ratio"),
        r["time_verdict"],
        _ratio_beside(r, "speed_time_ratio", "paper_time_ratio"),
        r["speed_time_verdict"],
    ]


def _cells9(r: dict[str, Any], objectives: dict[str, str]) -> list[str]:
    return [
        objectives.get(r["objective"], r["objective"]),
        r["terrain"],
        r["optimizer"],
        str(r["runs"]),
        _design_beside(r, "thigh"),
        _motor_beside(r, "hip_motor"),
        _design_beside(r, "shank"),
        _motor_beside(r, "knee_motor"),
        r["direction"],
        *_improvement_cells(r),
    ]


def _display(
    rows6: Sequence[dict[str, Any]],
    order: Sequence[dict[str, Any]],
    rows7: Sequence[dict[str, Any]],
    rows9: Sequence[dict[str, Any]],
    objectives: dict[str, str],
) -> list[tuple[str, list[str], list[list[str]]]]:
    """(title, header, cells) of each comparison table, shared by Markdown and HTML;
    methods by their table labels, objectives by `objectives` (name -> label)."""
    methods = {m.name: m.label for m in METHODS.values()}
    return [
        (
            "Table 6 beside the paper's",
            list(HEAD6),
            [_cells6(r, objectives, methods) for r in rows6],
        ),
        (
            "Method order by improvement, per objective and terrain",
            list(HEAD_ORDER),
            [_order_cells(r, objectives, methods) for r in order],
        ),
        (
            "Table 7 beside the paper's (ratios to the paper's method in the same table)",
            list(HEAD7),
            [_cells7(r, methods) for r in rows7],
        ),
        (
            "Table 9 beside the paper's (mixed variables)",
            list(HEAD9),
            [_cells9(r, objectives) for r in rows9],
        ),
    ]


def _missing(
    rows6: Sequence[dict[str, Any]], rows9: Sequence[dict[str, Any]], paper: PaperTables
) -> tuple[int, int]:
    have6 = {(r["objective"], r["method"], r["terrain"]) for r in rows6}
    have9 = {(r["objective"], r["method"], r["terrain"]) for r in rows9}
    return len(set(paper.table6) - have6), len(set(paper.table9) - have9)


def _explanation(
    paper: PaperTables, rows6: Sequence[dict[str, Any]], rows9: Sequence[dict[str, Any]]
) -> str:
    miss6, miss9 = _missing(rows6, rows9, paper)
    return (
        f"Paper: {paper.citation}. Ours: mean ± standard error over seeds (sample std / √n; one "
        "run: the SE it recorded). Direction: thigh and shank longer or shorter than nominal (a "
        f"scale within {NOMINAL_BAND} of 1.0 counts as nominal), as the paper's or not. "
        f"Improvement verdict: 'within' when the paper's figure lies within {Z:g} SE of our mean "
        "(plus the paper's rounding), else ours is 'above' or 'below' it; the paper's improvement "
        "is a plain mean over its evaluation scenarios, so the plain-mean column is the "
        "like-for-like one. Every improvement here, and every verdict, is the paper's measure, "
        "the cost reduction 1 - c/c0 of the mean cost (tracking: of P_cmd = e_v² + e_w², eq. 6; "
        "the paper says it compares tracking by 'the tracking error', which we read as P_cmd); "
        "where an objective reports its own improvement otherwise (tracking: the reduction of the "
        "RMS error, 1 - √(c/c0), about half as large: the other reading), each run's figure is "
        "restated (its SE by the delta method) and its own is shown beside it. Common scenarios: "
        "each run's best design and its nominal design re-evaluated with the run's own policy on "
        "one scenario set shared by every run of a terrain and preset (one yardstick for all "
        "methods; fall-rate difference in points, paired). Sim-to-sim: the paper trains in Isaac "
        "Gym and transfers to PyBullet; we train in another simulator and transfer to a second "
        "one (the sim-to-sim column of Table 6). Table 7: the paper's hours are on its hardware "
        "at its scale; ratios to the paper's method compare: each run's against the paper's "
        "method's run of the same cell (objective, terrain, seed), mean ± SE over the pairs; a "
        f"verdict of costlier or cheaper needs the ratio {Z:g} SE away from 1; wall clocks pair "
        "only runs made by the same code (the same clean git commit: a speed-up changes them) and "
        "carry the machine's load; at equal machine speed, each wall clock is divided by the "
        "run's own seconds per training interaction, the machine's speed while it ran, measured "
        f"on work every training method does alike. Paper cells with no run here: {miss6} of "
        f"{len(paper.table6)} (Table 6), {miss9} of {len(paper.table9)} (Table 9): not yet run."
    )


def comparison_markdown(
    rows6,
    order,
    rows7,
    rows9,
    paper: PaperTables | None = None,
    objectives: dict[str, str] | None = None,
    figure: tuple[Path, str] | None = None,
) -> str:
    paper = paper or paper_tables()
    lines = ["# Beside the paper", ""]
    if figure is not None:
        lines += [f"![{figure[1]}]({figure[0].name})", ""]
    for title, head, cells in _display(rows6, order, rows7, rows9, objectives or {}):
        lines += [f"## {title}", ""]
        if not cells:
            lines += ["No run of this report has a cell in this table of the paper.", ""]
            continue
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(c) + " |" for c in cells]
        lines.append("")
    lines.append(_explanation(paper, rows6, rows9))
    return "\n".join(lines) + "\n"


def comparison_html(
    rows6,
    order,
    rows7,
    rows9,
    paper: PaperTables | None = None,
    objectives: dict[str, str] | None = None,
) -> str:
    paper = paper or paper_tables()
    parts = [
        "<h2>Beside the paper</h2>",
        f"<p>{html.escape(_explanation(paper, rows6, rows9))}</p>",
    ]
    for title, head, cells in _display(rows6, order, rows7, rows9, objectives or {}):
        parts.append(f"<h3>{html.escape(title)}</h3>")
        if not cells:
            parts.append("<p>No run of this report has a cell in this table of the paper.</p>")
            continue
        header = "".join(f"<th>{html.escape(h)}</th>" for h in head)
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in cells
        )
        table = f"<table><thead><tr>{header}</tr></thead><tbody>{body}</tbody></table>"
        parts.append(f"<div class='scroll'>{table}</div>")
    return "\n".join(parts)


def figure_html(path: Path, caption: str) -> str:
    """A figure of report.html: the picture beside the report, with its caption."""
    image = f"<img src='{html.escape(path.name)}' alt='{html.escape(path.stem)}'>"
    return f"<figure>{image}<figcaption>{html.escape(caption)}</figcaption></figure>"
