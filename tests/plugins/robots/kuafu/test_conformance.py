"""Kuafu passes the Robot conformance suite every robot plugin must pass."""

from __future__ import annotations

import pytest
from coadapt_plugins.robots.kuafu.robot import Kuafu

from coadapt_core.testing import RobotConformance


class TestKuafuConformance(RobotConformance):
    @pytest.fixture
    def robot(self) -> Kuafu:
        return Kuafu()
