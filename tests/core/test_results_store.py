"""The results store: round trip, idempotent (resume-safe) recording, crash safety, export,
and the BO baseline's optuna study living in the same database."""

from __future__ import annotations

import csv
import json
import multiprocessing
import os
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from coadapt_core.errors import UserError
from coadapt_core.fitness import RunRecorder, TrainingResult
from coadapt_core.results import ResultsStore, SqliteRecorder, resolve_store_url
from coadapt_core.results.export import export_tables

CONFIG = {
    "method": "ours",
    "objective": "torque",
    "terrain": "flat",
    "seed": 3,
    "preset": "smoke",
    "optimizer": "pso",
    "sim": "mujoco",
    "robot": "kuafu",
    "design_space": {
        "variables": [
            {"name": "thigh_scale", "type": "continuous", "low": 0.5, "high": 1.5},
            {"name": "shank_scale", "type": "continuous", "low": 0.5, "high": 1.5},
        ]
    },
}


def _cost(design) -> float:
    return float((design[0] - 0.7) ** 2 + (design[1] - 0.6) ** 2)


def test_recorder_satisfies_the_protocol(tmp_path):
    assert isinstance(SqliteRecorder(tmp_path / "a.db"), RunRecorder)


def test_store_url_resolution(tmp_path, monkeypatch):
    assert resolve_store_url(tmp_path / "x.db") == f"sqlite:///{tmp_path / 'x.db'}"
    assert (
        resolve_store_url(tmp_path) == f"sqlite:///{tmp_path / 'coadapt.db'}"
    )  # a folder: its coadapt.db
    assert resolve_store_url("postgresql://u@h/db") == "postgresql://u@h/db"
    monkeypatch.setenv("COADAPT_STORE", str(tmp_path / "env.db"))
    assert resolve_store_url(None).endswith("env.db")
    with pytest.raises(UserError, match="does not exist"):
        resolve_store_url(tmp_path / "missing" / "x.db")


def test_round_trip_of_runs_evaluations_training_and_checkpoints(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = rec.start_run(CONFIG)
    rng = np.random.default_rng(0)
    designs = rng.uniform(0.5, 1.5, size=(6, 2))
    for inner in range(2):
        batch = designs[3 * inner : 3 * inner + 3]
        rec.record_evaluations(
            run_id,
            outer=0,
            inner=inner,
            designs=batch,
            costs=[{"torque": _cost(d)} for d in batch],
            kind="real",
            interactions=500,
            seconds=0.25,
        )
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=2,
        designs=designs[:1],
        costs=[{"torque": 0.5}],
        kind="surrogate",
        interactions=[0],
        seconds=[0.01],
        surrogate_errors=[{"torque": 0.125}],
    )
    rec.record_training(
        run_id,
        outer=0,
        result=TrainingResult(steps=12_000, seconds=4.5, mean_reward=1.25, extra={"kl": 0.01}),
    )
    rec.record_checkpoint(run_id, outer=0, path="/tmp/ckpt-0.pt")
    rec.finish(run_id, {"best_cost": 0.02, "best_design": [0.7, 0.6]})

    store = ResultsStore(tmp_path / "r.db")  # a fresh connection reads what was committed
    run = store.get_run(run_id)
    assert run["status"] == "finished" and run["finished_at"] is not None
    assert (run["method"], run["objectives"], run["terrain"], run["seed"], run["preset"]) == (
        "ours",
        ["torque"],
        "flat",
        3,
        "smoke",
    )
    assert run["summary"] == {"best_cost": 0.02, "best_design": [0.7, 0.6]}
    assert run["code_version"] == "0.1.0" and run["config"]["robot"] == "kuafu"
    real = store.evaluations(run_id, kind="real")
    assert len(real) == 6
    assert [(e.outer, e.inner, e.idx) for e in real] == [
        (0, 0, 0),
        (0, 0, 1),
        (0, 0, 2),
        (0, 1, 0),
        (0, 1, 1),
        (0, 1, 2),
    ]
    np.testing.assert_allclose([e.design for e in real], designs)
    np.testing.assert_allclose([e.costs["torque"] for e in real], [_cost(d) for d in designs])
    assert sum(e.interactions for e in real) == 3000
    (sur,) = store.evaluations(run_id, kind="surrogate")
    assert sur.surrogate_error == {"torque": 0.125} and sur.interactions == 0
    (phase,) = store.training(run_id)
    assert (phase["steps"], phase["seconds"], phase["final_reward"], phase["extra"]) == (
        12_000,
        4.5,
        1.25,
        {"kl": 0.01},
    )
    assert [c["path"] for c in store.checkpoints(run_id)] == ["/tmp/ckpt-0.pt"]


