"""Nothing read back from a run folder, a checkpoint or a shared store runs code.

Each test plants a payload through one of the nine ways the issue found (a pickle whose
`__reduce__` creates a marker file when it is unpickled; a store row that points elsewhere)
and checks, with the `coadapt` command a user would type, that the marker never appears and
the command fails with one line and exit code 2 (or ignores the row).
"""

from __future__ import annotations

import io
import json
import pickle
import sqlite3
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from coadapt_core.cli import main
from coadapt_core.learning.trainer import CHECKPOINT_FORMAT


class Payload:
    """Unpickling this creates `marker` (builtins.open in write mode): proof that code ran."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _payload_works(marker: Path) -> None:
    """The payload is live: a plain pickle.loads of it does create the marker."""
    pickle.loads(pickle.dumps(Payload(marker))).close()
    assert marker.exists()
    marker.unlink()


def plant_checkpoint(path: Path, marker: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"format": CHECKPOINT_FORMAT, "robot": "kuafu", "payload": Payload(marker)}, path)
    return path


def one_line_exit_2(capsys, argv: list[str], *, after_progress: bool = False) -> str:
    """Exit 2 and one error line; with `after_progress`, progress lines the command printed
    before it failed (a resumed run that had started) may precede that last line."""
    code = main(argv)
    captured = capsys.readouterr()
    text = (captured.err + captured.out).strip()
    assert code == 2, (code, text)
    assert "Traceback" not in text
    lines = [line for line in captured.err.strip().splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error")]
    assert len(errors) == 1 and lines[-1] == errors[0], captured.err
    assert after_progress or len(lines) == 1, captured.err
    return errors[0]


def test_the_payload_is_live(tmp_path):
    _payload_works(tmp_path / "marker")


# -- 1, 2: pickles planted in a run folder (run --resume) -------------------------------------
def test_planted_state_pickle_is_never_read(tmp_path, capsys):
    run = tmp_path / "runs" / "r1"
    run.mkdir(parents=True)
    marker = tmp_path / "ran-state"
    (run / "state.pkl").write_bytes(pickle.dumps(Payload(marker)))
    line = one_line_exit_2(capsys, ["run", "--resume", str(run)])
    assert "state.pkl" in line and not marker.exists()


def test_planted_state_json_cannot_name_a_class(tmp_path, capsys):
    """JSON can only name a registered dataclass; `os:system` or a plugin's arbitrary class is "
    "refused."""
    run = tmp_path / "r2"
    run.mkdir()
    state = {
        "format": "coadapt-loop-state-1",
        "run_id": "r2",
        "config": {},
        "summary": {
            "__dataclass__": "os:system",
            "fields": {"command": f"touch {tmp_path / 'ran'}"},
        },
    }
    (run / "state.json").write_text(json.dumps(state))
    line = one_line_exit_2(capsys, ["run", "--resume", str(run)])
    assert "state.json" in line and "damaged" in line and not (tmp_path / "ran").exists()


def test_planted_buffer_pickle_is_never_read(tmp_path, capsys):
    """The evaluation buffer is an .npz read with allow_pickle=False: an object array member
    (a pickle inside the zip) is refused."""
    from coadapt_core.coadapt.state import LoopState, save_state

    run = tmp_path / "r3"
    run.mkdir()
    save_state(run, LoopState(run_id="r3", config={}, buffer={"x": np.zeros(3)}, buffer_serial=0))
    assert (run / "buffer-0.npz").is_file()
    marker = tmp_path / "ran-buffer"
    buf = io.BytesIO()
    np.save(buf, np.array([Payload(marker)], dtype=object), allow_pickle=True)
    with zipfile.ZipFile(run / "buffer-0.npz", "w") as z:
        z.writestr("__tree__.npy", buf.getvalue())
    line = one_line_exit_2(capsys, ["run", "--resume", str(run)])
    assert "buffer-0.npz" in line and not marker.exists()


