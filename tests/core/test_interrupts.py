"""Ctrl-C on `coadapt run`: at any point it prints the run id and the exact command that
continues the run, leaves no partial file, and the store does not call the run finished;
the printed command finishes it with the design an uninterrupted run finds. Driven as a
user would, through a process of its own and SIGINT; the learner is the analytic fake
(`tests/fakes/fake_learner_cli.py`), the video is drawn for real."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from coadapt_core.results import ResultsStore
from tests.fakes.analytic import AnalyticBackend

ROOT = Path(__file__).resolve().parents[2]
HARNESS = [sys.executable, "-m", "tests.fakes.fake_learner_cli"]
ARGS = ["run", "--preset", "smoke", "--seed", "3"]


def cli(args: list[str], cwd: Path, **env: str) -> subprocess.Popen:
    environment = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    return subprocess.Popen(
        [*HARNESS, *args],
        cwd=cwd,
        env=environment,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def interrupt_at(
    proc: subprocess.Popen, marker: str, count: int = 1, wait: float = 0.0
) -> tuple[str, str]:
    """Read stderr until `marker` was seen `count` times, then send SIGINT; (stdout, stderr)."""
    seen, lines = 0, []
    assert proc.stderr is not None
    deadline = time.monotonic() + 120
    while seen < count:
        line = proc.stderr.readline()
        if not line:
            out, err = proc.communicate()
            raise AssertionError(f"ended before '{marker}' x{count}:\n{''.join(lines)}{err}")
        lines.append(line)
        seen += line.strip() == f"fake: {marker}"
        assert time.monotonic() < deadline
    time.sleep(wait)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    return out, "".join(lines) + err


#: where Ctrl-C is pressed: (the fake's marker, how many of them, seconds after it)
POINTS = {
    "training": ("training", 1, 0.2),
    "real round": ("real round", 2, 0.2),  # the second real round: state, buffer and rows exist
    "video": ("drawing", 1, 1.0),
}


@pytest.mark.slow
def test_ctrl_c_prints_the_resume_command_and_the_resume_finishes_the_run(
    tmp_path, monkeypatch, capsys
):
    """The three points run side by side (each in its own folder) to keep the test short."""
    from concurrent.futures import ThreadPoolExecutor

    folders = {where: tmp_path / where.replace(" ", "-") for where in POINTS}
    procs = {}
    for where, folder in folders.items():
        folder.mkdir()
        procs[where] = cli(
            [*ARGS, "--store", "s.db"], folder, FAKE_DELAY="1.5", FAKE_VIDEO_SECONDS="40"
        )
    pool = ThreadPoolExecutor(len(POINTS))  # each process is watched from the start
    futures = {where: pool.submit(interrupt_at, procs[where], *POINTS[where]) for where in POINTS}
    # the uninterrupted run, meanwhile, in this process (same fake learner)
    import coadapt_core.coadapt.setup as loop_setup
    from coadapt_core.cli import main

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )
    assert (
        main(
            [
                *ARGS,
                "--out",
                str(tmp_path / "ref"),
                "--store",
                str(tmp_path / "ref.db"),
                "--no-video",
                "--json",
            ]
        )
        == 0
    )
    expected = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    errs = {where: future.result()[1] for where, future in futures.items()}
    pool.shutdown()

    commands = {}
    for where, err in errs.items():
        folder = folders[where]
        assert procs[where].returncode == 130, err
        assert "Traceback" not in err
        (line,) = [x for x in err.splitlines() if x.startswith("interrupted:")]
        run_id = re.search(r"^run (\S+): ", err, re.MULTILINE).group(1)  # said when the run starts
        command = line.split("continue it with: ", 1)[1]
        assert command == f"coadapt run --resume {run_id}", where  # ./runs is the default --out
        assert run_id in line
        run_dir = folder / "runs" / run_id
        # every file whole: nothing empty, no temporary or partial file left behind
        files = [p for p in run_dir.rglob("*") if p.is_file()]
        assert files and all(p.stat().st_size > 0 for p in files), [
            p.name for p in files if p.stat().st_size == 0
        ]
        assert not [p.name for p in files if p.name.endswith(".tmp") or ".partial" in p.name], where
        with ResultsStore(folder / "s.db") as store:
            assert store.get_run(run_id)["status"] == "interrupted", where
        if where == "video":
            assert json.loads((run_dir / "state.json").read_text())["phase"] == "done"
            assert not (run_dir / "best_vs_nominal.gif").exists()
        commands[where] = (run_id, run_dir, command)

    # the printed command, as printed, finishes each run with the uninterrupted run's answer
    resumed = {
        where: cli([*shlex.split(command)[1:], "--json"], folders[where], FAKE_VIDEO_SECONDS="1")
        for where, (_, _, command) in commands.items()
    }
    for where, proc in resumed.items():
        run_id, run_dir, _ = commands[where]
        out, err = proc.communicate(timeout=180)
        assert proc.returncode == 0, err
        result = json.loads(out.strip().splitlines()[-1])
        assert result["run_id"] == run_id
        assert (result["best_design"], result["best_cost"]) == (
            expected["best_design"],
            expected["best_cost"],
        ), where
        with ResultsStore(folders[where] / "s.db") as store:
            assert store.get_run(run_id)["status"] == "finished"
        assert (run_dir / "best_vs_nominal.gif").stat().st_size > 0


@pytest.mark.slow
def test_ctrl_c_on_a_grid_stops_its_cells_and_the_same_command_resumes_them(
    tmp_path, monkeypatch, capsys
):
    """Ctrl-C while both cells train: each cell's run is stopped and marked interrupted with
    its state kept; the printed command (the same grid) resumes both and finishes them."""
    import threading

    import coadapt_core.experiments.grid_exec as grid_module  # where cells are started
    from coadapt_core.cli import main

    monkeypatch.setattr(
        grid_module,
        "ENTRY",
        ("-c", "import sys; from tests.fakes.fake_learner_cli import main; sys.exit(main())"),
    )
    monkeypatch.setenv("PYTHONPATH", str(ROOT))
    monkeypatch.setenv("FAKE_DELAY", "3")
    monkeypatch.setenv("FAKE_VIDEO_SECONDS", "0.2")
    monkeypatch.chdir(tmp_path)
    args = [
        "grid",
        "--methods",
        "ours",
        "--objectives",
        "torque",
        "--terrains",
        "flat",
        "--seeds",
        "0,1",
        "--preset",
        "smoke",
        "--workers",
        "2",
        "--store",
        "g.db",
        "--out",
        "runs",
    ]

    def press_ctrl_c_once_both_started() -> None:
        deadline = time.monotonic() + 120
        while (
            len(list((tmp_path / "runs").glob("*/state.json"))) < 2 and time.monotonic() < deadline
        ):
            time.sleep(0.2)
        time.sleep(0.5)
        os.kill(os.getpid(), signal.SIGINT)

    presser = threading.Thread(target=press_ctrl_c_once_both_started, daemon=True)
    presser.start()
    code = main(args)
    presser.join()
    err = capsys.readouterr().err
    assert code == 130, err
    (line,) = [x for x in err.splitlines() if x.startswith("interrupted: grid")]
    assert line.endswith("continue it with: coadapt " + shlex.join(args))
    with ResultsStore(tmp_path / "g.db") as store:
        runs = store.list_runs()
        assert len(runs) == 2 and {r["status"] for r in runs} == {"interrupted"}
    assert all((tmp_path / "runs" / r["id"] / "state.json").is_file() for r in runs)

    monkeypatch.setenv("FAKE_DELAY", "0")
    assert main([*args, "--json"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert len(report["resumed"]) == 2 and len(report["finished"]) == 2
    with ResultsStore(tmp_path / "g.db") as store:
        assert {r["id"]: r["status"] for r in store.list_runs()} == {
            r["id"]: "finished" for r in runs
        }
