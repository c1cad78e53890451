"""The backend conformance suite (`coadapt_core.testing.BackendConformance`) on coadapt's own
backends, and on broken ones it must fail: a backend that declares the surrogate ensemble
(`surrogate_ensemble = True`) without one of its methods fails the check, and the loop
refuses it in one line instead of quietly running without it."""

from __future__ import annotations

import pytest

from coadapt_core.coadapt.specialized import SpecializedPolicyBackend
from coadapt_core.errors import CoadaptError
from coadapt_core.fitness import surrogate_ensemble
from coadapt_core.testing import BackendConformance
from coadapt_core.testing.backends import check_backend
from tests.fakes.analytic import AnalyticBackend

pytest_plugins = ["pytester"]


class TestAnalyticBackend(BackendConformance):
    @pytest.fixture
    def backend(self):
        return AnalyticBackend(0)


class TestSpecializedBackend(BackendConformance):
    @pytest.fixture
    def backend(self):
        return SpecializedPolicyBackend(lambda seed: AnalyticBackend(seed), train_steps=10, seed=0)


class TestUniversalPolicyBackend(BackendConformance):
    @pytest.fixture
    def backend(self):
        from coadapt_core.learning.backend import UniversalPolicyBackend

        return UniversalPolicyBackend  # the class: building one needs a robot and a simulator


class NoMembers(AnalyticBackend):
    """Declares the ensemble (inherited) but has lost `surrogate_members`."""

    surrogate_members = None


class ExtraOption(AnalyticBackend):
    """A further keyword-only parameter with a default: still callable as the loop calls it."""

    def fit_surrogate(self, designs, costs, objectives, buffer, *, seed=0, epochs=3):
        return super().fit_surrogate(designs, costs, objectives, buffer, seed=seed)


class NoTrain:
    """Only a surrogate: no `train`, no `real_fitness`."""

    surrogate_ensemble = False

    def surrogate_fitness(self, designs, objectives, buffer, *, samples, seed=0): ...

    def save(self, path): ...

    def load(self, path): ...


def test_our_backends_declare_what_they_implement():
    from coadapt_core.learning.backend import UniversalPolicyBackend

    assert (
        AnalyticBackend.surrogate_ensemble is True
        and UniversalPolicyBackend.surrogate_ensemble is True
    )
    assert not getattr(
        SpecializedPolicyBackend, "surrogate_ensemble", False
    )  # no shared policy, no surrogate
    assert surrogate_ensemble(AnalyticBackend(0)) is not None
    assert surrogate_ensemble(SpecializedPolicyBackend(AnalyticBackend, train_steps=1)) is None


def test_a_declared_ensemble_missing_a_method_fails_the_check():
    problems = check_backend(NoMembers(0))
    assert len(problems) == 1 and "surrogate_members is missing" in problems[0], problems
    assert check_backend(AnalyticBackend(0)) == []
    missing = check_backend(NoTrain())
    assert any("train is missing" in p for p in missing) and any(
        "real_fitness is missing" in p for p in missing
    )
    assert (
        check_backend(ExtraOption(0)) == [] and check_backend(ExtraOption) == []
    )  # an instance or the class
    with pytest.raises(
        CoadaptError, match="declares surrogate_ensemble but has no surrogate_members"
    ):
        surrogate_ensemble(NoMembers(0))


def test_the_suite_fails_on_a_backend_missing_a_declared_surrogate_method(pytester):
    pytester.makepyfile(
        test_broken='''
import pytest
from coadapt_core.testing import BackendConformance


class HalfEnsemble:
    """Claims the surrogate ensemble but implements only its fit."""
    surrogate_ensemble = True

    def train(self, designs, steps, *, seed=0): ...
    def real_fitness(self, designs, objectives, *, agents, steps, seed=0): ...
    def surrogate_fitness(self, designs, objectives, buffer, *, samples, seed=0): ...
    def save(self, path): ...
    def load(self, path): ...
    def fit_surrogate(self, designs, costs, objectives, buffer, *, seed=0): ...


class PositionalSamples(HalfEnsemble):
    """Both methods, but `samples` cannot be given by keyword as the loop gives it."""
    def surrogate_members(self, designs, objectives, buffer, samples, /, seed=0): ...


class TestHalf(BackendConformance):
    @pytest.fixture
    def backend(self):
        return HalfEnsemble()


class TestPositional(BackendConformance):
    @pytest.fixture
    def backend(self):
        return PositionalSamples()
'''
    )
    result = pytester.runpytest_subprocess("-q", "-p", "no:cacheprovider")
    failed = [line for line in result.outlines if line.startswith("FAILED")]
    assert result.parseoutcomes().get("failed", 0) == 2, result.outlines[-15:]
    assert all("test_a_declared_surrogate_ensemble_is_implemented" in line for line in failed), (
        failed
    )
    text = "\n".join(result.outlines)
    assert (
        "surrogate_members is missing" in text and "cannot be called as surrogate_members" in text
    )
