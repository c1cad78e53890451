"""Validation with Pinocchio: findings on real designs, MuJoCo/Pinocchio agreement on
random designs, and every kind of check failing when its condition is broken."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pinocchio as pin
import pytest
from coadapt_plugins.robots.kuafu.validation import consistency, validate_model

CHECKS = {
    "kinematics.thigh_length",
    "kinematics.shank_length",
    "kinematics.joint_limits",
    "kinematics.feet_below_pelvis",
    "mass.total",
    "mass.com_over_support",
    "statics.double_support",
    "statics.single_support",
    "control.pd_stability",
    "consistency.total_mass",
    "consistency.com",
    "consistency.foot_positions",
    "consistency.mass_matrix",
}


@pytest.mark.parametrize(
    "design", [[1.0, 1.0], [0.5, 0.5], [1.5, 1.5], [1.5, 0.5], [0.5, 1.5, 3, 2]]
)
def test_corner_designs_are_feasible_with_all_checks(kuafu, design):
    report = kuafu.validate(np.array(design, dtype=float))
    assert {f.check for f in report.findings} == CHECKS
    assert report.feasible, report.reasons
    found = {f.check: f for f in report.findings}
    assert found["mass.total"].value == pytest.approx(
        kuafu.build(np.array(design, dtype=float)).total_mass
    )
    assert 0 < found["statics.double_support"].value < found["statics.single_support"].value


def test_mujoco_and_pinocchio_agree_on_random_designs(kuafu):
    for design in kuafu.design_space(mixed=True).sample(8, rng=11):
        worst = consistency(kuafu.build(design), count=4, seed=1)
        assert worst["mass"] < 1e-9
        assert worst["com"] < 1e-9
        assert worst["feet"] < 1e-9
        assert worst["mass_matrix"] < 1e-9


def test_mass_matrix_check_sees_a_missing_armature(kuafu):
    model = kuafu.build(np.array([1.0, 1.0]))
    bare = pin.buildModelFromXML(
        model.text("urdf"), pin.JointModelFreeFlyer()
    )  # URDF alone: no armature
    worst = consistency(model, pmodel=bare, count=2)
    assert worst["mass_matrix"] > 1e-4


def _findings(model) -> dict:
    return {f.check: f for f in validate_model(model).findings}


def test_statics_fail_with_weak_motors(kuafu):
    model = kuafu.build(np.array([1.5, 1.5]))
    weak = dataclasses.replace(model, torque_limit=model.torque_limit / 3.0)  # about 40 N m
    found = _findings(weak)
    assert found["statics.double_support"].ok
    assert not found["statics.single_support"].ok
    assert "knee" in found["statics.single_support"].message


def test_kinematics_fail_on_a_wrong_urdf(kuafu):
    model = kuafu.build(np.array([1.0, 1.0]))
    # move the left knee 5 mm down in the URDF only
    broken = model.text("urdf").replace(
        '<child link="left_shank"/><origin xyz="0 0 -0.35"',
        '<child link="left_shank"/><origin xyz="0 0 -0.355"',
    )
    assert broken != model.text("urdf")
    found = _findings(dataclasses.replace(model, formats={**model.formats, "urdf": broken}))
    assert not found["kinematics.thigh_length"].ok
    assert found["kinematics.shank_length"].ok
    assert not found["consistency.foot_positions"].ok
    assert not found["consistency.mass_matrix"].ok


def test_limit_and_support_checks_fail(kuafu):
    model = kuafu.build(np.array([1.0, 1.0]))
    at_limit = dataclasses.replace(model, joint_upper=model.default_joint_pos.copy())
    assert not _findings(at_limit)["kinematics.joint_limits"].ok
    toes_only = dataclasses.replace(
        model, foot_contact_points=model.foot_contact_points + np.array([0.3, 0.0, 0.0])
    )
    found = _findings(toes_only)
    assert not found["mass.com_over_support"].ok
    assert "outside" in found["mass.com_over_support"].message


def test_pd_stability_fails_with_too_much_damping(kuafu):
    model = kuafu.build(np.array([1.0, 1.0]))
    assert _findings(model)["control.pd_stability"].ok
    ringing = dataclasses.replace(model, kd=model.kd * 4.0)  # knee kd 40 on a 0.1 kg m^2 shank
    found = _findings(ringing)["control.pd_stability"]
    assert not found.ok and found.value > 1.0


def test_reasons_are_one_line_per_failed_check(kuafu):
    model = kuafu.build(np.array([1.0, 1.0]))
    report = validate_model(dataclasses.replace(model, torque_limit=model.torque_limit / 10.0))
    assert not report.feasible
    assert report.reasons and all("\n" not in r for r in report.reasons)
    assert all(r.split(":")[0] in CHECKS for r in report.reasons)


def test_validation_is_fast(kuafu):
    design = np.array([1.23, 0.77])
    start = time.perf_counter()
    kuafu.validate(design)
    assert time.perf_counter() - start < 1.0
