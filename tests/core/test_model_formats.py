"""Robot model formats: a model carries its descriptions by format name, a simulator
declares the formats it reads, and a simulator reading a new format needs no change to the
core (the robot writes the new key; the conformance suite checks the declaration)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from coadapt_core.errors import UserError
from coadapt_core.plugins import get_registry
from coadapt_core.testing import SimulatorConformance


@pytest.fixture(scope="module")
def kuafu():
    return get_registry().create("robot", "kuafu")


def test_a_model_gives_each_format_it_writes_and_names_them_when_asked_for_another(kuafu):
    model = kuafu.build(kuafu.nominal_design())
    assert sorted(model.formats) == ["mjcf", "urdf"]
    assert model.text("mjcf").lstrip().startswith("<mujoco") and "<robot" in model.text("urdf")
    with pytest.raises(UserError) as err:
        model.text("sdf")
    assert str(err.value) == (
        "the robot model has no 'sdf' description (it writes: mjcf, urdf); a simulator "
        "that reads it needs a robot plugin that writes it"
    )
    assert err.value.field == "robot"


def test_the_built_in_simulators_declare_what_they_read():
    registry = get_registry()
    assert registry.get("simulator", "mujoco").model_formats == ("mjcf",)
    if "pybullet" in registry.names("simulator"):
        assert registry.get("simulator", "pybullet").model_formats == ("urdf", "mjcf")


def test_a_third_format_needs_no_core_change(kuafu):
    """A robot that also writes a "toy" description and a simulator declaring it: the
    declaration check passes; the same simulator with a robot that lacks it fails."""
    toy_sim = type(
        "ToySim",
        (get_registry().get("simulator", "mujoco"),),
        {"name": "toy", "model_formats": ("toy",)},
    )

    class ToyKuafu(type(kuafu)):
        def build(self, design):
            model = super().build(design)
            return dataclasses.replace(model, formats={**model.formats, "toy": "<toy/>"})

    toy = ToyKuafu()
    assert toy.build(np.array([1.0, 1.0])).text("toy") == "<toy/>"
    SimulatorConformance().test_declares_the_model_formats_it_reads(toy_sim, toy)
    with pytest.raises(UserError, match="no 'toy' description"):
        SimulatorConformance().test_declares_the_model_formats_it_reads(toy_sim, kuafu)
