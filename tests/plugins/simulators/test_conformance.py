"""Every simulator's conformance suite on every robot: the registry's simulators (MuJoCo,
PyBullet) crossed with its robots, so a robot added later (a spec robot, a plugin's) is run
on both engines without a line here. A simulator whose library is not installed is skipped
with its own one-line reason."""

from __future__ import annotations

import functools

import pytest

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
