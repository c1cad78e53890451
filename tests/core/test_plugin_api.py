"""The plugin API's version: the recorded signature of the interfaces follows it, a plugin
written for an older major version is refused in one line, `coadapt plugins` shows what
each plugin declares, and a run says at its start when its optimizer ignores
`initial_designs`."""

from __future__ import annotations

import copy
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from coadapt_core import api_signature, plugin_api
from coadapt_core.api_signature import interface_signature
from coadapt_core.plugin_api import (
    PLUGIN_API_VERSION,
    api_problem,
    bump_problem,
    required_bump,
)
from tests.conftest import make_dist, run_cli

SIGNATURE_FILE = Path(__file__).with_name("plugin_api_signature.json")
MIGRATION_HEADING = "## Migration"


def test_recorded_signature_matches_the_interfaces_and_the_version():
    """Changing a base class, a record's fields, a hook or a conformance suite without
    raising PLUGIN_API_VERSION (and recording it) fails here."""
    history = json.loads(SIGNATURE_FILE.read_text())["history"]
    latest = history[-1]
    now = interface_signature()
    if latest["signature"] != now:
        problem = bump_problem(latest["version"], latest["signature"], PLUGIN_API_VERSION, now)
        pytest.fail(
            (problem or f"the plugin interfaces changed since {latest['version']} was recorded")
            + "; then run `python -m coadapt_core.api_signature "
            + f"{SIGNATURE_FILE.relative_to(Path.cwd())}`"
        )
    assert latest["version"] == PLUGIN_API_VERSION, (
        "PLUGIN_API_VERSION changed: record it (python -m coadapt_core.api_signature)"
    )
    for old, new in itertools.pairwise(history):  # every recorded step was bumped enough
        assert (
            bump_problem(old["version"], old["signature"], new["version"], new["signature"]) is None
        )


def test_signature_covers_what_plugins_are_written_against():
    sig = interface_signature()
    step = sig["coadapt_core.objective.StepBatch (fields)"]
    assert "joint_targets" in step and "action" not in step
    opt = sig["coadapt_core.optimizer.Optimizer"]
    assert opt["_ask"].startswith("abstract") and "initial_designs" in opt["__init__"]
    assert "coadapt_register_robots" in sig["coadapt_core.hookspecs"]
    assert (
        "test_initial_designs_are_the_first_proposals"
        in sig["coadapt_core.testing.OptimizerConformance"]
    )


def test_simulator_dtype_reads_as_a_torch_dtype_and_is_recorded_so():
    """`Simulator.dtype` is resolved when read (its module imports no torch) and reads as the
    plain class attribute it was: on the class, on an instance, overridden by a subclass or an
    instance; the signature records what a subclass reads, as before."""
    import torch

    from coadapt_core.physics.dtype import TorchDtype
    from coadapt_core.physics.simulator import Simulator

    class Holder:
        dtype = TorchDtype("float64")

    class Narrow(Holder):
        dtype = torch.float32

    held = Holder()
    assert Simulator.dtype is torch.float64 and Holder.dtype is torch.float64
    assert held.dtype is torch.float64 and Narrow().dtype is torch.float32
    held.dtype = torch.float16
    assert held.dtype is torch.float16 and Holder.dtype is torch.float64
    member = interface_signature()["coadapt_core.physics.simulator.Simulator"]["dtype"]
    assert member == "attribute: ClassVar[torch.dtype] = dtype"


def test_bump_rules_catch_a_change_the_version_does_not_account_for():
    old = interface_signature()
    removed = copy.deepcopy(old)
    del removed["coadapt_core.objective.StepBatch (fields)"]["joint_targets"]
    assert required_bump(old, removed) == "major"
    assert bump_problem("2.0.0", old, "2.1.0", removed) is not None  # a minor bump is not enough
    assert bump_problem("2.0.0", old, "3.0.0", removed) is None
    added = copy.deepcopy(old)
    added["coadapt_core.optimizer.Optimizer"]["new_helper"] = "method(self) -> 'None'"
    assert required_bump(old, added) == "minor"
    assert bump_problem("2.0.0", old, "2.0.0", added) is not None  # unchanged version
    assert bump_problem("2.0.0", old, "2.1.0", added) is None
    abstract = copy.deepcopy(old)
    abstract["coadapt_core.robot.Robot"]["must_do"] = "abstract method(self) -> 'None'"
    assert required_bump(old, abstract) == "major"
    required = copy.deepcopy(old)
    required["coadapt_core.objective.StepBatch (fields)"]["power"] = (
        "field: torch.Tensor (required)"
    )
    assert required_bump(old, required) == "major"
    # a record new altogether breaks no plugin, whatever its fields
    record = copy.deepcopy(old)
    record["coadapt_core.robot.NewRecord (fields)"] = {"joints": "field: tuple (required)"}
    assert required_bump(old, record) == "minor"
    assert required_bump(old, copy.deepcopy(old)) is None
    renamed = copy.deepcopy(
        old
    )  # a suite's check renamed: it runs on the plugin under its new name
    suite = renamed["coadapt_core.testing.RobotConformance"]
    suite["test_renamed_check"] = suite.pop("test_one_actuator_per_joint")
    assert required_bump(old, renamed) == "minor"
    assert bump_problem("2.0.0", old, "2.1.0", renamed) is None
    fixture = copy.deepcopy(
        old
    )  # a suite's fixture is what a plugin's tests supply or use: removing it breaks them
    del fixture["coadapt_core.testing.SimulatorConformance"]["make"]
    assert required_bump(old, fixture) == "major"


