"""Faults a user meets: a grid killed half-way, resuming a finished run, a run folder resumed
from another working folder, damaged state/buffer/store files, a full disk, a store that lost
rows, Ctrl-C in `coadapt train`, physics divergences in `coadapt eval`. Loop logic uses the
analytic fake backend; train and eval use the real Kuafu robot on MuJoCo."""

from __future__ import annotations

import errno
import json
import os
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.cli import main
from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.errors import UserError
from coadapt_core.results import ResultsStore
from coadapt_core.results.recorders import read_evaluations
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

BASE = dict(
    population=4,
    optimizer_iterations=2,
    outer_iterations=2,
    agents_per_design=4,
    eval_steps=5,
    train_steps=100,
    retrain_steps=50,
    seed=5,
)


def start(run_dir, store, factory=lambda s: AnalyticBackend(s), **overrides):
    config = make_config("smoke", overrides={**BASE, "store": str(store), **overrides})
    return run_coadaptation(
        config,
        backend_factory=factory,
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        run_dir=run_dir,
    )


def resume(run_dir):
    return run_coadaptation(
        backend_factory=lambda s: AnalyticBackend(s),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        resume=run_dir,
    )


def test_grid_restarts_a_cell_killed_before_its_first_state_file(tmp_path):
    """Registered in the store, folder made, no state.json yet: the next grid starts it afresh
    (it used to resume it and fail for good)."""
    from coadapt_core.experiments.grid_plan import GridSpec, plan_grid

    store = ResultsStore(tmp_path / "g.db")
    spec = GridSpec(
        methods=["ours"], objectives=["torque"], terrains=["flat"], seeds=[0, 1], preset="smoke"
    )
    c0, c1 = spec.cells()
    for cell, run_id in ((c0, "half-registered"), (c1, "has-state")):
        folder = tmp_path / "runs" / run_id
        folder.mkdir(parents=True)
        store.create_run(
            {"method": "ours", "objective": "torque", "seed": cell.seed, "grid_cell": cell.key},
            run_id=run_id,
            run_dir=str(folder),
        )
    (tmp_path / "runs" / "has-state" / "state.json").write_text("{}")
    tasks, _ = plan_grid(store, spec, out_dir=str(tmp_path / "runs"))
    assert {t.cell.key: t.resume for t in tasks} == {c0.key: None, c1.key: "has-state"}
    assert "--resume" not in tasks[0].argv


def test_resuming_a_finished_run_leaves_it_finished(tmp_path):
    db = tmp_path / "s.db"
    result = start(tmp_path / "runs" / "done", db)
    store = ResultsStore(db)
    assert store.get_run(result.run_id)["status"] == "finished"
    again = resume(tmp_path / "runs" / "done")
    assert again.summary == result.summary
    run = store.get_run(result.run_id)
    assert (
        run["status"] == "finished" and run["summary"]["best_cost"] == result.summary["best_cost"]
    )


def test_run_folder_resumes_from_any_working_folder(tmp_path, monkeypatch):
    """Started with a relative run folder from one working folder, interrupted, resumed by
    absolute path from another: nothing in the state is relative to the first."""
    first, second = tmp_path / "a", tmp_path / "b"
    first.mkdir()
    second.mkdir()
    monkeypatch.chdir(first)
    with pytest.raises(RuntimeError):
        start(Path("runs/r"), "none", factory=lambda s: AnalyticBackend(s, fail_on_real_call=3))
    state = json.loads((first / "runs" / "r" / "state.json").read_text())
    assert (
        state["backend_checkpoint"] is None or not Path(state["backend_checkpoint"]).is_absolute()
    )
    monkeypatch.chdir(second)
    result = resume(first / "runs" / "r")
    monkeypatch.chdir(first)
    reference = start(Path("runs/ref"), "none")
    assert result.summary["best_cost"] == reference.summary["best_cost"]
    assert result.summary["best_design"] == reference.summary["best_design"]


@pytest.fixture
def interrupted(tmp_path):
    """A run folder stopped after its second real round, with its state and buffer files."""
    with pytest.raises(RuntimeError):
        start(
            tmp_path / "runs" / "r",
            tmp_path / "s.db",
            factory=lambda s: AnalyticBackend(s, fail_on_real_call=2),
        )
    run = tmp_path / "runs" / "r"
    assert (run / "state.json").is_file() and list(run.glob("buffer-*.npz"))
    return run


