"""`coadapt report` and `coadapt landscape`: the tables' numbers are the store's numbers, the
figures exist, the sim-to-sim transfer goes through a `CoadaptationBackend` and writes rows
the report only reads (or says n/a and why), and a landscape run is stored like any run and
resumable."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from coadapt_core.analysis.report import write_report
from coadapt_core.errors import UserError
from coadapt_core.experiments.landscape import run_landscape
from coadapt_core.experiments.transfer import transfer_runs
from coadapt_core.fitness import CoadaptationBackend, RealFitness, TrainingResult
from coadapt_core.pareto import pareto_mask
from coadapt_core.plugins import get_registry
from coadapt_core.results import ResultsStore, SqliteRecorder

OPTIMUM = np.array([0.62, 0.57])


def objective_instances(names):
    return [get_registry().create("objective", n) for n in names]


def analytic_cost(designs: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """[K] a bowl with its minimum at OPTIMUM."""
    designs = np.atleast_2d(designs)
    return scale * (1.0 + ((designs[:, :2] - OPTIMUM) ** 2).sum(axis=1))


class AnalyticBackend:
    """Real fitness of a known bowl; `scale` stands in for a second simulator's physics."""

    def __init__(self, scale: float = 1.0, fail_on_call: int | None = None):
        self.scale = scale
        self.calls = 0
        self.fail_on_call = fail_on_call

    def train(self, designs, steps, *, seed=0):
        return TrainingResult(steps=steps, seconds=0.0, mean_reward=0.0)

    def real_fitness(self, designs, objectives, *, agents, steps, seed=0):
        self.calls += 1
        if self.fail_on_call is not None and self.calls == self.fail_on_call:
            raise RuntimeError("simulated crash")
        c = analytic_cost(designs, self.scale)
        return RealFitness(
            costs=np.stack([c] * len(objectives), axis=1),
            buffer=None,
            interactions=len(designs) * agents * steps,
            seconds=0.01,
        )

    def surrogate_fitness(self, designs, objectives, buffer, *, samples, seed=0):
        return np.stack([analytic_cost(designs)] * len(objectives), axis=1)

    def save(self, path):
        Path(path).write_text("ckpt")

    def load(self, path):
        pass


def record_run(
    rec: SqliteRecorder,
    method: str,
    seed: int,
    *,
    objectives=("torque",),
    terrain="flat",
    checkpoint: Path | None = None,
    optimizer="pso",
    numerics: dict | None = None,
) -> str:
    """A small finished run as the loop records it: 2 training phases, 2 x 2 batches of 4
    real designs (surrogate scored too), 4 surrogate-only designs, best and nominal."""
    rng = np.random.default_rng(seed + 17 * len(method))
    config = {
        "method": method,
        "objective": ",".join(objectives),
        "terrain": terrain,
        "seed": seed,
        "preset": "smoke",
        "sim": "mujoco",
        "robot": "kuafu",
        "optimizer": optimizer,
    }
    if (
        checkpoint is not None
    ):  # a run folder named after the run, holding its policy (as the loop writes)
        config["run_id"] = f"{method}-{'+'.join(objectives)}-{terrain}-{optimizer}-s{seed}"
        config["run_dir"] = str(checkpoint.parent / config["run_id"])
        (checkpoint.parent / config["run_id"] / "checkpoints").mkdir(parents=True, exist_ok=True)
        checkpoint = Path(config["run_dir"]) / "checkpoints" / checkpoint.name
        checkpoint.write_text("weights")
    run_id = rec.start_run(config)
    for outer in range(2):
        rec.record_training(
            run_id,
            outer=outer,
            result=TrainingResult(steps=10_000 * (seed + 1), seconds=2.0 + seed, mean_reward=0.3),
        )
        for inner in range(2):
            designs = rng.uniform(0.5, 1.5, size=(4, 2))
            real = analytic_cost(designs)
            rec.record_evaluations(
                run_id,
                outer=outer,
                inner=inner,
                designs=designs,
                kind="real",
                costs=[{o: float(c) * (1 + i) for i, o in enumerate(objectives)} for c in real],
                interactions=1000,
                seconds=0.5,
                surrogate_errors=[{objectives[0]: 0.1 * (d[0] - 1)} for d in designs],
            )
            rec.record_evaluations(
                run_id,
                outer=outer,
                inner=inner,
                designs=rng.uniform(0.5, 1.5, size=(1, 2)),
                costs=[{objectives[0]: 1.0}],
                kind="surrogate",
                interactions=0,
                seconds=0.05,
            )
        if checkpoint is not None:
            rec.record_checkpoint(run_id, outer=outer, path=str(checkpoint))
    real = rec.store.evaluations(run_id, kind="real")
    best = min(real, key=lambda e: e.costs[objectives[0]])
    nominal = float(analytic_cost(np.array([1.0, 1.0]))[0])
    rec.finish(
        run_id,
        {
            "run_id": run_id,
            "best_design": best.design,
            "best_cost": best.costs[objectives[0]],
            "nominal_cost": nominal,
            "improvement": (nominal - best.costs[objectives[0]]) / nominal,
            **({"numerics": numerics} if numerics else {}),
        },
    )
    return run_id


