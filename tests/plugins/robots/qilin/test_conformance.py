"""Qilin passes the Robot conformance suite every robot plugin must pass, and the MuJoCo
simulator's suite with it."""

from __future__ import annotations

import pytest
from coadapt_plugins.robots.qilin.robot import Qilin

from coadapt_core.testing import RobotConformance, SimulatorConformance


class TestQilinConformance(RobotConformance):
    @pytest.fixture
    def robot(self) -> Qilin:
        return Qilin()


class TestQilinOnMujoco(SimulatorConformance):
    @pytest.fixture
    def robot(self) -> Qilin:
        return Qilin()

    @pytest.fixture
    def simulator_cls(self):
        from coadapt_core.plugins import get_registry

        return get_registry().get("simulator", "mujoco")
