"""What an optimizer plugin declares is all the loop goes by: a third party's optimizer gets
the mixed design space by `implies_mixed`, a study name and the run's store by declaring
options filled `from_run`, exactly as a built-in does (no plugin or option is named)."""

from __future__ import annotations

import numpy as np
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.search import uses_mixed_space
from coadapt_core.optimizer import Optimizer
from coadapt_core.options import PluginOption
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend


class StudyKeeper(Optimizer):
    """A third party's optimizer that keeps a study (as optuna does): random designs, and the
    options it was built with remembered."""

    name = "study-keeper"
    option_specs = (
        PluginOption("study_name", "str", "", "name of the study", from_run="run_name"),
        PluginOption("storage", "str", "", "database URL of the study", from_run="store_url"),
    )
    built: list[dict] = []

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        StudyKeeper.built.append(dict(self.options))
        self._rng = np.random.default_rng(self.seed)
        self._first = self.initial_designs

    def _ask(self):
        if self._first is not None:
            first, self._first = self._first, None
            return first
        return self.space.decode(self._rng.uniform(size=(self.population, self.space.dim)))

    def _tell(self, designs, costs):
        pass


class MixedWalker(StudyKeeper):
    name = "mixed-walker"
    supports_mixed = True
    implies_mixed = True


class Registry:
    def __init__(self, *classes):
        self.classes = {c.name: c for c in classes}

    def get(self, kind, name):
        from coadapt_core.errors import UserError

        if name not in self.classes:
            raise UserError(f"unknown {kind} '{name}'", field=kind)
        return self.classes[name]


def test_a_third_party_optimizer_that_implies_mixed_gets_the_mixed_space(monkeypatch):
    import coadapt_core.plugins as plugins

    mixed, plain = make_config("smoke"), make_config("smoke")
    mixed.optimizer, plain.optimizer = "mixed-walker", "study-keeper"
    monkeypatch.setattr(plugins, "get_registry", lambda: Registry(MixedWalker, StudyKeeper))
    assert uses_mixed_space(mixed) is True
    assert uses_mixed_space(plain) is False


def test_a_third_party_optimizer_keeps_its_study_in_the_run_store_under_the_run_id(tmp_path):
    StudyKeeper.built.clear()
    store = tmp_path / "runs.db"
    config = make_config(
        "smoke",
        overrides={
            "out": str(tmp_path / "runs"),
            "store": str(store),
            "logger": "none",
            "outer_iterations": 2,
            "optimizer_iterations": 2,
        },
    )
    result = run_coadaptation(
        config,
        backend_factory=lambda seed: AnalyticBackend(seed),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        optimizer_cls=StudyKeeper,
    )
    names = [o["study_name"] for o in StudyKeeper.built]
    assert names[:2] == [f"{result.run_id}-outer0", f"{result.run_id}-outer1"]
    assert {o["storage"] for o in StudyKeeper.built} == {f"sqlite:///{store}"}
    assert result.summary["optimizer"] == "study-keeper"


def test_only_options_declared_from_run_are_filled():
    """The loop fills an option from the run because the plugin declares it so, whatever its
    name; one left undeclared (even called `study_name`) or set by the user is left alone."""
    import pytest

    from coadapt_core.options import fill_from_run

    specs = (
        PluginOption("study_name", "str", None, "not declared from_run"),
        PluginOption("journal", "str", None, "a name", from_run="run_name"),
        PluginOption("db", "str", None, "a store", from_run="store_url"),
    )
    facts = {"run_name": "r-outer1", "store_url": None}  # a run without a database store
    assert fill_from_run(specs, {}, facts) == {"journal": "r-outer1"}
    assert fill_from_run(specs, {"journal": "mine"}, facts) == {"journal": "mine"}
    assert (
        fill_from_run(specs, {}, {**facts, "store_url": "sqlite:///x.db"})["db"] == "sqlite:///x.db"
    )
    with pytest.raises(TypeError, match="from_run"):
        PluginOption("x", "str", None, "help", from_run="the moon")
