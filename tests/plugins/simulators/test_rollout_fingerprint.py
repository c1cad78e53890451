"""A fixed-seed rollout of each built-in backend repeats the numbers recorded before the
physics room was restructured (torch actuation and parameters, spawn and random streams in
the `Simulator` base): the same design, seed, randomization, terrain and targets give the
same state, parameters and, after `reseed`, the same redraw.

A case may hold more than one recorded variant: MuJoCo's height-field contacts are not the
same to the bit on every CPU. The random-terrain case has two, each repeated to the bit on
its machine: an AMD EPYC (AVX-512) and an Intel Xeon (AVX-512 with AMX) differ by up to
4e-4 m in base position after six steps (their parameters, draws and the step after
`reseed` agree to the bit; the slope and PyBullet cases are one variant on both). A rollout
passes when it matches one variant of its case to 1e-6. The PyBullet case was recorded
anew in issue 49, a deliberate physics change (the armature correction over the floating
base's velocities too: joint angles up to 0.009 rad apart after the six steps, parameters
and draws unchanged), and again in issue 58 (MuJoCo's implicit joint damping carried as h d
of armature: joint angles up to 0.003 rad and the base 0.15 mm apart, parameters and draws
unchanged), and once more in issue 58 (the armature correction predicts the base's rows as
Bullet's, the folded inertia in them: joint angles up to 0.0006 rad and the base 0.05 mm
apart, parameters and draws unchanged; `--write pybullet`, the MuJoCo cases kept).

    # this machine's variant, if new
    python tests/plugins/simulators/test_rollout_fingerprint.py --add
    # start again (a deliberate physics change): every case, or the named ones only (the
    # others keep every machine's variant)
    python tests/plugins/simulators/test_rollout_fingerprint.py --write
    python tests/plugins/simulators/test_rollout_fingerprint.py --write pybullet
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from coadapt_plugins.robots.kuafu.robot import Kuafu

from coadapt_core.physics.randomization import RandomizationConfig

RECORD = Path(__file__).parent / "data" / "rollout_fingerprint.json"
STATE = (
    "base_pos",
    "base_quat",
    "base_lin_vel",
    "joint_pos",
    "joint_vel",
    "joint_torque",
    "foot_pos",
    "foot_contact_force",
    "terrain_height",
)
PARAMS = (
    "friction",
    "restitution",
    "com_shift",
    "pd_factor",
    "motor_strength",
    "delay",
    "contact_timeconst",
    "joint_damping",
    "armature",
)
#: (case, backend, environments, terrain, randomization)
CASES = {
    "mujoco": ("mujoco", 6, "random", "table2"),
    "mujoco_slope": ("mujoco", 4, "slope", "engine"),
    "pybullet": ("pybullet", 2, "random", "table2"),
}


def rollout(case: str) -> dict[str, list]:
    """Reset, six policy steps of a fixed target sequence (one environment reset half-way),
    then `reseed(11)`, reset and one step."""
    backend, n, terrain, preset = CASES[case]
    if backend == "pybullet":
        from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator as cls
    else:
        from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator as cls
    robot = Kuafu()
    designs = robot.design_space(False).sample(n, rng=1)
    designs[0] = robot.nominal_design(False)
    out: dict[str, list] = {}
    with cls(
        robot, designs, terrain=terrain, randomization=RandomizationConfig.preset(preset), seed=7
    ) as sim:
        sim.reset()
        default = sim.default_joint_pos
        for k in range(6):
            state = sim.step(default + 0.2 * torch.sin(torch.arange(sim.num_joints) + k).float())
            if k == 3:
                sim.reset(torch.tensor([1]))
        sim.reseed(11)
        sim.reset()
        again = sim.step(default)
        params = sim.env_params
        for name in STATE:
            out[name] = getattr(state, name).double().cpu().numpy().tolist()
            out[f"after_reseed.{name}"] = getattr(again, name).double().cpu().numpy().tolist()
        for name in PARAMS:
            out[f"params.{name}"] = getattr(params, name).double().cpu().numpy().tolist()
    return out


def matches(now: dict[str, list], recorded: dict[str, list]) -> str | None:
    """None when `now` repeats `recorded` to 1e-6, else the first key that does not."""
    if set(now) != set(recorded):
        return f"keys {sorted(set(now) ^ set(recorded))}"
    for key, values in recorded.items():
        a, b = np.asarray(now[key]), np.asarray(values)
        if a.shape != b.shape or not np.allclose(a, b, rtol=1e-6, atol=1e-6):
            return key
    return None


def variants(case: str) -> list[dict[str, list]]:
    return json.loads(RECORD.read_text())[case]


def deviations(now: dict[str, list], recorded: dict[str, list]) -> str:
    """For a failure message: each key `matches` would refuse, with its largest difference
    (so another machine's variant can be told from a physics change)."""
    far = []
    for key, values in recorded.items():
        if matches({key: now.get(key)}, {key: values}) is not None:
            a, b = np.asarray(now.get(key, np.nan)), np.asarray(values)
            gap = float(np.max(np.abs(a - b))) if a.shape == b.shape else np.inf
            far.append(f"{key} {gap:.2g}")
    return ", ".join(far[:8]) + (f" and {len(far) - 8} more" if len(far) > 8 else "")


@pytest.mark.parametrize("case", list(CASES))
def test_rollout_repeats_the_recorded_numbers(case: str) -> None:
    if CASES[case][0] == "pybullet":
        pytest.importorskip("pybullet")
    now = rollout(case)
    recorded = variants(case)
    assert any(matches(now, r) is None for r in recorded), (
        f"{case}: matches none of its {len(recorded)} recorded variants; per variant, the "
        f"keys off by more than 1e-6 (largest difference): "
        f"{[deviations(now, r) for r in recorded]}"
    )


def test_a_changed_number_matches_no_variant() -> None:
    """The check is to 1e-6: one state entry moved by 1e-5 matches no recorded variant."""
    recorded = variants("mujoco_slope")[0]
    moved = json.loads(json.dumps(recorded))
    moved["base_pos"][0][0] += 1e-5
    assert matches(recorded, recorded) is None
    assert matches(moved, recorded) == "base_pos"
    assert deviations(recorded, recorded) == ""
    assert deviations(moved, recorded) == "base_pos 1e-05"


if __name__ == "__main__":
    mode, named = sys.argv[1:2], sys.argv[2:]
    if mode not in (["--write"], ["--add"]) or not set(named) <= set(CASES):
        sys.exit(
            "usage: python tests/plugins/simulators/test_rollout_fingerprint.py --add | --write"
            f" [CASE ...] (cases: {', '.join(CASES)})"
        )
    record = {} if mode == ["--write"] and not named else json.loads(RECORD.read_text())
    for case in named or CASES:
        if mode == ["--write"]:  # that case starts again; the others keep their variants
            record[case] = []
        now = rollout(case)
        known = record.setdefault(case, [])
        if all(matches(now, recorded) is not None for recorded in known):
            known.append(now)
    RECORD.write_text(json.dumps(record) + "\n")
