"""`coadapt import`: an export loaded into an empty store reports the same as the store it
came from (CSV and Parquet), two stores merge without a run twice, a second import of the
same export changes nothing, a grid skips the imported finished cells, and a bad file is one
line, exit 2, with nothing written."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from coadapt_core.analysis.report import write_report
from coadapt_core.errors import UserError
from coadapt_core.experiments.grid_plan import GridSpec, plan_grid
from coadapt_core.experiments.transfer import transfer_runs
from coadapt_core.results import ResultsStore, SqliteRecorder
from coadapt_core.results.export import export_tables
from coadapt_core.results.importer import import_tables
from tests.core.test_report import AnalyticBackend, record_run

TABLES = ("runs", "evaluations", "training_phases", "checkpoints", "verifications")
REPORT_FILES = ("table6.csv", "table6.md", "table7.csv", "table7.md")


def contents(store: ResultsStore) -> dict[str, list]:
    """Every row of every exported table, without the child tables' autoincrement ids, in a
    fixed order: what two stores holding the same runs must agree on."""
    out = {}
    for t in TABLES:
        rows = [
            {k: v for k, v in r.items() if not (t != "runs" and k == "id")}
            for r in store.table_rows(t)
        ]
        out[t] = sorted(rows, key=lambda r: json.dumps(r, sort_keys=True, default=str))
    return out


def counts(store: ResultsStore) -> dict[str, int]:
    return {t: len(store.table_rows(t)) for t in TABLES}


def filled(
    path: Path, methods=("ours", "no-surrogate"), seeds=(0, 1), objectives=("torque",)
) -> tuple[ResultsStore, dict]:
    rec = SqliteRecorder(path)
    ckpt = path.parent / "policy.pt"
    ckpt.write_text("weights")
    ids = {
        (m, s): record_run(rec, m, s, checkpoint=ckpt, objectives=objectives)
        for m in methods
        for s in seeds
    }
    return rec.store, ids


def transfer(store: ResultsStore, run_id: str) -> None:
    """Sim-to-sim rows for one run, through an analytic backend (as test_report does)."""
    transfer_runs(
        store,
        [store.get_run(run_id)],
        simulator="pybullet",
        factory=lambda *a, **k: AnalyticBackend(scale=1.5),
    )


def same_report(a: ResultsStore, b: ResultsStore, tmp_path: Path) -> None:
    ra = write_report(a, None, tmp_path / "rep_a", transfer_simulator="pybullet")
    rb = write_report(b, None, tmp_path / "rep_b", transfer_simulator="pybullet")
    for name in REPORT_FILES:
        assert ra[name].read_text() == rb[name].read_text(), name
    assert set(ra) == set(rb)
    html_a = ra["report.html"].read_text().replace(a.url, "STORE")
    html_b = rb["report.html"].read_text().replace(b.url, "STORE")
    assert html_a == html_b


def test_csv_round_trip_reproduces_store_and_report(tmp_path):
    (tmp_path / "a").mkdir()
    source, ids = filled(tmp_path / "a" / "r.db")
    transfer(source, ids[("ours", 0)])
    export_tables(source, tmp_path / "exp")
    target = ResultsStore(tmp_path / "b.db")
    done = import_tables(target, tmp_path / "exp")
    assert sorted(done.added) == sorted(ids.values()) and not done.replaced and not done.skipped
    assert done.rows == counts(source) and done.rows["evaluations"] == 4 * 20 + 2
    assert contents(target) == contents(source)  # every value, times and JSON text included
    sim = target.evaluations(ids[("ours", 0)], kind="sim2sim")
    assert [(e.idx, e.simulator) for e in sim] == [(0, "pybullet"), (1, "pybullet")]
    same_report(source, target, tmp_path)
    t6 = (tmp_path / "rep_b" / "table6.csv").read_text()
    assert "pybullet, 2 designs" in t6  # the sim-to-sim column came through


def test_parquet_round_trip(tmp_path):
    pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    (tmp_path / "a").mkdir()
    source, _ = filled(tmp_path / "a" / "r.db")
    export_tables(source, tmp_path / "exp", fmt="parquet")
    target = ResultsStore(tmp_path / "b.db")
    done = import_tables(
        target, tmp_path / "exp" / "runs.parquet"
    )  # a file of the export names its folder
    assert done.fmt == "parquet" and len(done.added) == 4
    assert contents(target) == contents(source)
    same_report(source, target, tmp_path)


def test_two_stores_merge_each_run_once_and_a_second_import_changes_nothing(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, ids_a = filled(tmp_path / "a" / "r.db", methods=("ours",))
    b, ids_b = filled(tmp_path / "b" / "r.db", methods=("no-surrogate",))
    export_tables(a, tmp_path / "exp_a")
    # machine B also holds a copy of one of A's runs (imported earlier): it must not double
    import_tables(b, tmp_path / "exp_a" / "runs.csv")
    assert len(b.list_runs()) == 4
    export_tables(b, tmp_path / "exp_b")
    merged = ResultsStore(tmp_path / "m.db")
    first = import_tables(merged, tmp_path / "exp_a")
    second = import_tables(merged, tmp_path / "exp_b")
    assert sorted(first.added) == sorted(ids_a.values())
    assert sorted(second.added) == sorted(ids_b.values()) and sorted(second.skipped) == sorted(
        ids_a.values()
    )
    assert len(merged.list_runs()) == 4
    assert counts(merged) == counts(b) and contents(merged) == contents(
        b
    )  # b holds a's runs once, and its own
    before = contents(merged)
    again = import_tables(merged, tmp_path / "exp_b")
    assert not again.added and not again.replaced and len(again.skipped) == 4
    assert again.rows == dict.fromkeys(TABLES, 0) and contents(merged) == before
    # the merged store reports both machines' runs, one row per method
    files = write_report(merged, None, tmp_path / "rep", sim2sim=False)
    t7 = files["table7.csv"].read_text().splitlines()
    assert len(t7) == 3 and ",ours,pso,2," in t7[1] and ",no-surrogate,pso,2," in t7[2]


def test_a_finished_copy_replaces_an_unfinished_one_and_not_the_other_way(tmp_path):
    """A run started on one machine and finished on another: the finished copy wins,
    whichever export comes first, and its rows replace the partial ones."""
    (tmp_path / "done").mkdir()
    done_store, ids = filled(tmp_path / "done" / "r.db", methods=("ours",), seeds=(0,))
    run_id = ids[("ours", 0)]
    partial = ResultsStore(tmp_path / "partial.db")
    run = done_store.get_run(run_id)
    partial.create_run(run["config"], run_id=run_id)
    partial.record_evaluations(
        run_id,
        [
            {
                "outer": 0,
                "inner": 0,
                "idx": i,
                "kind": "real",
                "design": [0.9, 0.9],
                "costs": {"torque": 99.0},
            }
            for i in range(7)
        ],
    )
    export_tables(done_store, tmp_path / "exp_done")
    export_tables(partial, tmp_path / "exp_partial")
    for order in (("exp_partial", "exp_done"), ("exp_done", "exp_partial")):
        merged = ResultsStore(tmp_path / f"m-{order[0]}.db")
        results = [import_tables(merged, tmp_path / o) for o in order]
        assert merged.get_run(run_id)["status"] == "finished"
        assert contents(merged) == contents(done_store)
        if order[0] == "exp_partial":
            assert results[1].replaced == [run_id]
        else:
            assert results[1].skipped == [run_id] and results[1].rows["evaluations"] == 0


def test_grid_skips_imported_finished_cells(tmp_path):
    """Cells finished on another machine: by the same grid command (same grid id), or by
    hand with the cell's whole configuration; after the import the grid plans only the rest."""
    from coadapt_core.coadapt.config_loading import make_config

    spec = GridSpec(
        methods=["ours", "no-surrogate"],
        objectives=["torque"],
        terrains=["flat"],
        seeds=[0, 1],
        preset="smoke",
        sim="mujoco",
    )
    c0, c1, c2, _c3 = spec.cells()
    elsewhere = ResultsStore(tmp_path / "elsewhere.db")
    for cell, run_id in ((c0, "g0"), (c1, "g1")):  # as the grid's recorder stores them
        rid = elsewhere.create_run(
            {
                "method": cell.method,
                "objective": cell.objective,
                "terrain": cell.terrain,
                "seed": cell.seed,
                "preset": cell.preset,
                "sim": cell.sim,
                "grid_id": spec.grid_id,
                "grid_cell": cell.key,
            },
            run_id=run_id,
        )
        elsewhere.finish_run(rid, {"best_cost": 1.0})
    config = make_config(
        "smoke",
        overrides={
            "method": c2.method,
            "objective": c2.objective,
            "terrain": "flat",
            "seed": c2.seed,
            "sim": "mujoco",
        },
    ).to_dict()
    elsewhere.finish_run(elsewhere.create_run(config, run_id="byhand"), {"best_cost": 2.0})
    elsewhere.create_run(
        {**config, "seed": 1}, run_id="unfinished"
    )  # c3 started there, never finished
    export_tables(elsewhere, tmp_path / "exp")

    here = ResultsStore(tmp_path / "here.db")
    tasks, skipped = plan_grid(here, spec, out_dir=str(tmp_path / "runs"))
    assert not skipped and len(tasks) == 4
    import_tables(here, tmp_path / "exp")
    tasks, skipped = plan_grid(here, spec, out_dir=str(tmp_path / "runs"))
    assert [c.key for c in skipped] == [c0.key, c1.key, c2.key]
    assert [t.cell.key for t in tasks] == [_c3.key] and tasks[
        0
    ].resume is None  # no run folder here to resume


