"""Qilin's models: the Go1 figures at the nominal design, masses and gains that follow the
design, motor types, leg kinematics against MuJoCo's, and validation that can fail."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from coadapt_plugins.robots.qilin import constants as C
from coadapt_plugins.robots.qilin.robot import Qilin
from coadapt_plugins.robots.qilin.validation import validate_model

CORNERS = [[0.7, 0.7], [0.7, 1.3], [1.3, 0.7], [1.3, 1.3]]


@pytest.fixture(scope="module")
def qilin() -> Qilin:
    return Qilin()


def test_the_nominal_design_is_the_go1(qilin) -> None:
    model = qilin.build(qilin.nominal_design())
    # 5.204 + 4 x (0.68 + 1.009 + 0.195862) kg, Menagerie's go1.xml
    assert model.total_mass == pytest.approx(12.743448, abs=1e-6)
    # the Go1 home pose (abduction 0, hip 0.9, knee -1.8) on 0.213 m links, foot radius 0.023 m
    np.testing.assert_allclose(model.default_joint_pos, [0.0, 0.9, -1.8] * 4, atol=1e-9)
    assert model.standing_base_height == pytest.approx(2 * 0.213 * np.cos(0.9) + 0.023, abs=1e-9)
    np.testing.assert_allclose(model.torque_limit, [23.7, 23.7, 35.55] * 4)
    np.testing.assert_allclose(model.speed_limit, [30.1, 30.1, 20.06] * 4)
    assert (
        model.joint_names[:3] == ["FL_abduction", "FL_hip", "FL_knee"]
        and model.foot_bodies[0] == "FL_foot"
    )
    assert [(leg.name, leg.phase_offset) for leg in qilin.legs()] == [
        ("FL", 0.0),
        ("FR", 0.5),
        ("RL", 0.5),
        ("RR", 0.0),
    ]


def test_masses_and_gains_follow_the_legs(qilin) -> None:
    small, large = qilin.build(np.array([0.7, 0.7])), qilin.build(np.array([1.3, 1.3]))
    # thigh structure 0.409 kg and the calf less its 0.02 kg foot scale with length;
    # the rest is fixed
    per_leg_change = 0.3 * (1.009 - 0.60 + 0.195862 - 0.02)
    assert large.total_mass - 12.743448 == pytest.approx(4 * per_leg_change, abs=1e-6)
    assert 12.743448 - small.total_mass == pytest.approx(4 * per_leg_change, abs=1e-6)
    assert small.standing_base_height < 0.29 < large.standing_base_height
    assert large.kp[0] == pytest.approx(C.KP * 1.3**2) and small.kd[0] == pytest.approx(
        C.KD * 0.7**2
    )


def test_motor_types_set_hip_and_knee_limits_but_not_abduction(qilin) -> None:
    model = qilin.build(np.array([1.0, 1.0, 2.0, 1.0]))
    np.testing.assert_allclose(model.torque_limit[:3], [23.7, 35.55, 23.7])
    np.testing.assert_allclose(model.speed_limit[:3], [30.1, 20.06, 30.1])
    assert model.total_mass == pytest.approx(
        12.743448, abs=1e-6
    )  # a reduction stage weighs nothing (assumed)


@pytest.mark.parametrize("design", [[1.0, 1.0], *CORNERS])
def test_leg_ik_puts_every_foot_where_asked_in_mujoco(qilin, design) -> None:
    """Targets off the default stance in x, y and z (the abduction moves the leg plane):
    MuJoCo's forward kinematics of the IK's angles puts each foot there to 1e-6 m."""
    from coadapt_core.physics.model_tools import tools_for
    from coadapt_core.plugins import get_registry

    model = qilin.build(np.array(design))
    tools = tools_for(get_registry(), model)[1]
    designs = torch.tensor([design], dtype=torch.float64)
    target = qilin.default_foot_positions(designs) + torch.tensor(
        [[0.04, 0.03, 0.02], [-0.03, -0.04, -0.01], [0.0, 0.05, 0.03], [0.05, -0.02, 0.0]],
        dtype=torch.float64,
    )
    q = qilin.leg_inverse_kinematics(designs, target)[0].numpy()
    feet = np.asarray(tools.foot_positions(model, q), dtype=float)  # base frame
    hips = np.array(
        [C.hip_centre(leg) + np.array([0.0, C.side(leg) * C.THIGH_OFFSET, 0.0]) for leg in C.LEGS]
    )
    np.testing.assert_allclose(feet - hips, target[0].numpy(), atol=1e-6)


@pytest.mark.parametrize("design", CORNERS)
def test_the_corners_validate(qilin, design) -> None:
    report = qilin.validate(np.array(design))
    assert report.feasible, report.reasons
    assert {f.check for f in report.findings} >= {
        "kinematics.thigh_length",
        "mass.total",
        "statics.standing_torque",
        "statics.com_over_feet",
        "consistency.feet_and_com",
    }


def test_validation_fails_a_model_that_is_wrong(qilin) -> None:
    model = qilin.build(qilin.nominal_design())
    heavier = dataclasses.replace(model, total_mass=model.total_mass + 0.5)
    assert [f.check for f in validate_model(heavier).findings if not f.ok] == ["mass.total"]
    weak = dataclasses.replace(
        model, torque_limit=np.full(12, 5.0)
    )  # the knees need 5.05 N m to stand
    failed = {f.check: f for f in validate_model(weak).findings if not f.ok}
    assert (
        set(failed) == {"statics.standing_torque"} and failed["statics.standing_torque"].value > 1.0
    )
