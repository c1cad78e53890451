"""Store migrations: a store of schema version 1 (as coadapt wrote it, tests/core/data/
store_v1.sql) is upgraded in place by alembic when it is opened, after a backup copy, keeps
every row, and ends with the layout a new store gets; a failed upgrade changes nothing."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
import sqlalchemy as sa

from coadapt_core.errors import UserError
from coadapt_core.results.migrate import VERSION_TABLE
from coadapt_core.results.schema import SCHEMA_VERSION, metadata
from coadapt_core.results.store import ResultsStore

V1_DUMP = Path(__file__).parent / "data" / "store_v1.sql"
TABLES = ("runs", "evaluations", "training_phases", "checkpoints", "grids", "grid_cells")
RUN0 = "20261201-000000-ours-torque-s0-abc120"


def _v1_store(db: Path, *, recorded: bool) -> Path:
    """A version-1 store: as coadapt wrote it from e14c752 on (`store_info` holds 1), or
    before (no `store_info` table at all)."""
    with sqlite3.connect(db) as conn:
        conn.executescript(V1_DUMP.read_text())
        if not recorded:
            conn.execute("DROP TABLE store_info")
    return db


def _rows(db: Path) -> dict[str, list[tuple]]:
    with sqlite3.connect(db) as conn:
        return {t: conn.execute(f"SELECT * FROM {t} ORDER BY 1, 2").fetchall() for t in TABLES}


def _objects(db: Path) -> set[str]:
    with sqlite3.connect(db) as conn:
        return {
            r[0]
            for r in conn.execute("SELECT name FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'")
        }


def _version(db: Path) -> str | None:
    with sqlite3.connect(db) as conn:
        if "store_info" not in {r[0] for r in conn.execute("SELECT name FROM sqlite_master")}:
            return None
        row = conn.execute("SELECT value FROM store_info WHERE key='schema_version'").fetchone()
    return None if row is None else row[0]


@pytest.mark.parametrize("recorded", [True, False], ids=["store_info-1", "no-store_info"])
def test_a_version_1_store_is_upgraded_in_place_and_reads_every_run_back(
    tmp_path, capsys, recorded
):
    db = _v1_store(tmp_path / "coadapt.db", recorded=recorded)
    before = _rows(db)
    assert {t: len(r) for t, r in before.items()} == {
        "runs": 3,
        "evaluations": 52,
        "training_phases": 6,
        "checkpoints": 6,
        "grids": 1,
        "grid_cells": 2,
    }
    assert _version(db) == ("1" if recorded else None) and "ix_runs_status" not in _objects(db)

    store = ResultsStore(db, create=False)  # a read-only open upgrades too
    lines = capsys.readouterr().err.strip().splitlines()
    assert store.schema_version == SCHEMA_VERSION == 3
    assert (
        len(lines) == 1
        and f"store 'sqlite:///{db}' upgraded from schema version 1 to 3" in lines[0]
    )
    backups = sorted(tmp_path.glob("coadapt.v1-backup-*.db"))
    assert len(backups) == 1 and lines[0].endswith(f"the store as it was is copied to {backups[0]}")

    # every row is there, unchanged, and reads back through the store's own methods
    assert _rows(db) == before and _rows(backups[0]) == before
    assert _version(db) == "3" and _version(backups[0]) == ("1" if recorded else None)
    assert store.verifications() == []  # the new table, empty
    assert "ix_runs_status" in _objects(db) and "ix_runs_status" not in _objects(backups[0])
    runs = store.list_runs()
    assert [(r["method"], r["objectives"], r["seed"], r["status"]) for r in runs] == [
        ("ours", ["torque"], 0, "finished"),
        ("ours", ["power", "torque"], 1, "finished"),
        ("bo-specialized", ["tracking"], 2, "interrupted"),
    ]
    assert runs[0]["summary"]["improvement"] == 0.125 and runs[1]["summary"]["best_cost"] == 2.5
    assert runs[0]["config"]["design_space"]["variables"][0]["name"] == "thigh_scale"
    assert [len(store.evaluations(r["id"])) for r in runs] == [20, 16, 16]
    assert [r["id"] for r in store.list_runs(status="finished")] == [RUN0, runs[1]["id"]]
    common = store.evaluations(RUN0, kind="common")
    assert [(e.outer, e.design, e.costs) for e in common] == [
        (-2, [0.75, 0.875], {"torque": 2.0}),
        (-2, [0.75, 0.875], {"torque": 2.5}),
    ]
    sim2sim = store.evaluations(RUN0, kind="sim2sim")
    assert [e.simulator for e in sim2sim] == ["pybullet", "pybullet"]
    surrogate = store.evaluations(runs[1]["id"], kind="surrogate")
    assert surrogate[1].surrogate_error == {"power": -0.125, "torque": -0.125}
    real = store.evaluations(runs[1]["id"], kind="real")
    assert real[4].costs == {"power": 1.5, "torque": 2.0} and real[4].interactions == 8000
    phases = store.training(runs[2]["id"])
    assert [(p["outer"], p["steps"], p["final_reward"], p["extra"]) for p in phases] == [
        (0, 120_000, 3.25, {"kl": 0.0125}),
        (1, 120_000, 4.25, {"kl": 0.0125}),
    ]
    assert [c["path"] for c in store.checkpoints(RUN0)] == [
        "checkpoints/outer_0.pt",
        "checkpoints/outer_1.pt",
    ]
    assert store.get_grid("g-1")["spec"]["seeds"] == [0, 1]
    cells = store.cells("g-1")
    assert sorted((c["status"], c["attempts"], c["last_error"]) for c in cells.values()) == [
        ("failed", 2, "exit 1: killed"),
        ("finished", 1, None),
    ]
    store.close()

    # the upgraded layout is the one a new store gets: alembic finds nothing to change
    engine = sa.create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        from alembic.autogenerate import compare_metadata
        from alembic.runtime.migration import MigrationContext

        context = MigrationContext.configure(conn, opts={"version_table": VERSION_TABLE})
        assert compare_metadata(context, metadata) == []
    engine.dispose()

    # opened again: nothing to do, nothing printed, no second copy
    ResultsStore(db).close()
    assert capsys.readouterr().err == "" and len(list(tmp_path.glob("coadapt.v1-backup-*.db"))) == 1


def test_a_new_store_has_the_layout_of_the_migrations(tmp_path):
    """schema.py and the scripts agree: a new store (made from schema.py) and an upgraded one
    hold the same tables, columns and indexes."""
    ResultsStore(tmp_path / "new.db").close()
    ResultsStore(_v1_store(tmp_path / "old.db", recorded=True)).close()

    def layout(db: Path) -> dict[str, object]:
        inspector = sa.inspect(sa.create_engine(f"sqlite:///{db}"))
        return {
            t: (
                [c["name"] for c in inspector.get_columns(t)],
                sorted((i["name"], tuple(i["column_names"])) for i in inspector.get_indexes(t)),
            )
            for t in (*TABLES, "verifications", "store_info")
        }

    assert layout(tmp_path / "new.db") == layout(tmp_path / "old.db")
    assert ("ix_runs_status", ("status",)) in layout(tmp_path / "new.db")["runs"][1]
    assert _version(tmp_path / "new.db") == _version(tmp_path / "old.db") == "3"


def test_a_failed_upgrade_leaves_the_store_as_it_was(tmp_path, capsys):
    """The upgrade runs in one transaction: a step failing half way (here a trigger planted
    to refuse the new version row, after the index was made) rolls every change back."""
    db = _v1_store(tmp_path / "coadapt.db", recorded=True)
    with sqlite3.connect(db) as conn:
        conn.execute(
            "CREATE TRIGGER planted BEFORE INSERT ON store_info BEGIN SELECT RAISE(ABORT, "
            "'planted'); END"
        )
    before, objects = _rows(db), _objects(db)
    with pytest.raises(UserError) as err:
        ResultsStore(db)
    assert "\n" not in str(err.value) and "planted" in str(err.value) and err.value.field == "store"
    assert _rows(db) == before and _objects(db) == objects and _version(db) == "1"
    assert "ix_runs_status" not in objects and "coadapt_alembic_version" not in objects
    assert capsys.readouterr().err == ""  # no line claims an upgrade


def test_an_optuna_study_in_the_store_survives_the_upgrade(tmp_path):
    """optuna keeps its own alembic revision (`alembic_version`) in the same database; the
    store's upgrade records its revision elsewhere and leaves the study readable."""
    import optuna

    db = _v1_store(tmp_path / "coadapt.db", recorded=True)
    url = f"sqlite:///{db}"
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name="coadapt-bo-x-outer0", storage=url)
    study.optimize(lambda t: (t.suggest_float("x", 0, 1) - 0.25) ** 2, n_trials=3)
    with sqlite3.connect(db) as conn:
        optuna_revision = conn.execute("SELECT * FROM alembic_version").fetchall()
    ResultsStore(db).close()
    with sqlite3.connect(db) as conn:
        assert conn.execute("SELECT * FROM alembic_version").fetchall() == optuna_revision
        assert conn.execute("SELECT * FROM coadapt_alembic_version").fetchall() == [("0003",)]
    again = optuna.load_study(study_name="coadapt-bo-x-outer0", storage=url)
    assert len(again.trials) == 3 and again.best_value == study.best_value