def test_sqlite_store_is_in_wal_mode(tmp_path):
    ResultsStore(tmp_path / "w.db").create_run(CONFIG)
    with sqlite3.connect(tmp_path / "w.db") as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_redone_batch_on_resume_replaces_rows_instead_of_duplicating(tmp_path):
    """A run recorded batch (1, 0), then was interrupted before it finished; a new process
    resumes it and redoes batch (1, 0) (the loop's state predates it): the store ends with
    each design once."""
    first = SqliteRecorder(tmp_path / "r.db")
    run_id = first.start_run(CONFIG)
    batch0 = np.array([[0.6, 0.6], [0.8, 0.9], [1.2, 1.1]])
    batch1 = np.array([[0.7, 0.65], [0.75, 0.6], [0.9, 0.8]])
    for outer, batch in ((0, batch0), (1, batch1)):
        first.record_evaluations(
            run_id,
            outer=outer,
            inner=0,
            designs=batch,
            costs=[{"torque": _cost(d)} for d in batch],
            kind="real",
            interactions=10,
            seconds=0.1,
        )
    assert first.store.count_evaluations(run_id) == 6

    resumed = SqliteRecorder(tmp_path / "r.db")  # new process
    assert resumed.start_run({**CONFIG, "run_id": run_id}) == run_id
    resumed.record_evaluations(
        run_id,
        outer=1,
        inner=0,
        designs=batch1,
        costs=[{"torque": _cost(d)} for d in batch1],
        kind="real",
        interactions=10,
        seconds=0.1,
    )
    resumed.finish(run_id, {"best_cost": _cost(batch1[0])})
    rows = resumed.store.evaluations(run_id)
    assert len(rows) == 6
    assert sorted(map(tuple, (e.design for e in rows))) == sorted(
        map(tuple, np.vstack([batch0, batch1]))
    )
    assert resumed.store.get_run(run_id)["status"] == "finished"
    assert resumed.store.get_run(run_id)["created_at"] == first.store.get_run(run_id)["created_at"]


def _crashing_run(db: str, crash_after: int, queue) -> None:
    rec = SqliteRecorder(db)
    run_id = rec.start_run(CONFIG)
    queue.put(run_id)
    # put() hands the id to a feeder thread; os._exit below kills that thread with the process,
    # so on a loaded machine the id could be lost unsent (crash_after=1 exits a few ms later):
    # wait until it is in the pipe
    queue.close()
    queue.join_thread()
    n = 0
    for outer in range(2):
        rec.record_training(
            run_id, outer=outer, result=TrainingResult(steps=1000, seconds=1.0, mean_reward=0.5)
        )
        for inner in range(3):
            batch = [[0.5 + 0.1 * k, 0.5 + 0.1 * inner] for k in range(4)]
            rec.record_evaluations(
                run_id,
                outer=outer,
                inner=inner,
                designs=batch,
                costs=[{"torque": _cost(d)} for d in batch],
                kind="real",
                interactions=100,
                seconds=0.01,
            )
            n += 1
            if n == crash_after:
                os._exit(9)  # no cleanup, no flush: a killed process


@pytest.mark.parametrize("crash_after", [1, 3, 4])
def test_crash_loses_no_recorded_evaluation(tmp_path, crash_after):
    """Killed between evaluation batches of 4 designs (1: mid outer iteration; 3: at the end
    of outer iteration 0, before the second training phase; 4: after it), everything
    recorded before survives."""
    # a fresh interpreter ("spawn"), not a fork of this one: a fork copies whatever locks the
    # suite's other threads held at that moment, and its child then waited forever on one
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_crashing_run, args=(str(tmp_path / "c.db"), crash_after, queue))
    proc.start()
    run_id = queue.get(timeout=120)
    proc.join(timeout=120)
    assert proc.exitcode == 9
    store = ResultsStore(tmp_path / "c.db")
    assert store.count_evaluations(run_id) == 4 * crash_after
    assert len(store.training(run_id)) == (1 if crash_after <= 3 else 2)
    assert store.get_run(run_id)["status"] == "running"  # never finished: the grid resumes it


