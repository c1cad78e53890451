"""The process-wide registry asks each kind's hooks when the kind is first used (issue 61):
naming the simulators calls no robot hook, and the shipped spec robots are registered by their
folders' names, their files read on first use, with the description and version an eager read
gives."""

from __future__ import annotations

import sys

import pytest

from coadapt_core import hookimpl
from coadapt_core.errors import PluginError, UnknownPluginError
from coadapt_core.objective import Objective
from coadapt_core.physics.simulator import Simulator
from coadapt_core.plugins import load_registry


class ProbeSimulator(Simulator):
    name = "probe-sim"
    description = "a simulator class no test builds"


class ProbeObjective(Objective):
    name = "probe-objective"

    def step_cost(self, step):
        return step.joint_vel.sum(-1)


def _probe_plugin(calls: list[str], robots_fail: bool = False) -> object:
    """A plugin module with a simulator, an objective (a class of its own) and a robot hook
    that raises (when `robots_fail`), recording which hooks were asked."""
    module = type(sys)("probe_plugin")
    objective = type("ProbeObjective", (ProbeObjective,), {})
    module.COADAPT_PLUGIN_API = "2.2"

    @hookimpl
    def coadapt_register_simulators():
        calls.append("simulator")
        return [ProbeSimulator]

    @hookimpl
    def coadapt_register_objectives():
        calls.append("objective")
        return [objective]

    @hookimpl
    def coadapt_register_robots():
        calls.append("robot")
        if robots_fail:
            raise RuntimeError("no robot here")
        return []

    module.coadapt_register_simulators = coadapt_register_simulators
    module.coadapt_register_objectives = coadapt_register_objectives
    module.coadapt_register_robots = coadapt_register_robots
    return module


def test_a_lazy_registry_asks_only_the_kind_it_is_asked_for():
    calls: list[str] = []
    registry = load_registry(extra_plugins=[(_probe_plugin(calls), "coadapt-probe")], lazy=True)
    assert calls == []
    assert "probe-sim" in registry.names("simulator") and "mujoco" in registry.names("simulator")
    assert calls == ["simulator"]
    assert registry.default("simulator") == "mujoco"  # the kind is asked once
    assert calls == ["simulator"]
    assert "probe-objective" in registry.entries["objective"]  # entries: every kind
    assert sorted(calls) == ["objective", "robot", "simulator"]


def test_an_eager_registry_asks_every_kind_at_once():
    calls: list[str] = []
    load_registry(extra_plugins=[(_probe_plugin(calls), "coadapt-probe")])
    assert sorted(calls) == ["objective", "robot", "simulator"]


def test_an_unknown_name_lists_the_failures_of_its_own_kind_and_broken_lists_all():
    """A robot hook that raises is no part of an unknown simulator's line (it was not asked),
    is part of an unknown robot's, and `broken` (read by `coadapt plugins`) has it always."""
    calls: list[str] = []
    plugin = _probe_plugin(calls, robots_fail=True)
    registry = load_registry(extra_plugins=[(plugin, "coadapt-probe")], lazy=True)
    with pytest.raises(UnknownPluginError) as sim:
        registry.get("simulator", "mujocoo")
    assert "no robot here" not in str(sim.value) and "did you mean 'mujoco'" in str(sim.value)
    with pytest.raises(UnknownPluginError) as robot:
        registry.get("robot", "nope")
    assert "coadapt_register_robots raised RuntimeError: no robot here" in str(robot.value)
    fresh = load_registry(extra_plugins=[(_probe_plugin([], True), "coadapt-probe")], lazy=True)
    assert [b.distribution for b in fresh.broken] == ["coadapt-probe"]


def test_a_name_claimed_twice_is_raised_where_its_kind_is_used_each_time():
    first, second = _probe_plugin([]), _probe_plugin([])
    second.__name__ = "probe_plugin_2"
    registry = load_registry(
        extra_plugins=[(first, "coadapt-probe"), (second, "coadapt-other")], lazy=True
    )
    assert "kuafu" in registry.names("robot")  # another kind answers
    for _ in range(2):  # the kind stays unregistered: every use says so
        with pytest.raises(PluginError, match="claimed twice"):
            registry.names("objective")
    with pytest.raises(PluginError, match="claimed twice"):
        load_registry(extra_plugins=[(first, "coadapt-probe"), (second, "coadapt-other")])


def test_the_shipped_spec_robots_read_on_first_use_as_an_eager_read_gives():
    """Each shipped robot folder's spec reads and names its folder; its class, registered by
    the folder's name, gives the description and version of `spec_robot_class` (read at
    registration), read when first asked for."""
    from coadapt_plugins.robots.specs import HERE
    from coadapt_plugins.robots.specs.discovery import robot_folders, spec_robots_in
    from coadapt_plugins.robots.specs.robot import spec_robot_class

    folders = robot_folders(HERE)
    assert [f.name for f in folders] == ["jingwei", "nezha"]
    lazy, problems = spec_robots_in(HERE, by_folder=True)
    assert problems == []
    for folder, cls in zip(folders, lazy, strict=True):
        assert "description" in vars(cls) and type(vars(cls)["description"]).__name__ == (
            "_ReadOnUse"
        )
        eager = spec_robot_class(folder)
        assert (cls.name, cls.spec_path) == (eager.name, eager.spec_path) == (folder.name, folder)
        assert cls.plugin_version == eager.plugin_version and len(cls.plugin_version) == 12
        assert cls.description == eager.description
        assert isinstance(vars(cls)["description"], str)  # read once, set on the class


def test_a_folder_named_robot_whose_spec_names_another_is_refused_on_use(tmp_path):
    from coadapt_plugins.robots.specs import HERE
    from coadapt_plugins.robots.specs.robot import folder_robot_class

    from coadapt_core.errors import UserError

    folder = tmp_path / "renamed"
    folder.mkdir()
    for path in (HERE / "jingwei").iterdir():
        if path.is_file():
            (folder / path.name).write_bytes(path.read_bytes())
    cls = folder_robot_class(folder)
    assert cls.name == "renamed"
    with pytest.raises(UserError, match="names the robot 'jingwei'"):
        _ = cls.plugin_version


def test_threads_asking_one_kind_at_once_register_it_once():
    """A grid's cells run in threads: the first use of a kind asks its hooks once, even where
    a hook makes new classes on each call (as a spec robot's does), which a second asking
    would refuse as a name claimed twice."""
    import threading
    import time

    calls: list[str] = []
    module = type(sys)("slow_plugin")
    module.COADAPT_PLUGIN_API = "2.2"

    @hookimpl
    def coadapt_register_objectives():
        calls.append("objective")
        time.sleep(0.05)
        return [type("SlowObjective", (ProbeObjective,), {"name": "slow-objective"})]

    module.coadapt_register_objectives = coadapt_register_objectives
    registry = load_registry(extra_plugins=[(module, "coadapt-slow")], lazy=True)
    found, errors = [], []

    def ask():
        try:
            found.append(registry.names("objective"))
        except Exception as exc:
            errors.append(exc)

    threads = [threading.Thread(target=ask) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == [] and calls == ["objective"]
    assert len(found) == 6 and all("slow-objective" in names for names in found)
