"""The comparison beside the paper as people read it: the cells of each table (Table 6,
the method order, Table 7, Table 9) with its header, written as paper_comparison.md and as a
section of report.html, and the paragraph that says how to read them."""

from __future__ import annotations

import html
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coadapt_core.analysis.paper import PaperTables
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
        f"{_points(r['common_fall_rate_difference'], r['common_fall_rate_difference_se'])}"
    )


def _points(v: float | None, se: float | None = None) -> str:
    """A difference of two fall rates in percentage points, signed, as `coadapt run` says it."""
    if v is None:
        return "n/a"
    return f"{100 * v:+.1f}" + (f" ± {100 * se:.1f}" if se is not None else "") + " points"


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


def _pct_of(r: dict[str, Any], name: str) -> str:
    """'ours ± SE' of a percentage column `name` (its SE `<name>_se`)."""
    return _pct(r[name], r[f"{name}_se"])


def _pct_beside(r: dict[str, Any], name: str) -> str:
    """'ours ± SE / paper's' of a percentage column `name` (the paper's figure
    `paper_<name>`)."""
    return f"{_pct_of(r, name)} / {_pct(r[f'paper_{name}'])}"


def _ratio_beside(r: dict[str, Any], name: str, paper: str) -> str:
    """'ours ± SE, paper's' of a Table 7 ratio `name` beside the paper's ratio `paper`."""
    return f"{_ratio(r[name], r.get(f'{name}_se'))}, {_ratio(r[paper])}"


def _design_beside(r: dict[str, Any], name: str) -> str:
    """'ours ± SE / paper's' of a continuous design variable (a scale, two decimals)."""
    return f"{_num(r[name], r[f'{name}_se'])} / {r[f'paper_{name}']:.2f}"


def _motor_beside(r: dict[str, Any], name: str) -> str:
    """Each seed's motor type / the paper's (the verdict): a choice, not a mean."""
    return f"{r[name] or 'n/a'} / {r[f'paper_{name}']} ({r[f'{name}_verdict']})"


Row = dict[str, Any]
#: a comparison table as both renderings take it: (title, header, cells)
Table = tuple[str, list[str], list[list[str]]]


@dataclass(frozen=True)
class _Labels:
    """The names people read: objectives by the report's labels, methods by their table
    labels; a name without a label reads as itself."""

    objectives: dict[str, str]
    methods: dict[str, str]

    def order(self, text: str) -> str:
        """A method order ('a > b > c') in the methods' labels."""
        return " > ".join(self.methods.get(m, m) for m in text.split(" > ") if m)


@dataclass(frozen=True)
class _Column:
    """One column of a comparison table: its header and how a row reads in it."""

    head: str
    cell: Callable[[Row, _Labels], str]


def _field(name: str) -> Callable[[Row, _Labels], str]:
    """A cell that shows the row's `name` as it stands."""
    return lambda r, _: str(r[name])


def _of(read: Callable[..., str], *args: str) -> Callable[[Row, _Labels], str]:
    """A cell that shows `read(row, *args)`."""
    return lambda r, _: read(r, *args)


def _vs_paper(ours: str, paper: str | None = None) -> Callable[[Row, _Labels], str]:
    """A Table 7 cell: our ratio `<ours>_ratio` beside the paper's `paper_<paper>_ratio`
    (`paper`: `ours` unless named)."""
    return _of(_ratio_beside, f"{ours}_ratio", f"paper_{paper or ours}_ratio")