@pytest.fixture
def filled_store(tmp_path):
    ckpt = tmp_path / "policy.pt"
    ckpt.write_text("weights")
    rec = SqliteRecorder(tmp_path / "r.db")
    ids = {
        (m, s): record_run(rec, m, s, checkpoint=ckpt)
        for m in ("ours", "no-surrogate")
        for s in (0, 1)
    }
    return rec.store, ids


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_report_tables_match_the_store(filled_store, tmp_path):
    store, ids = filled_store
    files = write_report(store, None, tmp_path / "rep", sim2sim=False)
    for name in (
        "table6.csv",
        "table6.md",
        "table7.csv",
        "table7.md",
        "report.html",
        "heatmap_flat.png",
        "convergence.png",
        "surrogate_error.png",
    ):
        assert files[name].exists() and files[name].stat().st_size > 0, name
    t6 = {(r["method"], r["terrain"]): r for r in read_csv(files["table6.csv"])}
    assert all(r["optimizer"] == "pso" for r in t6.values())
    for method in ("ours", "no-surrogate"):
        runs = [store.get_run(ids[(method, s)]) for s in (0, 1)]
        row = t6[(method, "flat")]
        assert int(row["runs"]) == 2
        # design columns are named after the robot's design space, with the spread over seeds
        thighs = [r["summary"]["best_design"][0] for r in runs]
        assert float(row["thigh_scale"]) == pytest.approx(np.mean(thighs))
        assert float(row["thigh_scale_std"]) == pytest.approx(np.std(thighs, ddof=1))
        assert float(row["shank_scale"]) == pytest.approx(
            np.mean([r["summary"]["best_design"][1] for r in runs])
        )
        improvements = [r["summary"]["improvement"] for r in runs]
        assert float(row["improvement"]) == pytest.approx(np.mean(improvements))
        assert float(row["improvement_std"]) == pytest.approx(np.std(improvements, ddof=1))
        assert int(row["improvement_n"]) == 2
        assert row["sim2sim_improvement"] == "" and "not requested" in row["sim2sim_note"]
    t7 = {r["method"]: r for r in read_csv(files["table7.csv"]) if r["optimizer"] == "pso"}
    for method in ("ours", "no-surrogate"):
        train = [sum(t["steps"] for t in store.training(ids[(method, s)])) for s in (0, 1)]
        evals = [store.evaluations(ids[(method, s)]) for s in (0, 1)]
        assert float(t7[method]["interactions_training"]) == pytest.approx(np.mean(train)) == 30_000
        assert (
            float(t7[method]["interactions_evaluation"])
            == pytest.approx(
                np.mean([sum(e.interactions for e in ev if e.kind == "real") for ev in evals])
            )
            == 16_000
        )
        assert float(t7[method]["seconds_evaluation"]) == pytest.approx(
            np.mean([sum(e.seconds for e in ev) for ev in evals])
        )
        assert (
            float(t7[method]["designs_real"]) == 16 and float(t7[method]["designs_surrogate"]) == 4
        )
    md = files["table7.md"].read_text()
    # thousands: 30 k training (20 k and 40 k: std 14.1 k) + 16 k evaluation
    assert "| Ours | pso | 2 | 46 ± 14.1 (30+16) |" in md
    t6md = files["table6.md"].read_text()
    assert "Ours w/o Surrogate" in t6md and "| Runs |" in t6md and "thigh_scale [x 0.35 m]" in t6md
    mean, std = np.mean(improvements), np.std(improvements, ddof=1)  # the last method's
    assert f"{100 * mean:.1f}% ± {100 * std:.1f}% (n=2)" in t6md
    html = files["report.html"].read_text()
    assert all(
        f"src='{p}'" in html for p in ("heatmap_flat.png", "convergence.png", "surrogate_error.png")
    )