@pytest.mark.parametrize(
    "damage",
    ["empty state", "garbage state", "truncated state", "garbage buffer", "missing buffer"],
)
def test_damaged_state_or_buffer_is_one_line_naming_the_file(interrupted, capsys, damage):
    (buffer,) = interrupted.glob("buffer-*.npz")
    state = interrupted / "state.json"
    if damage == "empty state":
        state.write_bytes(b"")
    elif damage == "garbage state":
        state.write_bytes(os.urandom(300))
    elif damage == "truncated state":
        state.write_bytes(state.read_bytes()[:200])
    elif damage == "garbage buffer":
        buffer.write_bytes(b"PK\x03\x04" + os.urandom(200))
    else:
        buffer.unlink()
    capsys.readouterr()
    code = main(["run", "--resume", str(interrupted)])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err
    named = buffer.name if "buffer" in damage else "state.json"
    assert named in lines[0] and "start it again" in lines[0]


def test_damaged_store_is_one_line_saying_how_to_recover(tmp_path):
    db = tmp_path / "s.db"
    start(tmp_path / "runs" / "r", db)
    db.write_bytes(b"this is not a database any more " * 200)
    for suffix in ("-wal", "-shm"):
        Path(str(db) + suffix).unlink(missing_ok=True)
    from tests.conftest import run_cli

    proc = run_cli("report", "--no-sim-to-sim", "--store", str(db), "--out", str(tmp_path / "rep"))
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "s.db" in lines[0] and "--resume" in lines[0]


def test_store_rows_lost_are_refilled_from_the_run_folder_on_resume(interrupted, tmp_path):
    db = tmp_path / "s.db"
    store = ResultsStore(db)
    run_id = interrupted.name
    before = store.count_evaluations(run_id)
    assert before == len(read_evaluations(interrupted)) > 0
    with sqlite3.connect(db) as conn:  # the store loses this run's rows
        conn.execute("DELETE FROM evaluations")
        conn.execute("DELETE FROM training_phases")
        conn.execute("DELETE FROM runs")
    resume(interrupted)
    rows = store.evaluations(run_id)
    assert (
        len(rows)
        == len(read_evaluations(interrupted))
        == len({(e.outer, e.inner, e.kind, e.idx) for e in rows})
    )
    assert len(rows) > before  # the lost rows are back and the run went on
    assert store.get_run(run_id)["status"] == "finished"
    assert len(store.training(run_id)) == len({t["outer"] for t in store.training(run_id)}) >= 1


def test_full_disk_is_one_line_and_leaves_no_partial_file(tmp_path, monkeypatch):
    from coadapt_core import statefile

    calls = {"n": 0}
    real_fsync = os.fsync

    def fsync(fd):
        calls["n"] += 1
        if calls["n"] >= 3:  # the disk fills up during the run
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_fsync(fd)

    monkeypatch.setattr(statefile.os, "fsync", fsync)
    with pytest.raises(UserError, match="disk full") as info:
        start(tmp_path / "runs" / "r", "none")
    assert "\n" not in str(info.value)
    leftovers = [p.name for p in (tmp_path / "runs" / "r").rglob("*") if p.name.endswith(".tmp")]
    assert leftovers == []


def test_checkpoint_write_on_a_full_disk_leaves_no_partial_file(tmp_path, monkeypatch):
    import torch

    from coadapt_core.learning import trainer as trainer_module

    def save(obj, path):
        Path(path).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(torch, "save", save)
    target = tmp_path / "model.pt"
    with pytest.raises(UserError, match=r"disk full writing .*model\.pt"):
        trainer_module.write_atomic(target, lambda tmp: torch.save({"x": 1}, tmp))
    assert list(tmp_path.iterdir()) == []
    from coadapt_core.cli.common import os_error_line

    line = os_error_line(OSError(errno.ENOSPC, "No space left on device", str(target)))
    assert line.startswith("disk full") and "model.pt" in line