def _export(tmp_path: Path) -> Path:
    (tmp_path / "a").mkdir()
    store, _ = filled(tmp_path / "a" / "r.db", methods=("ours",), seeds=(0,))
    export_tables(store, tmp_path / "exp")
    return tmp_path / "exp"


def _edit_csv(path: Path, row: int, column: str, value: str) -> None:
    import csv

    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
        columns = list(rows[0])
    rows[row][column] = value
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


@pytest.mark.parametrize(
    ("table", "column", "value", "message"),
    [
        ("runs", "id", "../../etc", "runs row 2: '../../etc' is not a run id"),
        ("runs", "config", "{not json", "runs row 2, column 'config': not JSON text"),
        (
            "runs",
            "summary",
            "[1, 2]",
            "runs row 2, column 'summary': expected a JSON dict, got list",
        ),
        ("runs", "created_at", "", "runs row 2, column 'created_at': a value is required"),
        (
            "evaluations",
            "outer",
            "first",
            "evaluations row 3, column 'outer': expected an integer, got 'first'",
        ),
        (
            "evaluations",
            "kind",
            "dream",
            "evaluations row 3, column 'kind': 'dream' is not one of real, surrogate, sim2sim",
        ),
        (
            "evaluations",
            "design",
            '["a"]',
            "evaluations row 3, column 'design': expected a JSON list of numbers",
        ),
        (
            "evaluations",
            "run_id",
            "other-run",
            "evaluations row 3: run 'other-run' is not in the runs file",
        ),
        (
            "evaluations",
            "cost_torque",
            "cheap",
            "evaluations row 3, column 'cost_torque': expected a number, got 'cheap'",
        ),
        (
            "training_phases",
            "steps",
            "1.5",
            "training_phases row 3, column 'steps': expected an integer, got '1.5'",
        ),
    ],
)
def test_a_bad_row_is_one_error_naming_it_and_writes_nothing(
    tmp_path, table, column, value, message
):
    exp = _export(tmp_path)
    _edit_csv(exp / f"{table}.csv", 0 if table == "runs" else 1, column, value)
    target = ResultsStore(tmp_path / "t.db")
    with pytest.raises(UserError) as err:
        import_tables(target, exp)
    assert str(err.value).startswith(message)
    assert counts(target) == dict.fromkeys(TABLES, 0)


