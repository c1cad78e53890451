"""Every registered robot passes the Robot conformance suite every robot plugin must pass
(Kuafu, Qilin, and whichever robot is registered later: a spec robot needs no line here).
Its standing check runs in every installed simulator that reads one of the robot's formats;
the simulators' own suite runs on every robot in tests/plugins/simulators/test_conformance.py."""

from __future__ import annotations

import pytest

from coadapt_core.plugins import get_registry
from coadapt_core.testing import RobotConformance

REGISTRY = get_registry()


def test_the_built_in_robots_are_registered():
    assert {"kuafu", "qilin"} <= set(REGISTRY.names("robot"))


class TestEveryRobot(RobotConformance):
    @pytest.fixture(params=REGISTRY.names("robot"))
    def robot(self, request):
        return REGISTRY.create("robot", request.param)