def test_record_refuses_an_unbumped_change(tmp_path, monkeypatch):
    path = tmp_path / "sig.json"
    assert api_signature.record(path) == "recorded"
    assert api_signature.record(path) == "unchanged"
    data = json.loads(path.read_text())
    data["history"][-1]["signature"]["coadapt_core.optimizer.Optimizer"]["gone"] = "method(self)"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="PLUGIN_API_VERSION"):
        api_signature.record(path)
    major, minor, _ = (int(x) for x in plugin_api.PLUGIN_API_VERSION.split("."))
    monkeypatch.setattr(
        plugin_api, "PLUGIN_API_VERSION", f"{major}.{minor + 1}.0"
    )  # 'gone' removed: minor is not enough
    with pytest.raises(ValueError, match="major"):
        api_signature.record(path)
    monkeypatch.setattr(plugin_api, "PLUGIN_API_VERSION", f"{major + 1}.0.0")
    assert api_signature.record(path) == "recorded"
    assert [e["version"] for e in json.loads(path.read_text())["history"]] == [
        f"{major}.{minor}.0",
        f"{major + 1}.0.0",
    ]


@pytest.mark.parametrize("declared", ["2", "2.0", "2.0.0", "2.1", 2])
def test_this_major_version_loads(declared):
    assert api_problem(None if declared is None else str(declared)) is None


def test_an_older_major_version_is_refused_naming_what_changed():
    line = api_problem("1.4")
    assert "1.x" in line and PLUGIN_API_VERSION in line
    assert "docs/plugins.md#migration" in line
    for change in ("action", "initial_designs", "option_specs", "JSON", "2**63"):
        assert change in line, change
    assert "\n" not in line


@pytest.mark.parametrize(
    "declared,expected",
    [("3.0", "upgrade coadapt"), ("2.9", "upgrade coadapt"), ("two", "not a version")],
)
def test_newer_or_malformed_declarations_are_refused(declared, expected):
    assert expected in api_problem(declared)


def test_migration_guide_covers_every_breaking_change():
    """Each change the refusal line names has its entry in docs/plugins.md's migration guide."""
    docs = (Path(__file__).resolve().parents[2] / "docs" / "plugins.md").read_text()
    assert MIGRATION_HEADING in docs
    guide = docs[docs.index(MIGRATION_HEADING) :]
    for key in (
        "`action`",
        "`initial_designs`",
        "`option_specs`",
        "state_dict",
        "2**63",
        "seed32",
        "COADAPT_PLUGIN_API",
        "cma",
    ):
        assert key in guide, key


QUAD_V1 = """
from coadapt_core import hookimpl

COADAPT_PLUGIN_API = "1.0"


@hookimpl
def coadapt_register_robots():
    from coadapt_core.robot import Robot

    class Quad(Robot):
        name = "quad"
        design_space = nominal_design = build = validate = None
        leg_inverse_kinematics = default_foot_positions = None

    return [Quad]
"""

QUAD_UNDECLARED = QUAD_V1.replace('COADAPT_PLUGIN_API = "1.0"\n', "").replace('"quad"', '"quad2"')


def test_a_plugin_for_an_older_major_version_is_one_line_and_exit_2(tmp_path):
    site = make_dist(
        tmp_path / "site",
        "quad-coadapt",
        "[coadapt]\nquad-coadapt = quad_coadapt\n",
        {"quad_coadapt": QUAD_V1},
    )
    done = run_cli("robot", "show", "quad", pythonpath=[site])
    assert done.returncode == 2, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, done.stderr
    assert (
        "quad-coadapt" in lines[0]
        and "plugin API 1.x" in lines[0]
        and "docs/plugins.md#migration" in lines[0]
    )
    listed = run_cli("plugins", "--json", pythonpath=[site])
    assert listed.returncode == 0
    data = json.loads(listed.stdout)
    assert data["plugin_api"] == PLUGIN_API_VERSION
    assert "quad" not in [p["name"] for p in data["plugins"]["robot"]]
    assert any("plugin API 1.x" in b["error"] for b in data["broken"])