@pytest.mark.slow
def test_ctrl_c_in_train_writes_a_checkpoint_first(tmp_path):
    out = tmp_path / "t"
    cmd = [
        sys.executable,
        "-c",
        "import sys; from coadapt_core.cli import main; sys.exit(main(sys.argv[1:]))",
        "train",
        "--steps",
        "100000",
        "--num-designs",
        "2",
        "--agents",
        "4",
        "--steps-per-env",
        "8",
        "--epochs",
        "1",
        "--minibatches",
        "2",
        "--checkpoint-every",
        "1000",
        "--quiet",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()  # the first iteration finished
    assert first.startswith("{"), proc.stderr.read()
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    assert proc.returncode == 130, err
    saved = sorted((out / "checkpoints").glob("model_*.pt"))
    assert len(saved) == 1 and "Traceback" not in err
    iteration = int(saved[0].stem.split("_")[1])
    assert iteration >= 1 and f"wrote {saved[0]}" in err
    rows = [json.loads(line) for line in (out / "progress.jsonl").read_text().splitlines()]
    assert rows[-1]["iteration"] == iteration  # the checkpoint holds the last finished iteration
    from coadapt_core.learning.checkpoints import read_checkpoint

    assert int(read_checkpoint(saved[0])["iteration"]) == iteration


@pytest.mark.slow
def test_eval_reports_divergences(capsys):
    assert main(["eval", "--agents", "2", "--seconds", "0.2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert isinstance(out["divergences"], int) and out["divergences"] == 0


def test_eval_counts_divergences_the_simulator_flags(monkeypatch):
    """A simulator that flags divergence on some agent-steps: eval's count is their number."""
    import torch

    from coadapt_core.task import env as env_module

    real_step = env_module.LocomotionEnv.step
    flagged = {"n": 0}

    def step(self, *args, **kwargs):
        out = real_step(self, *args, **kwargs)
        if flagged["n"] < 3:
            mask = torch.zeros_like(torch.as_tensor(self.state.diverged), dtype=torch.bool)
            mask[0] = True
            self.state.diverged = mask
            flagged["n"] += 1
        return out

    monkeypatch.setattr(env_module.LocomotionEnv, "step", step)
    from coadapt_core.experiments.evaluate import evaluate_checkpoint
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    robot = registry.create("robot", "kuafu")
    sim_cls = registry.get("simulator", "mujoco")
    shipped = robot.shipped_policy("flat", False)
    result = evaluate_checkpoint(
        shipped,
        robot,
        sim_cls,
        robot.nominal_design(),
        terrain="flat",
        command=[0.5, 0, 0],
        agents=2,
        seconds=0.2,
    )
    assert result["divergences"] == 3


def read_only(monkeypatch, folder: Path) -> None:
    """Writes under `folder` fail as on a read-only file system (EROFS), whoever runs the test
    (root ignores a chmod): Python's own file functions are wrapped."""
    import builtins

    folder = str(folder.resolve())

    def under(path) -> bool:
        try:
            return os.path.abspath(os.fsdecode(path)).startswith(folder)
        except TypeError:  # a file descriptor
            return False

    def refuse(path):
        raise OSError(
            errno.EROFS, "Read-only file system", os.fsencode(path)
        )  # as some libraries pass it: bytes

    real_open, real_os_open = builtins.open, os.open
    real_replace, real_makedirs, real_mkdir, real_unlink = (
        os.replace,
        os.makedirs,
        os.mkdir,
        os.unlink,
    )

    def open_(file, mode="r", *a, **k):
        if any(c in mode for c in "wax+") and under(file):
            refuse(file)
        return real_open(file, mode, *a, **k)

    def os_open(path, flags, *a, **k):
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT) and under(path):
            refuse(path)
        return real_os_open(path, flags, *a, **k)

    def guard(real):
        def wrapped(path, *a, **k):
            if under(path) and not (real is real_makedirs and os.path.isdir(path)):
                refuse(path)
            return real(path, *a, **k)

        return wrapped

    monkeypatch.setattr(builtins, "open", open_)
    monkeypatch.setattr(os, "open", os_open)
    monkeypatch.setattr(
        os,
        "replace",
        lambda src, dst, *a, **k: refuse(dst) if under(dst) else real_replace(src, dst, *a, **k),
    )
    for name, real in (("makedirs", real_makedirs), ("mkdir", real_mkdir), ("unlink", real_unlink)):
        monkeypatch.setattr(os, name, guard(real))


def test_resuming_a_run_in_a_read_only_folder_is_one_line_naming_it(
    interrupted, capsys, monkeypatch
):
    """The run folder can be read, not written: one line naming the folder as text (not
    b'...'), exit 2, and no traceback from TensorBoard's writer thread."""
    import shutil
    import threading

    shutil.rmtree(interrupted / "tb", ignore_errors=True)  # TensorBoard would make its folder first
    capsys.readouterr()
    threads = set(threading.enumerate())
    read_only(monkeypatch, interrupted)
    code = main(["run", "--resume", str(interrupted)])
    monkeypatch.undo()
    for thread in set(threading.enumerate()) - threads:
        thread.join(timeout=5)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and "Traceback" not in err, err
    assert len(lines) == 1 and f"'{interrupted}'" in lines[0] and "b'/" not in lines[0], err
    assert "writ" in lines[0]  # says it cannot write there


def test_a_path_given_as_bytes_is_shown_as_text():
    from coadapt_core.cli.common import os_error_line

    line = os_error_line(OSError(errno.EROFS, "Read-only file system", b"/data/runs/r/events"))
    assert (
        line.startswith("cannot write '/data/runs/r/events' (Read-only file system)")
        and "b'/" not in line
    )


def test_a_grid_settles_runs_killed_before_their_first_state_file(tmp_path):
    """An older coadapt registered a run before writing its state; a grid killed in between
    left it "running" over a folder holding only config.yaml. The next grid marks it failed,
    removes that folder (and only such a folder, only inside --out) and starts the cell again."""
    from coadapt_core.experiments.grid_plan import GridSpec, plan_grid, settle_abandoned

    store = ResultsStore(tmp_path / "g.db")
    spec = GridSpec(
        methods=["ours"], objectives=["torque"], terrains=["flat"], seeds=[0, 1, 2], preset="smoke"
    )
    cells = spec.cells()
    runs = tmp_path / "runs"
    ids = [
        "20260101-000000-ours-pso-torque-s0-aaaaaa",
        "20260101-000000-ours-pso-torque-s1-bbbbbb",
        "20260101-000000-ours-pso-torque-s2-cccccc",
    ]
    for cell, run_id in zip(cells, ids, strict=True):
        (runs / run_id / "tb").mkdir(parents=True)
        (runs / run_id / "config.yaml").write_text("seed: 0\n")
        store.create_run(
            {"method": "ours", "objective": "torque", "seed": cell.seed, "grid_cell": cell.key},
            run_id=run_id,
            run_dir=str(runs / run_id),
        )
    (runs / ids[1] / "state.json").write_text("{}")  # this one can be resumed: left alone
    (runs / ids[2] / "notes.txt").write_text("mine")  # a file coadapt did not write: folder kept
    settled = settle_abandoned(store, spec, runs)
    assert sorted(settled) == sorted([ids[0], ids[2]])
    status = {r["id"]: r["status"] for r in store.list_runs()}
    assert status == {ids[0]: "failed", ids[1]: "running", ids[2]: "failed"}
    assert (
        not (runs / ids[0]).exists()
        and (runs / ids[1]).is_dir()
        and (runs / ids[2] / "notes.txt").is_file()
    )
    tasks, _ = plan_grid(store, spec, out_dir=str(runs))
    assert {t.cell.seed: t.resume for t in tasks} == {0: None, 1: ids[1], 2: None}


def test_a_run_is_registered_in_the_store_only_once_its_state_exists(tmp_path):
    seen = []

    class Spy:
        def __getattr__(self, name):
            return lambda *a, **k: None

        def start_run(self, config):
            seen.append((Path(config["run_dir"]) / "state.json").is_file())
            return config["run_id"]

    config = make_config("smoke", overrides={**BASE, "store": "none"})
    run_coadaptation(
        config,
        backend_factory=lambda s: AnalyticBackend(s),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        run_dir=tmp_path / "r",
        recorder=Spy(),
    )
    assert seen == [True]