# -- 3-6: checkpoints given on the command line ----------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ["eval", "--agents", "1", "--seconds", "0.1", "--checkpoint", "{ckpt}"],
        ["run", "--preset", "smoke", "--store", "none", "--out", "{out}", "--checkpoint", "{ckpt}"],
        ["train", "--steps", "64", "--out", "{out}", "--init-from", "{ckpt}"],
        [
            "landscape",
            "--grid",
            "2",
            "--agents",
            "1",
            "--steps",
            "2",
            "--store",
            "{out}/s.db",
            "--checkpoint",
            "{ckpt}",
        ],
    ],
    ids=["eval", "run", "train-init-from", "landscape"],
)
def test_planted_checkpoint_is_refused_without_running(tmp_path, capsys, argv):
    marker = tmp_path / "ran-checkpoint"
    ckpt = plant_checkpoint(tmp_path / "evil.pt", marker)
    (tmp_path / "out").mkdir()
    args = [a.format(ckpt=ckpt, out=tmp_path / "out") for a in argv]
    line = one_line_exit_2(capsys, args)
    assert "evil.pt" in line and not marker.exists()


# -- 7: a checkpoint planted in a run folder (run --resume) ----------------------------------
@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    """A finished real run at the smallest size (MuJoCo, no store)."""
    out = tmp_path_factory.mktemp("tiny")
    args = [
        "run",
        "--optimizer",
        "pso",
        "--sim",
        "mujoco",
        "--objective",
        "torque",
        "--preset",
        "smoke",
        "--outer-iterations",
        "1",
        "--population",
        "2",
        "--optimizer-iterations",
        "1",
        "--agents-per-design",
        "1",
        "--eval-steps",
        "4",
        "--train-steps",
        "50",
        "--checkpoint",
        "none",
        "--store",
        "none",
        "--out",
        str(out),
        "--json",
    ]
    assert main(args) == 0
    (run,) = [p for p in out.iterdir() if (p / "state.json").is_file()]
    return run


def test_planted_backend_checkpoint_in_a_run_folder_is_refused(tiny_run, tmp_path, capsys):
    import shutil

    run = tmp_path / tiny_run.name
    shutil.copytree(tiny_run, run)
    state = json.loads((run / "state.json").read_text())
    assert (
        state["backend_checkpoint"] == "checkpoints/backend-outer0.pt"
    )  # relative to the run folder
    state["phase"] = "final"  # resuming must load the backend checkpoint again
    (run / "state.json").write_text(json.dumps(state))
    marker = tmp_path / "ran-backend"
    plant_checkpoint(run / "checkpoints" / "backend-outer0.pt", marker)
    capsys.readouterr()
    line = one_line_exit_2(capsys, ["run", "--resume", str(run)], after_progress=True)
    assert "backend-outer0.pt" in line and not marker.exists()


def test_state_path_leaving_the_run_folder_is_refused(tiny_run, tmp_path, capsys):
    import shutil

    run = tmp_path / tiny_run.name
    shutil.copytree(tiny_run, run)
    marker = tmp_path / "ran-outside"
    plant_checkpoint(tmp_path / "outside.pt", marker)
    state = json.loads((run / "state.json").read_text())
    state["phase"], state["backend_checkpoint"] = "final", "../outside.pt"
    (run / "state.json").write_text(json.dumps(state))
    line = one_line_exit_2(capsys, ["run", "--resume", str(run)])
    assert "state.json" in line and not marker.exists()


