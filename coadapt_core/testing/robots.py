"""Conformance suite for `Robot` plugins. Supply a fixture `robot` (an instance)."""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.errors import DesignError
from coadapt_core.robot import Robot, RobotModel, ValidationReport


class RobotConformance:
    """Every robot: design spaces, models that MuJoCo loads, validation, leg kinematics."""

    def test_is_robot_with_name(self, robot: Robot) -> None:
        assert isinstance(robot, Robot)
        assert isinstance(robot.name, str) and robot.name

    @pytest.mark.parametrize("mixed", [False, True])
    def test_nominal_design_inside_space(self, robot: Robot, mixed: bool) -> None:
        space = robot.design_space(mixed)
        nominal = robot.nominal_design(mixed)
        assert nominal.shape == (space.dim,)
        assert space.contains(nominal)

    def test_build_models_consistent(self, robot: Robot) -> None:
        import mujoco

        for design in robot.design_space().sample(3, rng=0):
            model = robot.build(design)
            assert isinstance(model, RobotModel)
            j = model.num_joints
            for name in ("default_joint_pos", "kp", "kd", "torque_limit", "speed_limit", "joint_lower", "joint_upper"):
                assert getattr(model, name).shape == (j,), name
            assert np.all(model.torque_limit > 0) and np.all(model.speed_limit > 0)
            assert np.all(model.joint_lower < model.joint_upper)
            assert np.all(model.default_joint_pos >= model.joint_lower)
            assert np.all(model.default_joint_pos <= model.joint_upper)
            assert model.total_mass > 0 and model.standing_base_height > 0
            mj = mujoco.MjModel.from_xml_string(model.mjcf)
            for name in model.joint_names:
                assert mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name) >= 0, name
            for name in [*model.foot_bodies, model.base_body]:
                assert mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name) >= 0, name
            assert "<robot" in model.urdf
            assert float(mj.body_subtreemass[0]) == pytest.approx(model.total_mass, rel=1e-6)

    def test_out_of_space_design_rejected(self, robot: Robot) -> None:
        space = robot.design_space()
        bad = space.upper + 1.0
        with pytest.raises(DesignError):
            robot.build(bad)
        with pytest.raises(DesignError):
            robot.build(np.append(space.lower, space.lower))

    def test_validate_returns_named_findings(self, robot: Robot) -> None:
        report = robot.validate(robot.nominal_design())
        assert isinstance(report, ValidationReport)
        assert report.findings
        assert all(f.check for f in report.findings)
        assert report.feasible, report.reasons

    def test_leg_ik_reaches_default_pose(self, robot: Robot) -> None:
        """IK of the default standing foot position gives joint targets near the default pose."""
        import torch

        raw = robot.design_space().sample(4, rng=1)
        designs = torch.as_tensor(raw, dtype=torch.float64)
        height = robot.hip_height(designs)
        assert height.shape == (4,) and torch.all(height > 0)
        feet = robot.default_foot_positions(designs)
        q = robot.leg_inverse_kinematics(designs, feet)
        for i in range(4):
            model = robot.build(raw[i])
            assert q.shape == (4, model.num_joints)
            np.testing.assert_allclose(q[i].numpy(), model.default_joint_pos, atol=1e-3)