def test_sim_to_sim_transfer_uses_the_backend_writes_rows_the_report_reads(filled_store, tmp_path):
    store, ids = filled_store
    built = []

    def factory(robot, simulator, objectives, *, terrain, checkpoint, **kwargs):
        assert (
            simulator.name == "pybullet" and checkpoint.endswith("policy.pt") and terrain == "flat"
        )
        backend = AnalyticBackend(scale=1.5)
        built.append(backend)
        assert isinstance(backend, CoadaptationBackend)
        return backend

    run = store.get_run(ids[("ours", 0)])
    assert transfer_runs(store, [run], simulator="pybullet", factory=factory) == {}
    files = write_report(store, ids[("ours", 0)], tmp_path / "rep", transfer_simulator="pybullet")
    (row,) = read_csv(files["table6.csv"])
    best = np.array(run["summary"]["best_design"])
    b, n = analytic_cost(best, 1.5)[0], analytic_cost(np.ones(2), 1.5)[0]
    assert float(row["sim2sim_improvement"]) == pytest.approx((n - b) / n)
    assert row["sim2sim_note"] == "pybullet, 2 designs"
    rows = store.evaluations(run["id"], kind="sim2sim")
    assert [(e.idx, e.simulator) for e in rows] == [(0, "pybullet"), (1, "pybullet")]
    assert (
        store.count_evaluations(run["id"], kind="real") == 16
    )  # transfer rows are not real-run evidence
    assert transfer_runs(store, [run], simulator="pybullet", factory=factory) == {}
    assert len(built) == 1  # the second transfer finds the stored rows


def test_the_report_reads_and_never_writes(filled_store, tmp_path):
    """The report runs no simulation and writes no row: without transfer rows its column
    says so; every table's row count is the same after it."""
    store, _ = filled_store
    before = {
        t: len(store.table_rows(t))
        for t in ("runs", "evaluations", "training_phases", "checkpoints")
    }
    files = write_report(store, None, tmp_path / "rep")
    after = {t: len(store.table_rows(t)) for t in before}
    assert after == before and before["evaluations"] > 0
    rows = read_csv(files["table6.csv"])
    assert rows and all(
        r["sim2sim_improvement"] == "" and "no sim-to-sim rows" in r["sim2sim_note"] for r in rows
    )


