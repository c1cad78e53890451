"""The committed evidence (docs/results/): the export of the paper-comparison grid, loaded
into an empty store by `coadapt import`, reports exactly the committed tables, and it holds
what docs/reproduction.md says it holds (the full flat column of Table 6 with the common
yardstick and the sim-to-sim rows of every run)."""

from __future__ import annotations

import csv
import math
from collections import Counter
from pathlib import Path

import pytest

from coadapt_core.cli import main

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"
EXPORT, REPORT = RESULTS / "export", RESULTS / "report"


def rows(table: str) -> list[dict[str, str]]:
    csv.field_size_limit(1 << 26)
    with open(EXPORT / f"{table}.csv", newline="") as f:
        return list(csv.DictReader(f))


def _csv(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))


def _close(x: str, y: str) -> bool:
    try:
        return math.isclose(float(x), float(y), rel_tol=1e-9, abs_tol=1e-12)
    except ValueError:
        return False


@pytest.mark.slow
def test_import_then_report_reproduces_the_committed_report(tmp_path):
    store = tmp_path / "results.db"
    assert main(["import", str(EXPORT), "--store", str(store)]) == 0
    out = tmp_path / "report"
    assert main(["report", "--store", str(store), "-o", str(out)]) == 0
    committed = sorted(p.name for p in REPORT.iterdir())
    tables = [n for n in committed if n.endswith((".md", ".csv"))]
    assert {"table6.md", "table7.md", "paper_comparison.md", "paper_table6.csv"} <= set(tables)
    for name in tables:
        if name.endswith(".md"):
            assert (out / name).read_text() == (REPORT / name).read_text(), (
                f"{name} differs from the committed one"
            )
        else:  # numbers to 1e-9: a mean's last bit from another numpy is not another report
            mine, theirs = _csv(out / name), _csv(REPORT / name)
            assert len(mine) == len(theirs) and all(
                len(a) == len(b) for a, b in zip(mine, theirs, strict=True)
            ), name
            for a, b in zip(mine, theirs, strict=True):
                for x, y in zip(a, b, strict=True):
                    assert x == y or _close(x, y), f"{name}: {x!r} against the committed {y!r}"
    assert sorted(p.name for p in out.glob("*.png")) == [n for n in committed if n.endswith(".png")]


def test_the_export_holds_the_full_flat_column_with_its_yardsticks():
    runs = [r for r in rows("runs") if r["status"] == "finished"]
    assert len(runs) == len(rows("runs")), "only finished runs are published"
    flat = Counter(
        (r["method"], r["objectives"], r["seed"])
        for r in runs
        if r["terrain"] == "flat" and r["optimizer"] in ("pso", "bo")
    )
    for method in ("ours", "no-surrogate", "no-real", "no-retrain", "bo-specialized"):
        for objective in ("tracking", "power", "torque"):
            for seed in ("0", "1", "2"):
                assert flat[(method, objective, seed)] == 1, (method, objective, seed)
    kinds = Counter((e["run_id"], e["kind"]) for e in rows("evaluations"))
    for r in runs:
        # the report's rows: best and nominal design on the common set and on the second simulator
        assert kinds[(r["id"], "common")] == 2, r["id"]
        assert kinds[(r["id"], "sim2sim")] == 2, r["id"]
        # the optimizer's own rounds: real ones for every method but w/o real, which has none
        assert (kinds[(r["id"], "real")] > 0) == (r["method"] != "no-real"), r["id"]