# -- 8: a store row pointing at a planted checkpoint (report's sim-to-sim column) -------------
def test_store_checkpoint_rows_outside_the_run_folder_are_ignored(tmp_path, capsys):
    from coadapt_core.results import SqliteRecorder
    from coadapt_core.results.rows import checkpoint_of

    marker = tmp_path / "ran-report"
    evil = plant_checkpoint(tmp_path / "elsewhere" / "evil.pt", marker)
    rec = SqliteRecorder(tmp_path / "s.db")
    run_dir = tmp_path / "runs" / "r8"
    run_dir.mkdir(parents=True)
    rec.store.create_run(
        {
            "method": "ours",
            "objective": "torque",
            "terrain": "flat",
            "seed": 0,
            "preset": "smoke",
            "sim": "mujoco",
            "robot": "kuafu",
            "optimizer": "pso",
        },
        run_id="r8",
        run_dir=str(run_dir),
    )
    rec.record_evaluations(
        "r8",
        outer=0,
        inner=0,
        designs=[[1.0, 1.0]],
        costs=[{"torque": 1.0}],
        kind="real",
        interactions=10,
        seconds=0.1,
    )
    rec.store.record_checkpoint("r8", outer=0, path=str(evil))
    rec.store.finish_run(
        "r8",
        {
            "run_id": "r8",
            "best_design": [1.0, 1.0],
            "best_cost": 1.0,
            "nominal_cost": 1.1,
            "improvement": 0.1,
        },
    )
    run = rec.store.get_run("r8")
    assert checkpoint_of(run, str(evil)) is None
    assert checkpoint_of(run, "../../elsewhere/evil.pt") is None
    assert checkpoint_of(run, "checkpoints/x.pt") == (run_dir / "checkpoints" / "x.pt").resolve()
    assert main(["report", "--store", str(tmp_path / "s.db"), "--out", str(tmp_path / "rep")]) == 0
    table = (tmp_path / "rep" / "table6.csv").read_text()
    assert "not inside the run's folder" in table and not marker.exists()
    # a payload inside the run folder is read with weights_only=True and refused: that run's
    # column says so, the report is still written
    inner = plant_checkpoint(run_dir / "checkpoints" / "backend-outer1.pt", marker)
    rec.store.record_checkpoint("r8", outer=1, path=str(inner))
    capsys.readouterr()
    assert main(["report", "--store", str(tmp_path / "s.db"), "--out", str(tmp_path / "rep2")]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and not marker.exists()
    assert "holds objects other than tensors" in (tmp_path / "rep2" / "table6.csv").read_text()


# -- 9: a run row with a path-like id (grid resume) ------------------------------------------
def test_grid_never_resumes_a_run_id_that_leaves_the_runs_folder(tmp_path):
    from coadapt_core.experiments.grid_plan import GridSpec, plan_grid
    from coadapt_core.results import ResultsStore

    store = ResultsStore(tmp_path / "g.db")
    spec = GridSpec(
        methods=["ours"], objectives=["torque"], terrains=["flat"], seeds=[0], preset="smoke"
    )
    (cell,) = spec.cells()
    evil = tmp_path / "evilrun"
    evil.mkdir()
    marker = tmp_path / "ran-grid"
    (evil / "state.pkl").write_bytes(pickle.dumps(Payload(marker)))
    (evil / "state.json").write_text("{}")
    for run_id, run_dir in (("../evilrun", tmp_path / "runs" / ".." / "evilrun"), ("okid", evil)):
        with sqlite3.connect(tmp_path / "g.db") as db:  # rows as a hostile store user writes them
            db.execute(
                "INSERT INTO runs (id, cell, method, objectives, status, run_dir, created_at, "
                "updated_at) "
                "VALUES (?, ?, 'ours', 'torque', 'running', ?, 0, 0)",
                (run_id, cell.key, str(run_dir)),
            )
        tasks, _ = plan_grid(store, spec, out_dir=str(tmp_path / "runs"))
        assert (
            tasks[0].resume is None and "--resume" not in tasks[0].argv
        )  # started afresh inside runs/
        with sqlite3.connect(tmp_path / "g.db") as db:
            db.execute("DELETE FROM runs")
    assert not marker.exists()


def test_shipped_policies_load_as_weights_only():
    """The policies the robot ships are read with weights_only=True (read_checkpoint) and hold
    tensors and plain values only: a trainer built from one acts exactly as the file says."""
    from coadapt_core.learning.checkpoints import read_checkpoint

    folder = Path(__file__).resolve().parents[2] / "plugins" / "robots" / "kuafu" / "policies"
    shipped = sorted(folder.glob("*.pt"))
    assert len(shipped) >= 2
    for path in shipped:
        state = read_checkpoint(path)
        assert state["robot"] == "kuafu"
        actor = state["ppo"]["actor"]
        assert actor and all(
            isinstance(t, torch.Tensor) and torch.isfinite(t).all() for t in actor.values()
        )
