"""The conformance suites, run against the example third-party plugin exactly as a plugin
author would run them in their own package."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from coadapt_core.testing import ObjectiveConformance, OptimizerConformance

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "example_plugin"))

from coadapt_example import JointSpeedObjective, RandomSearch


class TestJointSpeedObjective(ObjectiveConformance):
    @pytest.fixture
    def objective(self):
        return JointSpeedObjective()


class TestRandomSearch(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return RandomSearch
