"""How torch's OpenMP workers wait between parallel regions (coadapt_core.launch): a brief
spin with cores to spare, sleep at once when other processes want the cores, whatever the
user set always wins, and only the command's entry point chooses: importing the library
reads no /proc file and changes no environment variable."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from coadapt_core.launch import SPIN_WHEN_IDLE, omp_wait_settings


@pytest.mark.parametrize(
    ("cores", "running", "expected"),
    [
        (2, 1, {"GOMP_SPINCOUNT": SPIN_WHEN_IDLE}),  # only this process: spin briefly
        (2, 2, {"OMP_WAIT_POLICY": "PASSIVE"}),  # one more process on two cores: sleep
        (16, 8, {"GOMP_SPINCOUNT": SPIN_WHEN_IDLE}),  # 7 others on 16 cores
        (16, 9, {"OMP_WAIT_POLICY": "PASSIVE"}),  # 8 others: half the cores busy
        (2, None, {"OMP_WAIT_POLICY": "PASSIVE"}),  # unknown (no /proc): the safe choice
    ],
)
def test_spin_only_with_cores_to_spare(cores, running, expected):
    assert omp_wait_settings({}, cores, running) == expected


@pytest.mark.parametrize(
    "given", [{"OMP_WAIT_POLICY": "ACTIVE"}, {"GOMP_SPINCOUNT": "0"}, {"OMP_WAIT_POLICY": ""}]
)
def test_the_users_setting_wins(given):
    assert omp_wait_settings(given, 2, 1) == {}


#: a fresh interpreter that records every file it opens and the environment before and after
#: importing `module`, and prints them as JSON
_PROBE = """
import builtins, io, json, os, sys
opened = []
real_open, real_io_open = builtins.open, io.open
def spy(file, *args, **kwargs):
    opened.append(str(file))
    return real_open(file, *args, **kwargs)
builtins.open = io.open = spy
listed = []
real_listdir = os.listdir
os.listdir = lambda path=".": (listed.append(str(path)), real_listdir(path))[1]
before = dict(os.environ)
import {module}
{call}
after = dict(os.environ)
builtins.open, io.open, os.listdir = real_open, real_io_open, real_listdir
facts = {{"opened": opened, "listed": listed, "before": before, "after": after}}
print(json.dumps({{**facts, "torch": "torch" in sys.modules}}))
"""


def _probe(module: str, call: str = "", env: dict | None = None) -> dict:
    base = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE.format(module=module, call=call)],
        env={**base, **(env or {})},
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


@pytest.mark.parametrize("module", ["coadapt_core", "coadapt_core.learning"])
def test_importing_the_library_reads_no_proc_and_keeps_the_environment(module):
    seen = _probe(module)
    assert [p for p in seen["opened"] + seen["listed"] if p.startswith("/proc")] == []
    assert seen["after"] == seen["before"]
    assert "OMP_WAIT_POLICY" not in seen["after"] and "GOMP_SPINCOUNT" not in seen["after"]


def test_the_probe_sees_proc_reads_and_environment_changes():
    """The probe above can fail: the entry point's choice, run the same way, is seen."""
    seen = _probe("coadapt_core.launch", "coadapt_core.launch.apply_omp_wait_policy()")
    assert "/proc/stat" in seen["opened"] and "/proc/self/task" in seen["listed"]
    chosen = {k: v for k, v in seen["after"].items() if seen["before"].get(k) != v}
    assert chosen in ({"OMP_WAIT_POLICY": "PASSIVE"}, {"GOMP_SPINCOUNT": SPIN_WHEN_IDLE})


def test_the_entry_point_keeps_the_users_setting_and_does_nothing_after_torch():
    kept = _probe(
        "coadapt_core.launch",
        "coadapt_core.launch.apply_omp_wait_policy()",
        env={"OMP_WAIT_POLICY": "ACTIVE"},
    )
    assert kept["after"] == kept["before"]
    late = _probe("torch, coadapt_core.launch", "coadapt_core.launch.apply_omp_wait_policy()")
    assert late["after"] == late["before"] and not [
        p for p in late["opened"] if p.startswith("/proc/stat")
    ]


@pytest.mark.parametrize(
    ("argv", "chooses"),
    [(["run", "--preset", "smok"], True), (["--version"], False), (["plugins", "--help"], False)],
)
def test_the_command_chooses_before_torch_is_loaded(argv, chooses):
    """`python -m coadapt_core` (as the console script) sets the policy before torch loads
    libgomp, for a command that simulates (a refused `coadapt run` too); the others, which
    load no torch, leave it (and /proc) alone."""
    code = (
        f"import sys, runpy; sys.argv = ['coadapt', *{argv!r}]\n"
        "import os\n"
        "try:\n    runpy.run_module('coadapt_core', run_name='__main__')\n"
        "except SystemExit:\n    pass\n"
        "print(os.environ.get('OMP_WAIT_POLICY'), os.environ.get('GOMP_SPINCOUNT'))"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    if chooses:
        assert out[-2:] in (["PASSIVE", "None"], ["None", SPIN_WHEN_IDLE])
    else:
        assert out[-2:] == ["None", "None"]
