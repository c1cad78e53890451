"""The paper's Tables 6, 7 and 9 shipped as data (coadapt_core/analysis/paper_du2025.json):
complete, in the registry's names, and equal number for number to the paper's text
(../shared/paper-du2025-coadaptation.txt, which CI has; that check alone is skipped where
the file is absent)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from coadapt_core.analysis.paper import paper_tables
from coadapt_core.methods import METHOD_NAMES

PAPER_TEXT = Path(__file__).resolve().parents[2].parent / "shared" / "paper-du2025-coadaptation.txt"
OBJECTIVES, TERRAINS = ("tracking", "power", "torque"), ("flat", "slope", "random")
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def test_tables_are_complete_and_use_the_registry_names():
    paper = paper_tables()
    assert paper.methods == list(METHOD_NAMES) and paper.reference_method == METHOD_NAMES[0]
    assert set(paper.table6) == {
        (o, m, t) for o in OBJECTIVES for m in METHOD_NAMES for t in TERRAINS
    }
    assert set(paper.table9) == {(o, METHOD_NAMES[0], t) for o in OBJECTIVES for t in TERRAINS}
    assert "10.1016/j.birob.2025.100255" in paper.citation and "Du et al. 2025" in paper.citation
    # spot checks, as printed: ours, torque on flat ground; BO's Table 7 row;
    # Table 9 tracking on slope
    assert paper.table6[("torque", "ours", "flat")] == {
        "thigh": 0.51,
        "shank": 0.54,
        "improvement": pytest.approx(0.459),
        "sim2sim_improvement": pytest.approx(0.28),
    }
    assert paper.table6[("tracking", "bo-specialized", "random")]["improvement"] == pytest.approx(
        -0.039
    )
    assert paper.table7["bo-specialized"] == {
        "interactions_training": 200e6,
        "interactions_evaluation": 0.0,
        "interactions_total": 200e6,
        "hours_training": 2.67,
        "hours_evaluation": 0.33,
        "hours_total": 3.0,
    }
    assert paper.table9[("tracking", "ours", "slope")] == {
        "thigh": 1.24,
        "hip_motor": 2,
        "shank": 1.36,
        "knee_motor": 3,
        "improvement": pytest.approx(0.044),
    }
    for m, r in paper.table7.items():  # each printed total is its two parts
        assert r["interactions_total"] == pytest.approx(
            r["interactions_training"] + r["interactions_evaluation"]
        ), m
        assert r["hours_total"] == pytest.approx(
            r["hours_training"] + r["hours_evaluation"], abs=0.011
        ), m


def _table_lines(text: str, title: str, count: int) -> list[str]:
    """The `count` data lines of the table captioned `title` (lines holding numbers)."""
    lines = text.splitlines()
    start = lines.index(title)
    rows = []
    for line in lines[start + 1 :]:
        cells = [c for c in line.split("\t") if c.strip()]
        if len(NUMBER.findall(line)) >= 3 and cells and not cells[0].startswith("**"):
            rows.append(line)
            if len(rows) == count:
                return rows
    raise AssertionError(f"{title}: found {len(rows)} of {count} rows")


@pytest.mark.skipif(not PAPER_TEXT.is_file(), reason=f"the paper's text is not at {PAPER_TEXT}")
def test_every_number_is_the_papers():
    text = PAPER_TEXT.read_text()
    paper = paper_tables()
    # Table 6: per line, (thigh, shank, improvement %, sim-to-sim %) for flat, slope, random
    lines = _table_lines(text, "Table 6", 15)
    for i, line in enumerate(lines):
        o, m = OBJECTIVES[i // 5], METHOD_NAMES[i % 5]
        numbers = [float(x) for x in NUMBER.findall(line)]
        assert len(numbers) == 12, line
        for j, t in enumerate(TERRAINS):
            thigh, shank, imp, s2s = numbers[4 * j : 4 * j + 4]
            assert paper.table6[(o, m, t)] == {
                "thigh": thigh,
                "shank": shank,
                "improvement": pytest.approx(imp / 100),
                "sim2sim_improvement": pytest.approx(s2s / 100),
            }, (o, m, t)
    # Table 7: total(training+evaluation) for interactions (million) and wall clock (hour)
    for m, line in zip(METHOD_NAMES, _table_lines(text, "Table 7", 5), strict=True):
        it, itr, iev, ht, htr, hev = (float(x) for x in NUMBER.findall(line))
        r = paper.table7[m]
        assert (
            r["interactions_total"],
            r["interactions_training"],
            r["interactions_evaluation"],
        ) == (it * 1e6, itr * 1e6, iev * 1e6), m
        assert (r["hours_total"], r["hours_training"], r["hours_evaluation"]) == (ht, htr, hev), m
    # Table 9: thigh, hip motor, shank, knee motor, improvement % per objective (V, P, T)
    # and terrain
    lines = _table_lines(text, "Table 9", 9)
    for i, line in enumerate(lines):
        o, t = OBJECTIVES[i // 3], TERRAINS[i % 3]
        thigh, hip, shank, knee, imp = (float(x) for x in NUMBER.findall(line))
        assert paper.table9[(o, METHOD_NAMES[0], t)] == {
            "thigh": thigh,
            "hip_motor": hip,
            "shank": shank,
            "knee_motor": knee,
            "improvement": pytest.approx(imp / 100),
        }, (o, t)
