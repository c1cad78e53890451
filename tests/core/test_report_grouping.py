"""`coadapt report` never pools unlike runs: a quick and a smoke run of the same cell, or runs
of two robots or two simulators, are rows of their own, and the tables say so."""

from __future__ import annotations

import numpy as np

from coadapt_core.analysis.report import write_report
from coadapt_core.analysis.table_markdown import POOLING_NOTE
from coadapt_core.results.recorders import SqliteRecorder


def record(
    rec: SqliteRecorder,
    *,
    preset="quick",
    robot="kuafu",
    sim="mujoco",
    seed=0,
    best=1.0,
    policy: dict | None = None,
) -> str:
    config = {
        "method": "ours",
        "objective": "torque",
        "terrain": "flat",
        "seed": seed,
        "preset": preset,
        "sim": sim,
        "robot": robot,
        "optimizer": "pso",
    }
    if policy is not None:
        config["policy"] = policy
    run_id = rec.start_run(config)
    design = [best, 1.0]
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=0,
        designs=np.array([design]),
        kind="real",
        costs=[{"torque": best}],
        interactions=100,
        seconds=1.0,
    )
    rec.finish(
        run_id,
        {
            "run_id": run_id,
            "best_design": design,
            "best_cost": best,
            "nominal_cost": 2.0,
            "improvement": (2.0 - best) / 2.0,
        },
    )
    return run_id


def rows_of(path):
    import csv

    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_a_quick_and_a_smoke_run_of_one_cell_are_not_averaged(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    record(rec, preset="quick", best=0.6)
    record(rec, preset="smoke", best=1.4)
    files = write_report(rec.store, None, tmp_path / "report", sim2sim=False)
    t6 = rows_of(files["table6.csv"])
    assert sorted((r["preset"], r["runs"], float(r["best_cost"])) for r in t6) == [
        ("quick", "1", 0.6),
        ("smoke", "1", 1.4),
    ]
    t7 = rows_of(files["table7.csv"])
    assert sorted((r["preset"], r["runs"]) for r in t7) == [("quick", "1"), ("smoke", "1")]
    md = files["table6.md"].read_text()
    assert "| Robot | Simulator | Preset |" in md and POOLING_NOTE in md
    assert POOLING_NOTE in files["table7.md"].read_text()
    assert "never averaged together" in files["report.html"].read_text()


def test_runs_of_two_robots_or_two_simulators_are_rows_of_their_own_and_seeds_still_pool(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    record(rec, robot="kuafu", seed=0, best=0.5)
    record(rec, robot="kuafu", seed=1, best=0.7)  # same setting, another seed: one row of two runs
    record(rec, robot="trotter", best=1.2)
    record(rec, robot="kuafu", sim="pybullet", best=0.9)
    t6 = rows_of(write_report(rec.store, None, tmp_path / "report", sim2sim=False)["table6.csv"])
    got = sorted(
        (r["robot"], r["simulator"], r["runs"], round(float(r["best_cost"]), 6)) for r in t6
    )
    assert got == [
        ("kuafu", "mujoco", "2", 0.6),
        ("kuafu", "pybullet", "1", 0.9),
        ("trotter", "mujoco", "1", 1.2),
    ]


def test_the_starting_policy_is_shown(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    record(
        rec,
        policy={
            "source": "shipped",
            "file": "flat.pt",
            "path": "/x/flat.pt",
            "sha256": "ab" * 32,
            "robot": "kuafu",
        },
    )
    record(
        rec, preset="smoke", policy={"source": "none", "file": None, "path": None, "sha256": None}
    )
    record(rec, preset="paper")  # recorded before provenance existed
    files = write_report(rec.store, None, tmp_path / "report", sim2sim=False)
    policies = {r["preset"]: r["policy"] for r in rows_of(files["table6.csv"])}
    assert policies == {"quick": f"flat.pt ({'ab' * 6})", "smoke": "none", "paper": "?"}
    assert f"flat.pt ({'ab' * 6})" in files["table6.md"].read_text()
