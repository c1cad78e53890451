"""A fixed-seed rollout of each built-in backend repeats the numbers recorded before the
physics room was restructured (torch actuation and parameters, spawn and random streams in
the `Simulator` base): the same design, seed, randomization, terrain and targets give the
same state, parameters and, after `reseed`, the same redraw. Regenerate the file only for a
deliberate change of the physics, with `python tests/plugins/simulators/test_rollout_fingerprint.py`."""

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
STATE = ("base_pos", "base_quat", "base_lin_vel", "joint_pos", "joint_vel", "joint_torque", "foot_pos",
         "foot_contact_force", "terrain_height")
PARAMS = ("friction", "restitution", "com_shift", "pd_factor", "motor_strength", "delay", "contact_timeconst",
          "joint_damping", "armature")
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
    with cls(robot, designs, terrain=terrain, randomization=RandomizationConfig.preset(preset), seed=7) as sim:
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


@pytest.mark.parametrize("case", list(CASES))
def test_rollout_repeats_the_recorded_numbers(case: str) -> None:
    if CASES[case][0] == "pybullet":
        pytest.importorskip("pybullet")
    recorded = json.loads(RECORD.read_text())[case]
    now = rollout(case)
    assert set(now) == set(recorded)
    for key, values in recorded.items():
        np.testing.assert_allclose(np.asarray(now[key]), np.asarray(values), rtol=1e-6, atol=1e-6, err_msg=key)


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python tests/plugins/simulators/test_rollout_fingerprint.py --write")
    RECORD.write_text(json.dumps({case: rollout(case) for case in CASES}) + "\n")
