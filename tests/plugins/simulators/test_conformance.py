"""Every simulator's conformance suite on every robot: the registry's simulators (MuJoCo,
PyBullet) crossed with its robots, so a robot added later (a spec robot, a plugin's) is run
on both engines without a line here. A simulator whose library is not installed is skipped
with its own one-line reason. Beside the suite, each pair follows a joint step standing (the
check that caught PyBullet's armature correction on Qilin, issue 49)."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import torch

from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.plugins import get_registry
from coadapt_core.testing import SimulatorConformance

REGISTRY = get_registry()
ROBOTS = REGISTRY.names("robot")
SIMULATORS = REGISTRY.names("simulator")


@functools.cache
def _missing(simulator: str, robot: str) -> str | None:
    """Why `simulator` cannot run `robot` here (its library missing, or it reads none of the
    robot's model formats), or None."""
    cls = REGISTRY.get("simulator", simulator)
    bot = REGISTRY.create("robot", robot)
    formats = bot.build(bot.nominal_design()).formats
    if not set(cls.model_formats) & set(formats):
        return f"{simulator} reads none of {robot}'s model formats"
    try:
        cls(bot, bot.nominal_design()[None]).close()
    except ImportError as exc:  # an optional backend's one-line reason (PyBulletMissing)
        return str(exc)
    return None


@pytest.fixture(params=ROBOTS)
def robot(request):
    return REGISTRY.create("robot", request.param)


@pytest.fixture(params=SIMULATORS)
def simulator_cls(request, robot):
    reason = _missing(request.param, robot.name)
    if reason:
        pytest.skip(reason)
    return REGISTRY.get("simulator", request.param)


def test_both_engines_and_both_built_in_robots_are_crossed():
    assert {"mujoco", "pybullet"} <= set(SIMULATORS)
    assert {"kuafu", "qilin"} <= set(ROBOTS)


class TestEverySimulatorOnEveryRobot(SimulatorConformance):
    """The suite's tests, each once per (robot, simulator)."""


def test_a_standing_robot_follows_a_joint_step(simulator_cls, robot) -> None:
    """Standing on flat ground at the nominal design, environment e steps joint e's target by
    0.2 rad: for 0.5 s no environment diverges, the base stays above 70 % of its standing
    height and within 30 deg of upright, and the stepped joint moves towards its new target.
    PyBullet's armature correction once diverged here on Qilin, its lagged forces missing the
    floating base's reaction (issue 49)."""
    design = robot.nominal_design()
    with simulator_cls(
        robot, np.stack([design] * 3), randomization=RandomizationConfig.off()
    ) as sim:
        state = sim.reset()
        rows = torch.arange(sim.num_envs)
        stepped = rows % sim.num_joints
        start = state.joint_pos[rows, stepped].clone()
        targets = sim.default_joint_pos.clone()
        targets[rows, stepped] += 0.2
        for _ in range(round(0.5 / sim.control_dt)):
            state = sim.step(targets)
            assert not bool(state.diverged.any()), "diverged"
    height = robot.build(design).standing_base_height
    assert torch.all(state.base_pos[:, 2] - state.terrain_height > 0.7 * height)
    tilt = 2 * torch.acos(state.base_quat[:, 0].abs().clamp(max=1.0))
    assert float(tilt.max()) < np.radians(30), tilt.tolist()
    moved = state.joint_pos[rows, stepped] - start
    assert torch.all(moved > 0.02), moved.tolist()