def test_sim_to_sim_says_why_when_not_available(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = record_run(rec, "ours", 0)  # no checkpoint recorded
    notes = transfer_runs(rec.store, [rec.store.get_run(run_id)], simulator="pybullet")
    assert notes == {run_id: "n/a: the run recorded no policy checkpoint"}
    files = write_report(
        rec.store, run_id, tmp_path / "rep", transfer_simulator="pybullet", transfer_notes=notes
    )
    (row,) = read_csv(files["table6.csv"])
    assert (
        row["sim2sim_improvement"] == ""
        and row["sim2sim_note"] == "n/a: the run recorded no policy checkpoint"
    )
    assert "| n/a | n/a: the run recorded no policy checkpoint |" in files["table6.md"].read_text()


def test_landscape_is_stored_as_a_run_and_drives_the_heatmap(filled_store, tmp_path):
    store, _ = filled_store
    rec = SqliteRecorder(store)
    (torque,) = objective_instances(["torque"])
    summary = run_landscape(
        AnalyticBackend(),
        [torque],
        rec,
        config={"terrain": "flat", "sim": "mujoco", "robot": "kuafu"},
        grid=11,
        agents=2,
        steps=5,
    )
    run = store.get_run(summary["run_id"])
    assert run["method"] == "landscape" and run["status"] == "finished"
    rows = store.evaluations(run["id"], kind="real")
    assert len(rows) == 121 and sum(e.interactions for e in rows) == 121 * 2 * 5
    np.testing.assert_allclose(summary["best_design"], [0.6, 0.6])  # the grid point nearest OPTIMUM
    assert summary["nominal_cost"] == pytest.approx(analytic_cost(np.ones(2))[0])
    files = write_report(store, None, tmp_path / "rep", sim2sim=False)
    assert "landscape run" in files["report.html"].read_text()
    t6 = read_csv(files["table6.csv"])
    assert {r["method"] for r in t6} == {"ours", "no-surrogate"}  # the landscape is not a method


def test_interrupted_landscape_resumes_without_reevaluating_rows(tmp_path):
    rec = SqliteRecorder(tmp_path / "l.db")
    (torque,) = objective_instances(["torque"])
    crashing = AnalyticBackend(fail_on_call=4)  # dies on the 4th grid row
    with pytest.raises(RuntimeError):
        run_landscape(
            crashing, [torque], rec, config={"terrain": "flat"}, grid=5, agents=1, steps=1
        )
    (run,) = rec.store.list_runs(method="landscape")
    assert rec.store.count_evaluations(run["id"]) == 15 and run["status"] == "interrupted"
    again = AnalyticBackend()
    summary = run_landscape(
        again,
        [torque],
        SqliteRecorder(tmp_path / "l.db"),
        config={"terrain": "flat", "run_id": run["id"]},
        grid=5,
        agents=1,
        steps=1,
    )
    assert again.calls == 2 and summary["run_id"] == run["id"]
    assert rec.store.count_evaluations(run["id"]) == 25


def test_axes_go_logarithmic_only_for_costs_over_three_decades():
    from coadapt_core.analysis.figures import spans_decades

    assert spans_decades([900.0, 2.0e3, 3.5e11])  # one diverged rollout among sane costs
    assert not spans_decades([900.0, 2.0e3, 8.0e5])
    assert not spans_decades([-1.0, 1e6])  # signed values: never a log axis
    assert not spans_decades([np.nan, 5.0])


def test_pareto_front_of_a_two_objective_run(tmp_path):
    costs = np.array([[1.0, 5.0], [2.0, 2.0], [3.0, 3.0], [5.0, 1.0], [2.0, 2.5]])
    assert pareto_mask(costs).tolist() == [True, True, False, True, False]
    rec = SqliteRecorder(tmp_path / "p.db")
    run_id = record_run(rec, "ours", 0, objectives=("torque", "power"), optimizer="nsga2")
    files = write_report(rec.store, run_id, tmp_path / "rep", sim2sim=False)
    assert files["pareto.png"].stat().st_size > 0


def test_report_of_unknown_selection_is_one_line(tmp_path):
    store = ResultsStore(tmp_path / "e.db")
    with pytest.raises(UserError, match="neither a run nor a grid"):
        write_report(store, "nope", tmp_path / "rep")
    with pytest.raises(UserError, match="no finished runs"):
        write_report(store, None, tmp_path / "rep")


@pytest.mark.slow
def test_report_cli_writes_files(filled_store, tmp_path):
    from tests.conftest import run_cli

    store, _ = filled_store
    proc = run_cli("report", "--store", store.url, "-o", str(tmp_path / "cli"), "--no-sim-to-sim")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "cli" / "report.html").exists() and (
        tmp_path / "cli" / "heatmap_flat.png"
    ).exists()
    bad = run_cli("report", "missing-run", "--store", store.url, "-o", str(tmp_path / "cli"))
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--grid", "1"], "error: grid must be an integer in [2, 101], got 1"),
        (["--terrain", "ice"], "error: terrain 'ice' is not one of flat, slope, random"),
        (
            ["--checkpoint", "/nonexistent/policy.pt"],
            "error: --checkpoint /nonexistent/policy.pt does not exist",
        ),
        (["--objective", "speed"], "error: unknown objective 'speed'"),
    ],
)
def test_landscape_cli_bad_input_is_one_line(tmp_path, args, message):
    from tests.conftest import run_cli

    proc = run_cli("landscape", "--store", str(tmp_path / "l.db"), *args)
    assert proc.returncode == 2
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(message)