def test_plugins_shows_the_declared_version_and_refuses_an_undeclared_one(tmp_path):
    """A package declaring no version was written before versions were declared: for 1.x. It
    is listed as broken with the 1.x line (saying it declared nothing), not loaded."""
    site = make_dist(
        tmp_path / "site",
        "quad2-coadapt",
        "[coadapt]\nquad2-coadapt = quad2_coadapt\n",
        {"quad2_coadapt": QUAD_UNDECLARED},
    )
    done = run_cli("plugins", "--json", pythonpath=[site])
    assert done.returncode == 0, done.stderr
    data = json.loads(done.stdout)
    robots = {p["name"]: p for p in data["plugins"]["robot"]}
    assert "quad2" not in robots and robots["kuafu"]["plugin_api"] == "2.0"
    (broken,) = [b for b in data["broken"] if b["distribution"] == "quad2-coadapt"]
    assert (
        "declares no plugin API version" in broken["error"] and "plugin API 1.x" in broken["error"]
    )
    table = run_cli("plugins", pythonpath=[site])
    assert f"plugin API {PLUGIN_API_VERSION}" in table.stdout and " api " in table.stdout


# -- an optimizer that ignores initial_designs ---------------------------------------------------
class _IgnoresInitial:
    """Written for API 1: reads initial designs from an option it no longer gets, samples
    instead."""

    @staticmethod
    def make():
        from coadapt_core.optimizer import Optimizer

        class OldRandom(Optimizer):
            name = "old-random"

            def __init__(self, space, **kwargs):
                super().__init__(space, **kwargs)
                self._rng = np.random.default_rng(self.seed)

            def _ask(self):
                return self.space.sample(self.population, self._rng)

            def _tell(self, designs, costs):
                pass

        return OldRandom


def test_an_optimizer_ignoring_initial_designs_is_named_at_the_start_of_a_run(tmp_path, capsys):
    from coadapt_plugins.objectives.locomotion import TorqueObjective

    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.coadapt.first_round import initial_designs_note
    from coadapt_core.coadapt.run import run_coadaptation
    from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

    old = _IgnoresInitial.make()
    note = initial_designs_note(old, SPACE, 5, 1, {})
    assert note is not None and "old-random" in note and "initial_designs" in note
    from coadapt_core.plugins import get_registry

    assert (
        initial_designs_note(
            get_registry().get("optimizer", get_registry().default("optimizer")), SPACE, 5, 1, {}
        )
        is None
    )

    config = make_config(
        "smoke",
        overrides={
            "out": str(tmp_path),
            "population": 5,
            "outer_iterations": 1,
            "optimizer_iterations": 2,
            "store": "none",
        },
    )
    result = run_coadaptation(
        config,
        backend_factory=lambda seed: AnalyticBackend(seed),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        optimizer_cls=old,
    )
    err = capsys.readouterr().err
    assert err.startswith("warning: optimizer 'old-random' ignores `initial_designs`"), err
    assert result.summary["notes"] and "old-random" in result.summary["notes"][0]


def test_an_optimizer_keeping_a_study_is_checked_at_its_first_round(tmp_path, capsys):
    """An optimizer that keeps a study in the run's store (an option it declares `from_run`)
    is not probed before training (building one has side effects); its real first round is
    checked instead, once per run."""
    from coadapt_plugins.objectives.locomotion import TorqueObjective

    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.coadapt.run import run_coadaptation
    from coadapt_core.options import PluginOption
    from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

    class OldStudy(_IgnoresInitial.make()):
        name = "old-study"
        option_specs = (PluginOption("storage", "str", None, "database URL", from_run="store_url"),)
        built = 0

        def __init__(self, space, **kwargs):
            super().__init__(space, **kwargs)
            type(self).built += 1

    config = make_config(
        "smoke",
        overrides={
            "out": str(tmp_path),
            "population": 5,
            "outer_iterations": 2,
            "optimizer_iterations": 2,
            "store": "none",
        },
    )
    result = run_coadaptation(
        config,
        backend_factory=lambda seed: AnalyticBackend(seed),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        optimizer_cls=OldStudy,
    )
    assert OldStudy.built == 2  # one per outer iteration: no probe
    warnings = [
        line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")
    ]
    assert len(warnings) == 1 and "optimizer 'old-study' ignores `initial_designs`" in warnings[0]
    assert result.summary["notes"] == warnings
