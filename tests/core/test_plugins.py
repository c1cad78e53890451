"""Plugin discovery: entry points, third-party plugins, duplicates, broken plugins and the
COADAPT_LOAD_PLUGINS filter."""

from __future__ import annotations

import json
import re
import sys

import numpy as np
import pytest

from coadapt_core.design_space import Continuous, DesignSpace
from coadapt_core.errors import PluginError, UnknownPluginError
from coadapt_core.plugins import KINDS, load_registry
from tests.conftest import make_dist, run_cli

DUPLICATE_SOURCE = """
from coadapt_core import hookimpl
from coadapt_core.objective import Objective

COADAPT_PLUGIN_API = "2.1"

class Impostor(Objective):
    name = "joint-speed"
    display_name = "impostor"
    def step_cost(self, step):
        return step.joint_vel.sum(-1)

@hookimpl
def coadapt_register_objectives():
    return [Impostor]
"""


def test_builtin_plugins_register_through_entry_points():
    from importlib import metadata

    eps = [
        ep
        for ep in metadata.entry_points(group="coadapt")
        if ep.dist and ep.dist.metadata["Name"] == "coadapt"
    ]
    assert eps, "coadapt's own pyproject declares its built-ins in the `coadapt` group"
    assert all(ep.name.startswith("coadapt.") for ep in eps), (
        "built-in entry-point names are namespaced"
    )
    registry = load_registry()
    for info in registry.all():
        if info.distribution == "coadapt":
            assert info.entry_point.startswith("coadapt.")


def test_plugins_json_lists_every_kind_and_the_example_plugin(example_plugin_site):
    result = run_cli("plugins", "--json", pythonpath=[example_plugin_site])
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data["plugins"]) == set(KINDS)
    objectives = {p["name"]: p for p in data["plugins"]["objective"]}
    optimizers = {p["name"]: p for p in data["plugins"]["optimizer"]}
    assert objectives["joint-speed"]["distribution"] == "coadapt-example"
    assert objectives["joint-speed"]["version"] == "0.2.0"
    assert optimizers["random-search"]["entry_point"] == "coadapt-example"


def test_example_plugin_hidden_by_empty_load_list(example_plugin_site):
    result = run_cli(
        "plugins", "--json", pythonpath=[example_plugin_site], env={"COADAPT_LOAD_PLUGINS": ""}
    )
    assert result.returncode == 0, result.stderr
    names = {p["name"] for p in json.loads(result.stdout)["plugins"]["objective"]}
    assert "joint-speed" not in names
    shown = run_cli(
        "plugins",
        "--json",
        pythonpath=[example_plugin_site],
        env={"COADAPT_LOAD_PLUGINS": "coadapt-example"},
    )
    assert "joint-speed" in {p["name"] for p in json.loads(shown.stdout)["plugins"]["objective"]}


def test_example_plugin_usable_by_name(example_plugin_site, monkeypatch):
    monkeypatch.syspath_prepend(str(example_plugin_site))
    monkeypatch.delenv("COADAPT_LOAD_PLUGINS", raising=False)
    registry = load_registry()
    space = DesignSpace([Continuous("a", 0.5, 1.5), Continuous("b", 0.5, 1.5)])
    opt = registry.create("optimizer", "random-search", space, population=8, budget=15, seed=0)
    while not opt.done:
        d = opt.ask()
        opt.tell(d, ((d - np.array([0.8, 1.2])) ** 2).sum(axis=1))
    best, cost = opt.best()
    assert cost < 1e-3 and np.allclose(best, [0.8, 1.2], atol=0.05)
    objective = registry.create("objective", "joint-speed")
    assert objective.display_name == "Joint speed"


def test_unknown_name_lists_available(example_plugin_site):
    result = run_cli("run", "--optimizer", "nope", pythonpath=[example_plugin_site])
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1
    assert "unknown optimizer 'nope'; available:" in lines[0]
    assert "random-search" in lines[0]


def test_help_shows_third_party_choices(example_plugin_site):
    result = run_cli("run", "--help", pythonpath=[example_plugin_site], env={"COLUMNS": "200"})
    assert result.returncode == 0
    assert "random-search" in re.sub(r"-\n\s+", "-", result.stdout)  # help text wraps at hyphens


def test_duplicate_name_is_one_clear_line_naming_both(example_plugin_site, tmp_path):
    dup = make_dist(
        tmp_path / "dup",
        "coadapt-impostor",
        "[coadapt]\ncoadapt-impostor = impostor_plugin\n",
        {"impostor_plugin": DUPLICATE_SOURCE},
    )
    result = run_cli("plugins", pythonpath=[example_plugin_site, dup])
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert (
        "joint-speed" in lines[0]
        and "coadapt-example" in lines[0]
        and "coadapt-impostor" in lines[0]
    )


def test_duplicate_in_process_raises_plugin_error(example_plugin_site, monkeypatch):
    monkeypatch.syspath_prepend(str(example_plugin_site))
    monkeypatch.delenv("COADAPT_LOAD_PLUGINS", raising=False)
    namespace: dict = {}
    exec(DUPLICATE_SOURCE, namespace)
    module = type(sys)("impostor")
    module.__dict__.update(namespace)
    with pytest.raises(PluginError, match="claimed twice"):
        load_registry(extra_plugins=[(module, "coadapt-impostor")])


def test_broken_plugin_reported_by_name_others_load(example_plugin_site, tmp_path):
    broken = make_dist(
        tmp_path / "broken",
        "coadapt-broken",
        "[coadapt]\ncoadapt-broken = coadapt_no_such_module\n",
    )
    result = run_cli("plugins", "--json", pythonpath=[example_plugin_site, broken])
    assert result.returncode == 0
    data = json.loads(result.stdout)
    assert [b["distribution"] for b in data["broken"]] == ["coadapt-broken"]
    assert "joint-speed" in {p["name"] for p in data["plugins"]["objective"]}
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "coadapt-broken" in lines[0] and "ModuleNotFoundError" in lines[0]


def test_registry_unknown_plugin_error_lists_names():
    registry = load_registry()
    with pytest.raises(UnknownPluginError) as info:
        registry.get("robot", "no-such-robot")
    assert "available:" in str(info.value)


def test_hook_returning_non_subclass_reported():
    module = type(sys)("bad_hooks")
    from coadapt_core import hookimpl

    @hookimpl
    def coadapt_register_objectives():
        return [int]

    module.coadapt_register_objectives = coadapt_register_objectives
    registry = load_registry(extra_plugins=[(module, "coadapt-bad")])
    assert any("not a Objective subclass" in b.error for b in registry.broken)
