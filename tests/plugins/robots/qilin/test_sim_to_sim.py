"""Qilin's sim-to-sim (issue 49): its shipped flat policy, trained on MuJoCo, walks its
nominal design on PyBullet too. Before the PyBullet backend's armature correction counted the
floating base's rows (and folded the knees' armature into the calves that carry the feet),
every agent fell: survival 0.00, 50 agents x 20 s. Measured since with `coadapt eval --robot
qilin --sim pybullet` (50 agents x 20 s, 0.5 m/s): survival 1.00, 0.496 m/s (MuJoCo 1.00,
0.482 m/s)."""

from __future__ import annotations

import pytest

pytest.importorskip("pybullet")

from coadapt_core.experiments.evaluate import evaluate_checkpoint
from coadapt_core.plugins import get_registry


@pytest.mark.slow
def test_the_shipped_policy_walks_the_nominal_design_on_pybullet():
    """8 agents x 4 s under 0.5 m/s, Table 2 randomization on: measured survival 1.00 and
    0.483 +- 0.010 m/s (MuJoCo, the same agents: 1.00, 0.467 +- 0.011); 10 s here."""
    registry = get_registry()
    robot = registry.create("robot", "qilin")
    result = evaluate_checkpoint(
        robot.shipped_policy("flat"),
        robot,
        registry.get("simulator", "pybullet"),
        robot.nominal_design(),
        terrain="flat",
        command=[0.5, 0.0, 0.0],
        agents=8,
        seconds=4.0,
        device="cpu",
        seed=0,
        randomize=True,
        record=False,
        progress=None,
        objectives=[],
    )
    assert result["survival"] >= 0.9
    assert result["divergences"] == 0
    assert abs(result["vx_mean"] - 0.5) < 0.15, result["vx_mean"]