@pytest.mark.slow
def test_landscape_cli_on_real_mujoco_with_a_saved_policy(tmp_path):
    """End to end: a barely trained universal policy saved by the learner, a 3 x 3 landscape
    on MuJoCo through `coadapt landscape`, stored as a run the report draws."""
    from coadapt_core.learning.backend import UniversalPolicyBackend
    from coadapt_core.plugins import get_registry
    from tests.conftest import run_cli

    registry = get_registry()
    robot = registry.get("robot", "kuafu")()
    backend = UniversalPolicyBackend(
        robot,
        registry.get("simulator", "mujoco"),
        objective_instances(["torque"]),
        terrain="flat",
        design_space=robot.design_space(),
        agents_per_design=1,
        seed=0,
    )
    backend.train(np.array([[1.0, 1.0]]), 64, seed=0)  # builds the networks; a few PPO steps
    backend.save(str(tmp_path / "policy.pt"))
    proc = run_cli(
        "landscape",
        "--objective",
        "torque",
        "--grid",
        "3",
        "--agents",
        "1",
        "--steps",
        "10",
        "--checkpoint",
        str(tmp_path / "policy.pt"),
        "--store",
        str(tmp_path / "l.db"),
        "--json",
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    store = ResultsStore(tmp_path / "l.db")
    rows = store.evaluations(summary["run_id"], kind="real")
    assert len(rows) == 9 and sum(e.interactions for e in rows) == 9 * 10
    assert (
        summary["interactions"] == 10 * 10
    )  # and the nominal design once more: the capped rule's reference
    assert sorted({round(e.design[0], 6) for e in rows}) == [0.5, 1.0, 1.5]
    best = min(rows, key=lambda e: e.costs["torque"])
    assert (
        summary["best_cost"] == pytest.approx(best.costs["torque"])
        and summary["best_design"] == best.design
    )
    assert all(np.isfinite(e.costs["torque"]) and e.costs["torque"] >= 0 for e in rows)


def test_the_report_says_which_rows_it_simulates_and_no_evaluate_simulates_none(
    filled_store, tmp_path, capsys
):
    """Issue 50: before simulating, one line names the runs that lack rows (simulated once,
    stored); once they are stored it says nothing is simulated; --no-evaluate writes no row."""
    from coadapt_core.cli.report import _say_missing

    store, ids = filled_store
    runs = [store.get_run(i) for i in sorted(ids.values())]
    _say_missing(store, runs, "pybullet", common=False)
    line = capsys.readouterr().err.strip()
    listed = ", ".join(r["id"] for r in runs)
    assert line == (
        "report: simulating the rows these runs lack, once (stored: later reports read them "
        f"back; --no-evaluate skips them): sim-to-sim on pybullet: {listed}"
    )

    def factory(robot, simulator, objectives, *, terrain, checkpoint, **kwargs):
        return AnalyticBackend(scale=1.5)

    assert transfer_runs(store, runs, simulator="pybullet", factory=factory) == {}
    _say_missing(store, runs, "pybullet", common=False)
    assert capsys.readouterr().err.strip() == (
        "report: every run's sim-to-sim and common-scenario rows are stored; nothing is simulated"
    )
    before = len(store.table_rows("evaluations"))
    db = store.url.removeprefix("sqlite:///")
    from coadapt_core.cli import main

    out = tmp_path / "rep"
    assert main(["report", "--store", db, "--no-evaluate", "-o", str(out)]) == 0
    assert len(store.table_rows("evaluations")) == before
    assert "simulating" not in capsys.readouterr().err


def test_the_report_names_each_runs_numerics(tmp_path):
    """Table 6 (CSV, Markdown, HTML) says which numerics trained and evaluated each run of a
    row; a run from before they were recorded says so."""
    rec = SqliteRecorder(tmp_path / "r.db")
    numerics = {
        "precision": "bf16",
        "device": "cpu",
        "processor": "AMD EPYC 9B14",
        "torch": "2.13.0",
        "engine": "mujoco",
        "engine_version": "4.0.0",
    }
    record_run(rec, "ours", 0, numerics=numerics)
    record_run(rec, "ours", 1)  # an older run: nothing recorded
    files = write_report(rec.store, None, tmp_path / "rep", sim2sim=False)
    (row,) = read_csv(files["table6.csv"])
    said = "bf16 learner, CPU AMD EPYC 9B14, torch 2.13.0, mujoco 4.0.0; not recorded"
    assert row["numerics"] == said
    md = files["table6.md"].read_text()
    assert "| Numerics |" in md.splitlines()[0] and f"| {said} |" in md
    assert "<th>numerics</th>" in files["report.html"].read_text()


def test_fall_rate_differences_read_in_points():
    """A difference of two fall rates is in percentage points, signed, as `coadapt run` says
    it, never a percentage (issue 61): over seeds with their spread, one run with its SE."""
    from coadapt_core.analysis.table_markdown import cell, common_cell

    assert cell({"d": 0.008, "d_std": 0.008, "d_n": 3}, "d", points=True) == (
        "+0.8 ± 0.8 points (n=3)"
    )
    assert cell({"d": -0.004, "d_se": 0.002, "d_n": 1}, "d", points=True) == (
        "-0.4 ± 0.2 points SE (n=1)"
    )
    row = {
        **{f"common_improvement{k}": v for k, v in (("", 0.3), ("_std", 0.02), ("_n", 2))},
        **{f"common_improvement_plain{k}": v for k, v in (("", 0.2), ("_std", 0.05), ("_n", 2))},
        **{f"common_fall_rate_difference{k}": v for k, v in (("", 0.01), ("_std", 0.0), ("_n", 2))},
    }
    assert common_cell(row) == "30.0% ± 2.0% (n=2) / 20.0% ± 5.0% (n=2) / +1.0 ± 0.0 points (n=2)"