OBJECTIVE = _Column("Objective", lambda r, k: k.objectives.get(r["objective"], r["objective"]))
METHOD = _Column("Method", lambda r, k: k.methods.get(r["method"], r["method"]))
OPTIMIZER = _Column("Optimizer", _field("optimizer"))
TERRAIN = _Column("Terrain", _field("terrain"))
RUNS = _Column("Runs", _field("runs"))
THIGH = _Column("Thigh ours / paper", _of(_design_beside, "thigh"))
SHANK = _Column("Shank ours / paper", _of(_design_beside, "shank"))
DIRECTION = _Column("Direction", _field("direction"))
HIP = _Column("Hip motor per seed, ours / paper", _of(_motor_beside, "hip_motor"))
KNEE = _Column("Knee motor per seed, ours / paper", _of(_motor_beside, "knee_motor"))
#: the columns every improvement table shares: the paper's measure, the plain mean, the
#: common yardstick and the objective's own measure
IMPROVEMENT = (
    _Column("Improvement (1 - c/c0) ours / paper", _of(_pct_beside, "improvement")),
    _Column("Verdict", _field("improvement_verdict")),
    _Column("Plain-mean improvement ours", _of(_pct_of, "improvement_plain")),
    _Column("Verdict", _field("improvement_plain_verdict")),
    _Column("Common scenarios: improvement, plain mean, fall-rate difference", _of(_common)),
    _Column("Verdict (plain mean)", _field("common_improvement_plain_verdict")),
    _Column(OWN_HEADER, _of(_own)),
)
SIM2SIM = (
    _Column("Sim-to-sim ours / paper", _of(_pct_beside, "sim2sim_improvement")),
    _Column("Verdict", _field("sim2sim_verdict")),
)
TABLE6 = (
    OBJECTIVE,
    METHOD,
    OPTIMIZER,
    TERRAIN,
    RUNS,
    THIGH,
    SHANK,
    DIRECTION,
    *IMPROVEMENT,
    *SIM2SIM,
)
ORDER = (
    OBJECTIVE,
    TERRAIN,
    _Column("Measure", lambda r, _: MEASURES.get(r["measure"], r["measure"])),
    _Column("Paper's order", lambda r, k: k.order(r["paper_order"])),
    _Column("Our order", lambda r, k: k.order(r["our_order"])),
    _Column("Verdict", _field("verdict")),
)
TABLE7 = (
    METHOD,
    OPTIMIZER,
    RUNS,
    _Column("Pairs", lambda r, _: str(r.get("pairs", "n/a"))),
    _Column("Interactions / paper's method: ours, paper", _vs_paper("interactions")),
    _Column("Verdict", _field("interactions_verdict")),
    _Column("Evaluation interactions / paper's method: ours, paper", _vs_paper("evaluation")),
    _Column("Wall-clock pairs (same code)", lambda r, _: str(r.get("time_pairs", "n/a"))),
    _Column("Wall clock / paper's method: ours, paper", _vs_paper("time")),
    _Column("Verdict", _field("time_verdict")),
    _Column("Wall clock at equal machine speed: ours, paper", _vs_paper("speed_time", "time")),
    _Column("Verdict", _field("speed_time_verdict")),
)
TABLE9 = (OBJECTIVE, TERRAIN, OPTIMIZER, RUNS, THIGH, HIP, SHANK, KNEE, DIRECTION, *IMPROVEMENT)


def display_tables(
    rows6: Sequence[Row],
    order: Sequence[Row],
    rows7: Sequence[Row],
    rows9: Sequence[Row],
    objectives: dict[str, str],
) -> list[Table]:
    """(title, header, cells) of each comparison table, shared by Markdown and HTML;
    methods by their table labels, objectives by `objectives` (name -> label)."""
    labels = _Labels(objectives, {m.name: m.label for m in METHODS.values()})
    return [
        (title, [c.head for c in columns], [[c.cell(r, labels) for c in columns] for r in rows])
        for title, columns, rows in (
            ("Table 6 beside the paper's", TABLE6, rows6),
            ("Method order by improvement, per objective and terrain", ORDER, order),
            (
                "Table 7 beside the paper's (ratios to the paper's method in the same table)",
                TABLE7,
                rows7,
            ),
            ("Table 9 beside the paper's (mixed variables)", TABLE9, rows9),
        )
    ]


def _missing(
    rows6: Sequence[dict[str, Any]], rows9: Sequence[dict[str, Any]], paper: PaperTables
) -> tuple[int, int]:
    have6 = {(r["objective"], r["method"], r["terrain"]) for r in rows6}
    have9 = {(r["objective"], r["method"], r["terrain"]) for r in rows9}
    return len(set(paper.table6) - have6), len(set(paper.table9) - have9)


def how_to_read(
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
    tables: Sequence[Table], reading: str, figure: tuple[Path, str] | None = None
) -> str:
    """paper_comparison.md: the figure beside the paper (if any), each of `tables`
    (`display_tables`), then `reading` (`how_to_read`)."""
    lines = ["# Beside the paper", ""]
    if figure is not None:
        lines += [f"![{figure[1]}]({figure[0].name})", ""]
    for title, head, cells in tables:
        lines += [f"## {title}", ""]
        if not cells:
            lines += ["No run of this report has a cell in this table of the paper.", ""]
            continue
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(c) + " |" for c in cells]
        lines.append("")
    lines.append(reading)
    return "\n".join(lines) + "\n"


def comparison_html(tables: Sequence[Table], reading: str) -> str:
    """The section of report.html: `reading` (`how_to_read`), then each of `tables`."""
    parts = ["<h2>Beside the paper</h2>", f"<p>{html.escape(reading)}</p>"]
    for title, head, cells in tables:
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