def test_bad_paths_and_files_are_one_line(tmp_path):
    exp = _export(tmp_path)
    target = ResultsStore(tmp_path / "t.db")
    (tmp_path / "notes.txt").write_text("hello")
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match="does not exist"):
        import_tables(target, tmp_path / "missing")
    with pytest.raises(UserError, match="is not a file `coadapt export` writes"):
        import_tables(target, tmp_path / "notes.txt")
    with pytest.raises(UserError, match=re.escape("holds no runs.csv or runs.parquet")):
        import_tables(target, tmp_path / "empty")
    with pytest.raises(UserError, match="import format 'xlsx' is not one of csv, parquet"):
        import_tables(target, exp, fmt="xlsx")
    (exp / "checkpoints.csv").unlink()
    with pytest.raises(UserError, match=re.escape("lacks checkpoints.csv")):
        import_tables(target, exp)
    (exp / "checkpoints.csv").write_bytes(b"\x80\x04\x95binary pickle-ish bytes\x00")
    with pytest.raises(UserError, match=re.escape("checkpoints.csv is not UTF-8 text")):
        import_tables(target, exp)
    (exp / "checkpoints.csv").write_text("nothing,useful\n1,2\n")
    with pytest.raises(UserError, match="checkpoints file: the header lacks run_id, outer, path"):
        import_tables(target, exp)
    assert counts(target) == dict.fromkeys(TABLES, 0)