def test_export_csv_matches_store(tmp_path):
    rec = SqliteRecorder(tmp_path / "e.db")
    run_id = rec.start_run(CONFIG)
    other = rec.start_run({**CONFIG, "seed": 4})
    designs = [[0.6, 0.7], [1.1, 0.9]]
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=0,
        designs=designs,
        costs=[{"torque": _cost(d)} for d in designs],
        kind="real",
        interactions=7,
        seconds=0.5,
    )
    rec.record_evaluations(
        other,
        outer=0,
        inner=0,
        designs=designs,
        costs=[{"torque": 9.0}] * 2,
        kind="real",
        interactions=7,
        seconds=0.5,
    )
    rec.record_training(
        run_id, outer=0, result=TrainingResult(steps=99, seconds=1.5, mean_reward=0.25)
    )
    rec.finish(run_id, {"best_cost": 0.02})
    written = export_tables(rec.store, tmp_path / "out", fmt="csv", run_ids=[run_id])
    with written["evaluations"].open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 and {r["run_id"] for r in rows} == {run_id}
    np.testing.assert_allclose([float(r["thigh_scale"]) for r in rows], [0.6, 1.1])
    np.testing.assert_allclose([float(r["cost_torque"]) for r in rows], [_cost(d) for d in designs])
    with written["runs"].open() as fh:
        (run_row,) = list(csv.DictReader(fh))
    assert json.loads(run_row["summary"]) == {"best_cost": 0.02} and run_row["status"] == "finished"
    with written["training_phases"].open() as fh:
        (phase,) = list(csv.DictReader(fh))
    assert (int(phase["steps"]), float(phase["seconds"])) == (99, 1.5)


def test_export_rejects_unknown_run_and_format(tmp_path):
    store = ResultsStore(tmp_path / "e.db")
    with pytest.raises(UserError, match="not in store"):
        export_tables(store, tmp_path / "o", run_ids=["nope"])
    with pytest.raises(UserError, match="csv, parquet"):
        export_tables(store, tmp_path / "o", fmt="xlsx")


def test_export_cli_parquet_without_pandas_is_one_line(tmp_path):
    from tests.conftest import run_cli

    try:
        import pandas  # noqa: F401
        import pyarrow  # noqa: F401

        pytest.skip("pandas and pyarrow are installed; the missing-package message cannot be shown")
    except ImportError:
        pass
    proc = run_cli(
        "export",
        "--store",
        str(tmp_path / "p.db"),
        "--format",
        "parquet",
        "-o",
        str(tmp_path / "o"),
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "error: parquet export needs pandas and pyarrow: pip install 'coadapt[parquet]' (or use "
        "--format csv)"
    ]


def test_bo_study_lives_in_the_store_and_optuna_finds_it(tmp_path):
    """The BO baseline keeps its optuna study in the results database (its own tables next
    to ours), so optuna's tools read it."""
    import optuna

    from coadapt_core.design_space import Continuous, DesignSpace
    from coadapt_core.plugins import get_registry

    store = ResultsStore(tmp_path / "bo.db")
    run_id = store.create_run({**CONFIG, "method": "bo-specialized", "optimizer": "bo"})
    bo_cls = get_registry().get("optimizer", "bo")
    space = DesignSpace([Continuous("thigh_scale", 0.5, 1.5), Continuous("shank_scale", 0.5, 1.5)])
    bo = bo_cls(space, budget=4, seed=0, storage=store.url, study_name=f"coadapt-bo-{run_id}")
    for _ in range(4):
        d = bo.ask()
        bo.tell(d, np.array([_cost(d[0])]))
    study = optuna.load_study(study_name=f"coadapt-bo-{run_id}", storage=store.url)
    assert len(study.trials) == 4
    assert study.best_value == pytest.approx(bo.best()[1])
    assert (
        ResultsStore(tmp_path / "bo.db").get_run(run_id)["method"] == "bo-specialized"
    )  # our tables intact


