"""How torch's OpenMP workers wait between parallel regions (coadapt_core.omp_wait_settings):
a brief spin with cores to spare, sleep at once when other processes want the cores, and
whatever the user set always wins."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from coadapt_core import SPIN_WHEN_IDLE, omp_wait_settings


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


@pytest.mark.parametrize("given", [{"OMP_WAIT_POLICY": "ACTIVE"}, {"GOMP_SPINCOUNT": "0"}, {"OMP_WAIT_POLICY": ""}])
def test_the_users_setting_wins(given):
    assert omp_wait_settings(given, 2, 1) == {}


def test_importing_the_core_before_torch_sets_a_policy_and_keeps_the_users():
    code = "import os, coadapt_core; print(os.environ.get('OMP_WAIT_POLICY'), os.environ.get('GOMP_SPINCOUNT'))"
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    chosen = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout.split()
    assert chosen in (["PASSIVE", "None"], ["None", SPIN_WHEN_IDLE])
    kept = subprocess.run([sys.executable, "-c", code], env={**env, "OMP_WAIT_POLICY": "ACTIVE"},
                          capture_output=True, text=True, check=True).stdout.split()
    assert kept == ["ACTIVE", "None"]