def test_import_cli_round_trip_and_bad_input(tmp_path):
    from tests.conftest import run_cli

    exp = _export(tmp_path)
    proc = run_cli("import", str(exp), "--store", str(tmp_path / "t.db"), "--json")
    assert proc.returncode == 0, proc.stderr
    done = json.loads(proc.stdout.strip().splitlines()[-1])
    assert len(done["added"]) == 1 and done["rows"]["evaluations"] == 20 and done["format"] == "csv"
    proc = run_cli("import", str(exp), "--store", str(tmp_path / "t.db"))
    assert proc.returncode == 0 and "0 runs added, 0 replaced, 1 already there" in proc.stdout
    _edit_csv(exp / "runs.csv", 0, "seed", "zero")
    for args in ([str(tmp_path / "missing")], [str(exp)], [str(exp), "--format", "xlsx"]):
        bad = run_cli("import", *args, "--store", str(tmp_path / "t2.db"))
        assert bad.returncode == 2, bad.stderr
        (line,) = bad.stderr.strip().splitlines()
        assert line.startswith("error: ") and "Traceback" not in bad.stderr
    assert (
        not (tmp_path / "t2.db").exists() or counts(ResultsStore(tmp_path / "t2.db"))["runs"] == 0
    )


def test_design_values_and_costs_are_exact_after_the_round_trip(tmp_path):
    """Floats go through CSV text and back bit for bit; a NaN cost stays NaN in CSV."""
    rec = SqliteRecorder(tmp_path / "n.db")
    run_id = rec.start_run({"method": "ours", "objective": "torque,power", "seed": 0})
    designs = np.array([[1 / 3, 2 / 7], [0.1 + 0.2, 1e-17]])
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=0,
        designs=designs,
        kind="real",
        interactions=5,
        seconds=0.1,
        costs=[{"torque": float("nan"), "power": 1 / 9}, {"torque": 2 / 3, "power": 1e300}],
    )
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=0,
        designs=designs[:1],
        kind="surrogate",
        interactions=0,
        seconds=0.0,
        costs=[{"torque": 0.5}],
    )  # one objective only: the other column stays empty
    export_tables(rec.store, tmp_path / "exp")
    target = ResultsStore(tmp_path / "t.db")
    import_tables(target, tmp_path / "exp")
    real = target.evaluations(run_id, kind="real")
    assert [e.design for e in real] == designs.tolist()
    assert (
        np.isnan(real[0].costs["torque"])
        and real[0].costs["power"] == 1 / 9
        and real[1].costs["power"] == 1e300
    )
    (sur,) = target.evaluations(run_id, kind="surrogate")
    assert sur.costs == {"torque": 0.5}