def test_make_recorder_tees_json_files_into_the_store_beside_the_runs_folder(tmp_path, monkeypatch):
    from coadapt_core.results.recorders import JsonRecorder, make_recorder

    monkeypatch.delenv("COADAPT_STORE", raising=False)
    run_dir = tmp_path / "runs" / "r1"
    rec = make_recorder(run_dir)
    assert isinstance(rec, SqliteRecorder) and rec.url == f"sqlite:///{tmp_path / 'coadapt.db'}"
    assert rec.start_run(CONFIG) == "r1"  # the JSON recorder names the run after its folder
    rec.record_evaluations(
        "r1",
        outer=0,
        inner=0,
        designs=[[1.0, 1.0]],
        costs=[{"torque": 2.0}],
        kind="real",
        interactions=5,
        seconds=0.1,
    )
    rec.record_checkpoint("r1", outer=0, path="runs/r1/ckpt.pt")
    assert (run_dir / "evaluations.jsonl").read_text().count("\n") == 1
    store = ResultsStore(tmp_path / "coadapt.db")
    assert store.count_evaluations("r1") == 1 and store.get_run("r1")["run_dir"] == str(run_dir)
    assert Path(store.checkpoints("r1")[0]["path"]).is_absolute()
    assert isinstance(make_recorder(tmp_path / "runs" / "r2", "none"), JsonRecorder)
    monkeypatch.setenv("COADAPT_STORE", str(tmp_path / "env.db"))
    assert make_recorder(tmp_path / "runs" / "r3").url.endswith("env.db")


def _open_and_record(db: str, n: int) -> None:
    rec = SqliteRecorder(db)
    run_id = rec.start_run({**CONFIG, "seed": n})
    for i in range(20):
        rec.record_evaluations(
            run_id,
            outer=0,
            inner=i,
            designs=[[1.0, 1.0]],
            costs=[{"torque": float(i)}],
            kind="real",
            interactions=1,
            seconds=0.0,
        )
    rec.finish(run_id, {"n": n})


def test_processes_creating_and_writing_one_store_at_once(tmp_path):
    """Four processes open a store that does not exist yet and write to it concurrently
    (what a grid's first cells do): every row arrives."""
    ctx = multiprocessing.get_context("spawn")
    procs = [
        ctx.Process(target=_open_and_record, args=(str(tmp_path / "c.db"), n)) for n in range(4)
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=120)
    assert [p.exitcode for p in procs] == [0, 0, 0, 0]
    store = ResultsStore(tmp_path / "c.db")
    runs = store.list_runs(status="finished")
    assert sorted(r["seed"] for r in runs) == [0, 1, 2, 3]
    assert all(store.count_evaluations(r["id"]) == 20 for r in runs)


# -- schema version (upgrades from older versions: test_store_migrations.py) ---------------------
def _recorded_version(db: Path):
    with sqlite3.connect(db) as conn:
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if "store_info" not in tables:
            return None
        row = conn.execute("SELECT value FROM store_info WHERE key='schema_version'").fetchone()
    return None if row is None else row[0]


def test_a_new_store_records_its_schema_version(tmp_path):
    from coadapt_core.results.schema import SCHEMA_VERSION

    store = ResultsStore(tmp_path / "new.db")
    assert store.schema_version == SCHEMA_VERSION == 3
    store.close()
    assert _recorded_version(tmp_path / "new.db") == "3"
    assert (
        ResultsStore(tmp_path / "new.db").schema_version == 3
    )  # opened again: the same version, one row
    with sqlite3.connect(tmp_path / "new.db") as conn:
        assert conn.execute("SELECT count(*) FROM store_info").fetchone()[0] == 1


@pytest.mark.parametrize("version", ["4", "99", "x"])
def test_a_store_of_a_newer_schema_is_refused_with_one_line(tmp_path, version):
    db = tmp_path / "future.db"
    ResultsStore(db).close()
    with sqlite3.connect(db) as conn:
        conn.execute("UPDATE store_info SET value=? WHERE key='schema_version'", (version,))
    for create in (True, False):
        with pytest.raises(UserError) as err:
            ResultsStore(db, create=create)
        message = str(err.value)
        assert "\n" not in message and err.value.field == "store"
        shown = version if version != "x" else "unreadable"
        assert (
            f"has schema version {shown}; coadapt" in message and "reads versions 1 to 3" in message
        )


def test_cli_on_a_newer_store_prints_one_line_and_exits_2(tmp_path):
    from tests.conftest import run_cli

    db = tmp_path / "future.db"
    ResultsStore(db).close()
    with sqlite3.connect(db) as conn:
        conn.execute("UPDATE store_info SET value='7' WHERE key='schema_version'")
    proc = run_cli("report", "--store", str(db), "-o", str(tmp_path / "report"))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "schema version 7" in lines[0] and "Traceback" not in proc.stderr
