"""`coadapt grid`: expansion, skipping finished cells, resuming a killed grid, the local and
Ray executors. Cells run a small fake `coadapt run` (this file run as a script) that records
through the real `SqliteRecorder`, so the store sees what a real run writes."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from coadapt_core.errors import UserError
from coadapt_core.experiments.grid import run_grid
from coadapt_core.experiments.grid_plan import GridSpec, plan_grid
from coadapt_core.results import ResultsStore

FAKE_RUN = [sys.executable, str(Path(__file__).resolve())]
OPTIMUM = {"torque": (0.5, 0.5), "tracking": (1.4, 1.1), "power": (1.3, 1.3)}


def fake_run(argv: list[str]) -> int:
    """A stand-in for `coadapt run ... --json`: 2 outer x 2 inner batches of 3 real
    evaluations of an analytic cost; saves its position after every batch in its run folder
    and continues from it with --resume, like the real loop. FAKE_CRASH_AT=<cell>:<n> makes
    the cell die after n batches (once: a marker file records it)."""
    from coadapt_core.results import SqliteRecorder

    args = _fake_run_args(argv)
    rec = SqliteRecorder(args.store)
    config = {
        k: v
        for k, v in vars(args).items()
        if k not in ("json", "resume", "out", "store", "optimizer_option")
    }
    config["omp_num_threads"] = os.environ.get("OMP_NUM_THREADS")
    if args.resume:
        config["run_id"] = args.resume
    run_id = rec.start_run(config)
    run_dir = Path(args.out) / run_id
    run_dir.mkdir(parents=True, exist_ok=True)
    rec.store.create_run(config, run_id=run_id, run_dir=str(run_dir))
    _fake_batches(rec, run_id, run_dir, args)
    real = rec.store.evaluations(run_id, kind="real")
    i = int(np.argmin([e.costs[args.objective] for e in real]))
    opt = np.array(OPTIMUM[args.objective])
    summary = {
        "run_id": run_id,
        "best_design": real[i].design,
        "best_cost": real[i].costs[args.objective],
        "nominal_cost": float(((1 - opt) ** 2).sum()),
        "improvement": 0.5,
        "interactions": 300 * len(real) + 4000,
        "seconds": 0.1,
    }
    rec.finish(run_id, summary)
    print("fake run done")
    print(json.dumps(summary))
    return 0


def _fake_run_args(argv: list[str]) -> argparse.Namespace:
    """The options of `coadapt run` the fake reads (argv[0] is "run")."""
    p = argparse.ArgumentParser()
    for opt in (
        "--method",
        "--objective",
        "--terrain",
        "--preset",
        "--sim",
        "--robot",
        "--out",
        "--resume",
        "--optimizer",
        "--store",
        "--optimizer-option",
    ):
        p.add_argument(opt)
    p.add_argument("--seed", type=int)
    p.add_argument(
        "--threads", type=int
    )  # recorded in the config, as the real run's config.yaml does
    p.add_argument("--json", action="store_true")
    return p.parse_args(argv[1:])


def _fake_batches(rec: Any, run_id: str, run_dir: Path, args: argparse.Namespace) -> None:
    """The batches not yet done (state.json), each recorded and then saved as done; the
    FAKE_CRASH_AT cell dies between the two, once."""
    from coadapt_core.fitness import TrainingResult

    state_file = run_dir / "state.json"
    done = json.loads(state_file.read_text())["done"] if state_file.exists() else 0
    crash = os.environ.get("FAKE_CRASH_AT", "")
    crash_cell, _, crash_n = crash.rpartition(":")
    marker = run_dir / "crashed"
    rng = np.random.default_rng(args.seed)
    opt = np.array(OPTIMUM[args.objective])
    count = 0
    for b in range(4):
        outer, inner = divmod(b, 2)
        designs = opt + rng.normal(0.0, 0.3 / (b + 1), size=(3, 2))
        if b < done:
            continue
        if inner == 0:
            rec.record_training(
                run_id,
                outer=outer,
                result=TrainingResult(steps=2000, seconds=0.5, mean_reward=0.1 * b),
            )
        rec.record_evaluations(
            run_id,
            outer=outer,
            inner=inner,
            designs=designs,
            kind="real",
            interactions=300,
            seconds=0.01,
            costs=[{args.objective: float(((d - opt) ** 2).sum())} for d in designs],
        )
        count += 1
        if (
            crash_cell == os.environ.get("COADAPT_GRID_CELL")
            and count == int(crash_n or 0)
            and not marker.exists()
        ):
            marker.write_text("x")
            os._exit(9)  # after recording batch `count`, before saving the state that says so
        state_file.write_text(json.dumps({"done": b + 1}))


def _spec(**kw) -> GridSpec:
    base = {
        "methods": ["ours", "no-surrogate"],
        "objectives": ["torque"],
        "terrains": ["flat"],
        "seeds": [0],
        "preset": "smoke",
    }
    base.update(kw)
    return GridSpec(**base)


def test_grid_expands_every_combination():
    spec = GridSpec(
        methods=["ours", "no-surrogate", "no-real", "no-retrain", "bo-specialized"],
        objectives=["tracking", "power", "torque"],
        terrains=["flat", "slope", "random"],
        seeds=[0, 1, 2],
    )
    cells = spec.cells()
    assert len(cells) == 5 * 3 * 3 * 3 == len({c.key for c in cells})
    argv = cells[0].run_args(out_dir="runs")
    assert argv[:2] == ["run", "--method"] and argv[-1] == "--json" and "--out" in argv
    assert spec.grid_id == GridSpec.from_dict(spec.to_dict()).grid_id  # same grid, same id
    bo = next(c for c in cells if c.method == "bo-specialized").run_args(store="sqlite:///x.db")
    assert bo[bo.index("--store") + 1] == "sqlite:///x.db"
    assert (
        bo[bo.index("--optimizer-option") + 1] == "storage=sqlite:///x.db"
    )  # the option BO declares for its study
    assert "--optimizer-option" not in cells[0].run_args(
        store="sqlite:///x.db"
    )  # only BO keeps a study


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("methods", ["ours", "sgd"], "unknown method 'sgd'"),
        ("seeds", [], "at least one value"),
        ("terrains", ["flat", "flat"], "twice"),
    ],
)
def test_bad_grid_is_one_clear_error(field, value, message):
    with pytest.raises(UserError, match=message):
        _spec(**{field: value})


@pytest.mark.slow
def test_local_grid_runs_cells_then_skips_them(tmp_path):
    store = ResultsStore(tmp_path / "g.db")
    spec = _spec(seeds=[0, 1])
    report = run_grid(spec, store, workers=2, out_dir=str(tmp_path / "runs"), command=FAKE_RUN)
    assert sorted(report.finished) == sorted(c.key for c in spec.cells()) and not report.failed
    runs = store.list_runs(grid_id=spec.grid_id)
    assert len(runs) == 4 and {r["status"] for r in runs} == {"finished"}
    assert all(store.count_evaluations(r["id"]) == 12 for r in runs)
    assert {r["cell"] for r in runs} == {c.key for c in spec.cells()}
    assert {c["status"] for c in store.cells(spec.grid_id).values()} == {"finished"}
    # the same grid again: nothing to run
    again = run_grid(spec, store, workers=2, out_dir=str(tmp_path / "runs"), command=FAKE_RUN)
    assert sorted(again.skipped) == sorted(report.finished) and not again.finished
    assert len(store.list_runs()) == 4
    # the grid's report covers its runs, one Table 7 row per method
    from coadapt_core.analysis.report import write_report

    files = write_report(store, spec.grid_id, tmp_path / "report", sim2sim=False)
    t7 = files["table7.csv"].read_text().splitlines()
    assert len(t7) == 3 and t7[1].startswith("kuafu,mujoco,smoke,ours,unknown,2,")
    assert t7[2].startswith("kuafu,mujoco,smoke,no-surrogate,unknown,2,")
    # a bigger grid runs only the new cells
    bigger = _spec(seeds=[0, 1, 2])
    third = run_grid(bigger, store, workers=2, out_dir=str(tmp_path / "runs"), command=FAKE_RUN)
    assert len(third.skipped) == 4 and len(third.finished) == 2


def test_killed_cell_is_resumed_without_losing_or_duplicating_evaluations(tmp_path, monkeypatch):
    store = ResultsStore(tmp_path / "g.db")
    spec = _spec(methods=["ours"])
    (cell,) = spec.cells()
    monkeypatch.setenv(
        "FAKE_CRASH_AT", f"{cell.key}:2"
    )  # dies after batch 1 is recorded, before its state is saved
    first = run_grid(spec, store, workers=1, out_dir=str(tmp_path / "runs"), command=FAKE_RUN)
    assert first.failed == [cell.key]
    (run,) = store.list_runs(cell=cell.key)
    assert run["status"] == "interrupted" and store.count_evaluations(run["id"]) == 6
    assert store.cells(spec.grid_id)[cell.key]["status"] == "failed"
    tasks, skipped = plan_grid(store, spec, out_dir=str(tmp_path / "runs"))
    assert (
        not skipped
        and tasks[0].resume == run["id"]
        and tasks[0].argv[-3:] == ["--resume", run["id"], "--json"]
    )

    second = run_grid(spec, store, workers=1, out_dir=str(tmp_path / "runs"), command=FAKE_RUN)
    assert second.finished == [cell.key] and second.resumed == [cell.key]
    (resumed,) = store.list_runs(cell=cell.key)  # the same run, continued
    assert resumed["id"] == run["id"] and resumed["status"] == "finished"
    rows = store.evaluations(run["id"])
    assert len(rows) == 12  # batch 1 redone: its 3 rows replaced, not duplicated
    assert len({(e.outer, e.inner, e.idx) for e in rows}) == 12
    assert store.cells(spec.grid_id)[cell.key]["attempts"] == 2


def test_killed_grid_resumes_runs_left_running(tmp_path):
    """The grid process itself was killed: its cells' runs are still marked running. The
    next invocation resumes those whose run folder exists and restarts the others."""
    store = ResultsStore(tmp_path / "g.db")
    spec = _spec(seeds=[0, 1])
    c0, c1, c2, c3 = spec.cells()
    (tmp_path / "runs" / "r0").mkdir(parents=True)
    (tmp_path / "runs" / "r0" / "state.json").write_text("{}")  # got as far as its first state
    store.create_run(
        {"method": c0.method, "objective": c0.objective, "seed": c0.seed, "grid_cell": c0.key},
        run_id="r0",
        run_dir=str(tmp_path / "runs" / "r0"),
    )
    store.create_run(
        {"method": c1.method, "objective": c1.objective, "seed": c1.seed, "grid_cell": c1.key},
        run_id="r1",
        run_dir=str(tmp_path / "runs" / "gone"),
    )
    from coadapt_core.coadapt.config_loading import make_config

    def by_hand(cell, run_id, **changed):
        config = make_config(
            "smoke",
            overrides={
                "method": cell.method,
                "objective": cell.objective,
                "terrain": "flat",
                "seed": cell.seed,
                "sim": "mujoco",
                **changed,
            },
        ).to_dict()
        store.finish_run(
            store.create_run({**config, "out": "elsewhere"}, run_id=run_id), {"best_cost": 1.0}
        )

    by_hand(c2, "r2")  # finished by hand, no grid, the cell's whole config: reused
    by_hand(c3, "r3", population=7)  # by hand with another population: not this cell's run
    tasks, skipped = plan_grid(store, spec, out_dir=str(tmp_path / "runs"))
    assert [c.key for c in skipped] == [c2.key]
    assert {t.cell.key: t.resume for t in tasks} == {c0.key: "r0", c1.key: None, c3.key: None}
    # the same cells with another --extra option: neither hand-made run matches any more
    other = _spec(seeds=[0, 1])
    other.extra_args = ["--population", "7"]
    _, skipped = plan_grid(store, other, out_dir=str(tmp_path / "runs"))
    assert [c.key for c in skipped] == [c3.key]


def test_cell_that_cannot_start_is_reported_failed(tmp_path):
    store = ResultsStore(tmp_path / "g.db")
    report = run_grid(
        _spec(methods=["ours"]),
        store,
        out_dir=str(tmp_path / "runs"),
        command=[sys.executable, "-c", "import sys; print('boom', file=sys.stderr); sys.exit(3)"],
    )
    assert len(report.failed) == 1
    assert "boom" in report.outcomes[report.failed[0]].error


def test_grid_cli_dry_run_and_bad_input(tmp_path):
    from tests.conftest import run_cli

    proc = run_cli(
        "grid",
        "--methods",
        "ours,no-real",
        "--objectives",
        "torque",
        "--terrains",
        "flat,slope",
        "--seeds",
        "0",
        "--preset",
        "smoke",
        "--store",
        str(tmp_path / "g.db"),
        "--dry-run",
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert sum(line.startswith("new") for line in lines) == 4 and lines[-1].endswith(
        "0 finished, 4 to run"
    )
    bad = run_cli("grid", "--seeds", "0,x", "--store", str(tmp_path / "g.db"))
    assert (
        bad.returncode == 2
        and bad.stderr.strip()
        == "error: --seeds must be comma-separated integers, e.g. 0,1,2; got '0,x'"
    )


@pytest.mark.slow
def test_ray_executor_runs_a_two_cell_grid(tmp_path):
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'coadapt[ray]')")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        store = ResultsStore(tmp_path / "ray.db")
        spec = _spec()
        start = time.perf_counter()
        report = run_grid(
            spec, store, executor="ray", out_dir=str(tmp_path / "runs"), command=FAKE_RUN
        )
        print(f"ray grid of 2 cells: {time.perf_counter() - start:.1f} s")
        assert sorted(report.finished) == sorted(c.key for c in spec.cells()) and not report.failed
        assert all(
            store.count_evaluations(r["id"]) == 12 for r in store.list_runs(grid_id=spec.grid_id)
        )
    finally:
        ray.shutdown()


@pytest.mark.slow
def test_local_grid_of_two_cells_at_once_on_two_cores_gives_each_one_thread(tmp_path, monkeypatch):
    """On 2 CPUs (the grid's `usable_cpus`, fixed here) 2 cells run at once with `--threads 1`
    each (cells at once x threads per cell <= cores), not one per core with every core each."""
    import coadapt_core.experiments.grid as grid_module

    monkeypatch.setattr(grid_module, "usable_cpus", lambda: 2)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    pools = []  # the cells at once the grid gave its process pool
    pool = grid_module.local_executor
    monkeypatch.setattr(
        grid_module,
        "local_executor",
        lambda tasks, workers: (pools.append(workers), pool(tasks, workers))[1],
    )
    store = ResultsStore(tmp_path / "g.db")
    report = run_grid(_spec(), store, out_dir=str(tmp_path / "runs"), command=FAKE_RUN)
    assert len(report.outcomes) == 2 and all(o.returncode == 0 for o in report.outcomes.values())
    configs = [r["config"] for r in store.list_runs(grid_id=_spec().grid_id)]
    assert [(c["threads"], c["omp_num_threads"]) for c in configs] == [(1, "1"), (1, "1")]
    assert pools == [2]  # the two at once
    one = run_grid(
        _spec(methods=["ours"], seeds=[5]), store, out_dir=str(tmp_path / "runs"), command=FAKE_RUN
    )
    (row,) = store.list_runs(grid_id=_spec(methods=["ours"], seeds=[5]).grid_id)
    assert (
        row["config"]["threads"] == 2 and not one.failed and pools == [2, 1]
    )  # a cell alone gets both cores


def test_a_local_grid_refuses_more_threads_than_cores(tmp_path, monkeypatch):
    import coadapt_core.experiments.grid as grid_module

    monkeypatch.setattr(grid_module, "usable_cpus", lambda: 2)
    store = ResultsStore(tmp_path / "g.db")
    with pytest.raises(UserError, match="--workers 2 x --threads 2 = 4 threads on 2 CPUs"):
        run_grid(
            _spec(), store, workers=2, threads=2, out_dir=str(tmp_path / "runs"), command=FAKE_RUN
        )
    with pytest.raises(UserError, match="--run-arg=--threads"):
        run_grid(
            _spec(extra_args=["--threads", "2"]),
            store,
            out_dir=str(tmp_path / "runs"),
            command=FAKE_RUN,
        )


if __name__ == "__main__":  # the fake `coadapt run` the grid starts in these tests
    sys.exit(fake_run(sys.argv[1:]))
