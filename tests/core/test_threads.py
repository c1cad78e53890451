"""The thread budget (`coadapt_core.threads`): the CPUs a process may use (affinity mask and
cgroup CPU quota, v1 and v2), what `apply_threads` gives torch and the physics, and how a
local grid shares the cores among its cells."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
import torch

from coadapt_core import threads
from coadapt_core.errors import UserError


def _proc(tmp_path, text: str):
    path = tmp_path / "cgroup"
    path.write_text(text)
    return path


def _write(folder, name: str, text: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_text(text)


def test_cgroup_v2_quota_is_the_tightest_on_the_path(tmp_path):
    root = tmp_path / "sys"
    proc = _proc(tmp_path, "0::/slurm/job7/step0\n")
    assert threads.cgroup_cpu_limit(root, proc) is None  # no cpu.max anywhere: no limit
    _write(root, "cpu.max", "max 100000\n")
    assert threads.cgroup_cpu_limit(root, proc) is None  # "max": none
    _write(root / "slurm" / "job7", "cpu.max", "350000 100000\n")
    assert threads.cgroup_cpu_limit(root, proc) == 3.5
    _write(root / "slurm" / "job7" / "step0", "cpu.max", "150000 100000\n")
    assert threads.cgroup_cpu_limit(root, proc) == 1.5  # the child's is tighter
    _write(root / "slurm", "cpu.max", "100000 100000\n")
    assert threads.cgroup_cpu_limit(root, proc) == 1.0  # a parent's limit holds for its children


def test_cgroup_v1_quota_over_period(tmp_path):
    root = tmp_path / "sys"
    proc = _proc(tmp_path, "4:memory:/x\n3:cpu,cpuacct:/docker/abc\n")
    folder = root / "cpu,cpuacct" / "docker" / "abc"
    _write(folder, "cpu.cfs_quota_us", "-1\n")
    _write(folder, "cpu.cfs_period_us", "100000\n")
    assert threads.cgroup_cpu_limit(root, proc) is None  # -1: no quota
    _write(folder, "cpu.cfs_quota_us", "250000\n")
    assert threads.cgroup_cpu_limit(root, proc) == 2.5


def test_usable_cpus_is_the_affinity_capped_by_the_quota_rounded_up(tmp_path, monkeypatch):
    affinity = len(os.sched_getaffinity(0))
    root = tmp_path / "sys"
    monkeypatch.setattr(threads, "_own_cgroups", lambda proc_file="": [("", "/")])
    assert threads.usable_cpus(root) == affinity
    _write(root, "cpu.max", "50000 100000\n")  # half a CPU: still one thread
    assert threads.usable_cpus(root) == 1
    _write(root, "cpu.max", f"{100000 * affinity + 1} 100000\n")  # a hair over the cores: the cores
    assert threads.usable_cpus(root) == affinity


def _in_subprocess(code: str, env: dict[str, str] | None = None) -> str:
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
        env={**os.environ, **(env or {})},
    )
    return out.stdout.strip()


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs 2 CPUs to narrow the affinity")
def test_the_default_budget_follows_affinity_and_quota(tmp_path):
    """A process pinned to one core, or under a cgroup quota of one CPU (a fake cgroup tree
    named by $COADAPT_CGROUP_ROOT), gets a budget of 1 for torch and the physics (what
    `apply_threads()` then gives torch is checked in-process below; torch is not imported here)."""
    code = (
        "import os; {pre}from coadapt_core import threads; "
        "print(threads.usable_cpus(), threads.budget())"
    )
    assert _in_subprocess(code.format(pre="os.sched_setaffinity(0, {0}); ")) == "1 1"
    root = tmp_path / "sys"
    _write(root, "cpu.max", "100000 100000\n")
    for line in ("1:cpu:/", "1:cpu,cpuacct:/"):  # v1 trees read under the same root
        _write(root / line.split(":")[1], "cpu.cfs_quota_us", "-1\n")
        _write(root / line.split(":")[1], "cpu.cfs_period_us", "100000\n")
    assert _in_subprocess(code.format(pre=""), {threads.ENV_CGROUP_ROOT: str(root)}) == "1 1"
    full = len(os.sched_getaffinity(0))
    assert (
        _in_subprocess(code.format(pre=""), {threads.ENV_CGROUP_ROOT: str(tmp_path / "none")})
        == f"{full} {full}"
    )


def test_apply_threads_gives_torch_and_the_budget_n_and_refuses_nonsense():
    before = torch.get_num_threads()
    try:
        assert (
            threads.apply_threads(3) == 3 and threads.budget() == 3 and torch.get_num_threads() == 3
        )
        assert (
            threads.apply_threads() == threads.usable_cpus() == torch.get_num_threads()
        )  # the default
        for bad in (0, -1, 1.5, True, "2"):
            with pytest.raises(UserError, match="threads must be a whole number >= 1"):
                threads.apply_threads(bad)
    finally:
        threads._budget = None
        torch.set_num_threads(before)


@pytest.mark.parametrize(
    ("cores", "cells", "workers", "per_cell", "expected"),
    [
        (2, 2, None, None, (2, 1)),  # 2 cells at once on 2 cores: 1 thread each
        (2, 1, None, None, (1, 2)),  # one cell: both cores
        (16, 3, None, None, (3, 5)),  # 3 cells: 5 threads each (15 <= 16)
        (2, 4, None, 2, (1, 2)),  # --threads 2 on 2 cores: one cell at a time
        (16, 8, 2, None, (2, 8)),  # --workers 2: the cores divided between them
    ],
)
def test_a_local_grid_shares_the_cores(cores, cells, workers, per_cell, expected):
    got = threads.share_cores(cores, cells, workers, per_cell)
    assert got == expected and min(got[0], cells) * got[1] <= cores


def test_a_local_grid_refuses_more_threads_than_cores():
    with pytest.raises(UserError, match="--workers 2 x --threads 2 = 4 threads on 2 CPUs"):
        threads.share_cores(2, 4, 2, 2)
    with pytest.raises(UserError, match="--threads 3 per cell is more than the 2 CPUs"):
        threads.share_cores(2, 1, None, 3)


#: a real `coadapt run` of one tiny training phase (one PPO iteration) and one real round
TINY_RUN = [
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
    "2",
    "--train-steps",
    "10",
    "--store",
    "none",
    "--no-video",
    "--json",
]


def _recorded(out) -> tuple[int, list[dict]]:
    """(config.yaml's threads, each training phase's recorded threads) of the run in `out`."""
    import json

    import yaml

    (folder,) = [p for p in out.iterdir() if (p / "config.yaml").is_file()]
    config = yaml.safe_load((folder / "config.yaml").read_text())
    phases = [
        json.loads(line)["extra"] for line in (folder / "trainings.jsonl").read_text().splitlines()
    ]
    return config["threads"], [
        {k: p[k] for k in ("torch_threads", "physics_threads")} for p in phases
    ]


@pytest.mark.slow
def test_run_threads_2_gives_the_physics_and_torch_2(tmp_path):
    """`coadapt run --threads 2`: config.yaml says 2 and the training phase ran on 2 torch
    threads (torch's own count during the update) and a MuJoCo pool of 2 (the batch's nthread),
    although the shipped starting policy records torch_threads 1."""
    from coadapt_core.cli import main

    before = torch.get_num_threads()
    try:
        assert main([*TINY_RUN, "--threads", "2", "--out", str(tmp_path)]) == 0
    finally:
        threads._budget = None
        torch.set_num_threads(before)
    assert _recorded(tmp_path) == (2, [{"torch_threads": 2, "physics_threads": 2}])


@pytest.mark.slow
@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs 2 CPUs to narrow the affinity")
def test_run_default_threads_follow_the_affinity_not_the_checkpoint(tmp_path):
    """Without --threads a run pinned to one core uses 1 thread for torch and the physics,
    though its starting policy records torch_threads 7."""
    from pathlib import Path

    shipped = (
        Path(__file__).resolve().parents[2]
        / "plugins"
        / "robots"
        / "kuafu"
        / "policies"
        / "flat.pt"
    )
    state = torch.load(shipped, map_location="cpu", weights_only=True)
    state["train_config"]["torch_threads"] = 7
    torch.save(state, tmp_path / "seven.pt")
    out = tmp_path / "runs"
    args = [*TINY_RUN, "--checkpoint", str(tmp_path / "seven.pt"), "--out", str(out)]
    code = (
        "import os, sys; os.sched_setaffinity(0, {0}); "
        f"from coadapt_core.cli import main; sys.exit(main({args!r}))"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, timeout=600)
    assert _recorded(out) == (1, [{"torch_threads": 1, "physics_threads": 1}])