def test_coadapt_export_on_a_version_1_store_prints_one_line_and_exports_every_row(tmp_path):
    db = _v1_store(tmp_path / "coadapt.db", recorded=False)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "coadapt_core",
            "export",
            "--store",
            str(db),
            "-o",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.strip().splitlines()  # the one line, nothing else (alembic logs nothing)
    assert len(lines) == 1 and "upgraded from schema version 1 to 3" in lines[0], proc.stderr
    assert "the store as it was is copied to" in lines[0]
    rows = (tmp_path / "out" / "evaluations.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + 52


def test_the_migration_scripts_ship_in_the_package():
    """setup.py's package list (what a pip install copies) holds the scripts' folders."""
    from setuptools import find_packages

    root = Path(__file__).resolve().parents[2]
    packages = find_packages(str(root), include=["coadapt_core", "coadapt_core.*"])
    assert {"coadapt_core.results.migrations", "coadapt_core.results.migrations.versions"} <= set(
        packages
    )
    versions = root / "coadapt_core" / "results" / "migrations" / "versions"
    assert sorted(p.name[:4] for p in versions.glob("0*.py")) == ["0001", "0002", "0003"]


def _verification(role: str, improvement: float) -> dict:
    side = {"improvement": improvement, "improvement_se": 0.01, "improvement_plain": improvement}
    return {
        "role": role,
        "design": [0.5, 0.75],
        "objective": "torque",
        "specialist": side,
        "universal": {**side, "improvement": 0.3},
        "difference": improvement - 0.3,
        "difference_se": 0.02,
        "verdict": "holds",
        "line": f"{role}: holds",
    }


def test_a_version_2_store_gains_the_verifications_table_and_keeps_every_row(tmp_path, capsys):
    """Version 3 adds the table of `coadapt verify`'s rows; a version-2 store upgraded to it
    keeps its rows, and verifications are written, replaced by key and read back."""
    db = _v1_store(tmp_path / "coadapt.db", recorded=True)
    ResultsStore(db).close()  # now version 3; step it back to a version-2 store by hand
    with sqlite3.connect(db) as conn:
        conn.execute("DROP TABLE verifications")
        conn.execute("UPDATE store_info SET value='2' WHERE key='schema_version'")
        conn.execute("UPDATE coadapt_alembic_version SET version_num='0002'")
    capsys.readouterr()
    before = _rows(db)
    store = ResultsStore(db)
    assert "upgraded from schema version 2 to 3" in capsys.readouterr().err
    assert _rows(db) == before and _version(db) == "3"
    result = {
        "key": "b1000-s0",
        "budget": 1000,
        "seed": 0,
        "scenarios": 64,
        "training_interactions": 2000,
        "evaluation_interactions": 500,
        "seconds": 12.5,
        "blocks": 2,
        "designs": [_verification("best", 0.25)],
    }
    assert store.record_verification(RUN0, result) == 1
    result["designs"] = [_verification("best", 0.28)]  # the same key and role: replaced
    store.record_verification(RUN0, result)
    (row,) = store.verifications([RUN0])
    assert (row["role"], row["budget"], row["verdict"], row["interactions"]) == (
        "best",
        1000,
        "holds",
        2500,
    )
    assert row["specialist_improvement"] == 0.28 and row["universal_improvement"] == 0.3
    assert row["difference"] == pytest.approx(-0.02) and row["design"] == [0.5, 0.75]
    assert row["detail"]["line"] == "best: holds"
    store.close()
