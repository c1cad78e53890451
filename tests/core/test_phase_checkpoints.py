"""Resume inside a training phase (issue 40): `coadapt run` saves the policy and the loop
state every `checkpoint_interactions` interactions of a training phase (coadapt/phase.py),
and a run cut off inside the phase continues from its last chunk: no interaction is trained
twice and the run ends as an uninterrupted one. The loop's logic with the analytic backend;
a real MuJoCo run killed (SIGKILL) inside its phase in the slow test."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
import yaml
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.loop import seed_at
from coadapt_core.coadapt.phase import PARTIAL_CHECKPOINT
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.results.recorders import read_evaluations
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

BASE = dict(
    population=6,
    optimizer_iterations=2,
    outer_iterations=2,
    agents_per_design=4,
    eval_steps=10,
    train_steps=1000,
    retrain_steps=500,
    checkpoint_interactions=300,
    seed=5,
    store="none",
)


class Counting(AnalyticBackend):
    """Records every training call (steps, seed) in `calls`; raises as a kill would on the
    `kill_at`-th call of this process, before training."""

    def __init__(self, seed, calls, kill_at=None):
        super().__init__(seed)
        self.calls, self.kill_at = calls, kill_at

    def train(self, designs, steps, *, seed=0):
        if self.kill_at is not None and len(self.calls) + 1 == self.kill_at:
            raise KeyboardInterrupt("killed inside the training phase")
        self.calls.append((int(steps), int(seed)))
        return super().train(designs, steps, seed=seed)


def _run(folder, calls, kill_at=None, resume=False):
    kwargs = dict(
        backend_factory=lambda s: Counting(s, calls, kill_at),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
    )
    if resume:
        return run_coadaptation(resume=folder, **kwargs)
    return run_coadaptation(make_config("smoke", overrides=dict(BASE)), run_dir=folder, **kwargs)


def test_a_phase_cut_inside_continues_from_its_last_chunk(tmp_path):
    full_calls: list = []
    full = _run(tmp_path / "full", full_calls).summary
    seed = BASE["seed"]
    phase0 = [
        (300, seed_at(seed, 1, 0)),
        (300, seed_at(seed, 1, 0, 1)),
        (300, seed_at(seed, 1, 0, 2)),
        (100, seed_at(seed, 1, 0, 3)),
    ]
    assert (
        full_calls[:4] == phase0
    )  # 1000 interactions in chunks of 300; chunk 0 has the phase's own seed
    assert full_calls[4:] == [
        (300, seed_at(seed, 1, 1)),
        (200, seed_at(seed, 1, 1, 1)),
    ]  # the retraining
    assert full["train_interactions"] == 1500

    cut_calls: list = []
    with pytest.raises(KeyboardInterrupt, match="killed inside"):
        _run(tmp_path / "cut", cut_calls, kill_at=3)  # after two chunks of the first phase
    state = json.loads((tmp_path / "cut" / "state.json").read_text())
    assert state["phase"] == "train" and state["backend_checkpoint"] == PARTIAL_CHECKPOINT
    assert {k: state["train_progress"][k] for k in ("outer", "done", "chunk")} == {
        "outer": 0,
        "done": 600,
        "chunk": 2,
    }
    assert (tmp_path / "cut" / PARTIAL_CHECKPOINT).is_file()

    resumed_calls: list = []
    resumed = _run(tmp_path / "cut", resumed_calls, resume=True).summary
    assert cut_calls + resumed_calls == full_calls  # every chunk trained once, none repeated
    assert sum(steps for steps, _ in cut_calls + resumed_calls) == 1500
    assert resumed["train_interactions"] == full["train_interactions"] == 1500
    assert (
        resumed["best_design"] == full["best_design"]
        and resumed["interactions"] == full["interactions"]
    )
    assert resumed["spaces"] == full["spaces"]  # the range of the cut phase recorded once


def test_no_mid_phase_checkpoint_when_the_phase_fits_in_one_chunk(tmp_path):
    calls: list = []
    config = make_config(
        "smoke", overrides={**BASE, "checkpoint_interactions": 0, "outer_iterations": 1}
    )
    run_coadaptation(
        config,
        backend_factory=lambda s: Counting(s, calls),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        run_dir=tmp_path / "r",
    )
    assert calls == [(1000, seed_at(BASE["seed"], 1, 0))]
    assert not (tmp_path / "r" / PARTIAL_CHECKPOINT).exists()


#: a real `coadapt run` whose one training phase is 20 PPO iterations of 48 interactions
#: (2 designs x 1 agent x 24 steps), a checkpoint every 2 iterations: 10 chunks
REAL = [
    "run",
    "--preset",
    "smoke",
    "--population",
    "2",
    "--outer-iterations",
    "1",
    "--optimizer-iterations",
    "1",
    "--agents-per-design",
    "1",
    "--eval-steps",
    "4",
    "--train-steps",
    "960",
    "--checkpoint-interactions",
    "96",
    "--store",
    "none",
    "--no-video",
    "--json",
    "--threads",
    "1",
]


def _in_process(args):
    from coadapt_core import threads
    from coadapt_core.cli import main

    before = torch.get_num_threads()
    try:
        assert main(args) == 0
    finally:
        threads._budget = None
        torch.set_num_threads(before)


def _folder(out: Path) -> Path:
    (folder,) = [p for p in out.iterdir() if (p / "state.json").is_file()]
    return folder


def _weights(folder: Path) -> dict:
    state = torch.load(
        folder / "checkpoints" / "backend-outer0.pt", map_location="cpu", weights_only=True
    )
    return state["ppo"]["actor"] if "ppo" in state else state


@pytest.mark.slow
def test_a_real_run_killed_inside_its_training_phase_resumes_where_it_was(tmp_path):
    """SIGKILL a real MuJoCo run once its first mid-phase checkpoint is written; `coadapt run
    --resume` trains only the rest of the phase and ends as the uninterrupted run: the same
    interactions, best design and final policy weights."""
    cut = tmp_path / "cut"
    argv = [*REAL, "--out", str(cut)]
    code = f"import sys; from coadapt_core.cli import main; sys.exit(main({argv!r}))"
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    deadline, progress = time.monotonic() + 300, None
    try:
        while progress is None and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
            states = list(cut.glob("*/state.json")) if cut.is_dir() else []
            if states:
                try:
                    progress = json.loads(states[0].read_text()).get("train_progress")
                except (OSError, ValueError):  # being replaced: read it again
                    continue
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(30)
    assert progress is not None, proc.stderr.read().decode()[-2000:]
    folder = _folder(cut)
    killed_at = json.loads((folder / "state.json").read_text())["train_progress"]["done"]
    assert 96 <= killed_at < 960 and killed_at % 96 == 0  # inside the phase, at a chunk's end

    _in_process(["run", "--resume", str(folder), "--no-video", "--json", "--threads", "1"])
    _in_process([*REAL, "--out", str(tmp_path / "full")])
    full = _folder(tmp_path / "full")
    summaries = [json.loads((f / "summary.json").read_text()) for f in (folder, full)]
    phases = [
        [json.loads(line) for line in (f / "trainings.jsonl").read_text().splitlines()]
        for f in (folder, full)
    ]
    assert [p["steps"] for p in phases[0]] == [p["steps"] for p in phases[1]] == [960]
    assert (
        phases[0][0]["extra"]["resumed_at"] == killed_at
        and phases[1][0]["extra"]["resumed_at"] == 0
    )
    assert phases[0][0]["extra"]["chunks"] == phases[1][0]["extra"]["chunks"] == 10
    assert summaries[0]["interactions"] == summaries[1]["interactions"]
    assert summaries[0]["train_interactions"] == summaries[1]["train_interactions"] == 960
    assert summaries[0]["best_design"] == summaries[1]["best_design"]
    records = [[(r["design"], r["costs"]) for r in read_evaluations(f)] for f in (folder, full)]
    assert (
        records[0] == records[1] and len(records[0]) == 2
    )  # both designs of the real round, cost to the bit
    a, b = _weights(folder), _weights(full)
    assert a.keys() == b.keys() and all(
        torch.equal(a[k], b[k]) for k in a
    )  # the same policy, bit for bit
    assert yaml.safe_load((folder / "config.yaml").read_text())["checkpoint_interactions"] == 96
