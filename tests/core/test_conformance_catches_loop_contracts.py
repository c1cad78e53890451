"""The conformance suites catch the contracts the co-adaptation loop relies on. Each
throwaway plugin below plants one mistake a third-party author made (issue 15's points 2,
3, 5, 6, 7 and 9) and the suite must fail on exactly the test that guards that contract."""

from __future__ import annotations

from tests.conftest import EXAMPLE_PLUGIN

pytest_plugins = ["pytester"]

PLANTED = f'''
import random
import sys

import numpy as np
import pytest

sys.path.insert(0, {str(EXAMPLE_PLUGIN)!r})
from coadapt_example import RandomSearch
from coadapt_example.robot import Trotter

from coadapt_core.robot import Finding, ValidationReport
from coadapt_core.testing import OptimizerConformance, RobotConformance


class IgnoresInitialDesigns(RandomSearch):
    """Point 2: the loop's K training designs are silently dropped."""
    name = "ignores-initial"

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        self._first = None


class SeedsLegacyRandomState(RandomSearch):
    """Point 3: passes the seed to a 32-bit library; seeds >= 2**32 crash it."""
    name = "legacy-seed"

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        self._legacy = np.random.RandomState(self.seed)


class ZeroSeedMeansRandom(RandomSearch):
    """Point 3: like cma, reads seed 0 as 'pick one at random'."""
    name = "zero-random"

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        self._rng = np.random.default_rng(None if self.seed == 0 else self.seed)


class CannotResume(RandomSearch):
    """Point 5: its proposals hang on state no resume can restore (the global random module)."""
    name = "cannot-resume"

    def _ask(self):
        designs = super()._ask()
        jitter = random.random() * 1e-3
        return np.clip(designs + jitter, self.space.lower, self.space.upper)


class NoActuators(Trotter):
    """Point 6: an MJCF without actuators."""
    def build(self, design):
        model = super().build(design)
        mjcf = model.text("mjcf")
        start, end = mjcf.index("<actuator>"), mjcf.index("</actuator>") + len("</actuator>")
        model.formats = {{**model.formats, "mjcf": mjcf[:start] + mjcf[end:]}}
        return model


class SwappedFeet(Trotter):
    """Point 7: foot bodies listed front-right first while the IK's leg 0 is front-left."""
    def build(self, design):
        model = super().build(design)
        feet = list(model.foot_bodies)
        feet[0], feet[1] = feet[1], feet[0]
        model.foot_bodies = feet
        return model


class NumpyBoolFindings(Trotter):
    """Point 9: a validation check returning numpy's bool (robot show --json crashed on it)."""
    def validate(self, design):
        report = super().validate(design)
        findings = [
            Finding(f.check, np.bool_(f.ok), f.message, f.value, f.limit)
            for f in report.findings
        ]
        return ValidationReport(report.design, findings)


def _optimizer(cls):
    class Suite(OptimizerConformance):
        @pytest.fixture
        def optimizer_cls(self):
            return cls
    return Suite


def _robot(cls):
    class Suite(RobotConformance):
        @pytest.fixture
        def robot(self):
            return cls()
    return Suite


TestIgnoresInitialDesigns = _optimizer(IgnoresInitialDesigns)
TestSeedsLegacyRandomState = _optimizer(SeedsLegacyRandomState)
TestZeroSeedMeansRandom = _optimizer(ZeroSeedMeansRandom)
TestCannotResume = _optimizer(CannotResume)
TestNoActuators = _robot(NoActuators)
TestSwappedFeet = _robot(SwappedFeet)
TestNumpyBoolFindings = _robot(NumpyBoolFindings)
'''

#: planted mistake -> the suite test that must fail on it
EXPECTED = {
    "TestIgnoresInitialDesigns": "test_initial_designs_are_the_first_proposals",
    "TestSeedsLegacyRandomState": "test_any_seed_below_2_to_63_works[4294967296]",
    "TestZeroSeedMeansRandom": "test_any_seed_below_2_to_63_works[0]",
    "TestCannotResume": "test_state_round_trips_through_json_and_continues_identically",
    "TestNoActuators": "test_one_actuator_per_joint",
    "TestSwappedFeet": "test_ik_leg_order_matches_foot_bodies",
    "TestNumpyBoolFindings": "test_validation_findings_are_plain_json",
}


def test_each_planted_mistake_fails_its_contract_test(pytester):
    pytester.makepyfile(test_planted=PLANTED)
    result = pytester.runpytest_subprocess(
        "-q",
        "-p",
        "no:cacheprovider",
        "-k",
        "initial_designs_are or any_seed or state_round_trips or one_actuator or ik_leg_order or "
        "plain_json",
    )
    failed = {line.split(" ")[1] for line in result.outlines if line.startswith("FAILED")}
    failed = {name.split("::", 1)[1] for name in failed}
    for suite, test in EXPECTED.items():
        assert f"{suite}::{test}" in failed, (suite, test, sorted(failed), result.outlines[-25:])
    # the same suites pass on the unbroken plugins: each failure is the planted mistake
    assert not any(name.startswith("TestSwappedFeet::test_one_actuator") for name in failed)
    assert not any(name.startswith("TestNoActuators::test_ik_leg_order") for name in failed)
    assert not any(name.startswith("TestIgnoresInitialDesigns::test_any_seed") for name in failed)
