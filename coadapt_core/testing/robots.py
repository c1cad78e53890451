"""Conformance suite for `Robot` plugins. Supply a fixture `robot` (an instance).

Besides shapes and consistency it checks the contracts the loop and the task rely on: the
MJCF contract (one actuator per actuated joint; the model stands on flat ground in MuJoCo
under its own PD gains), validation findings that are plain JSON, legs declared in the
order of `foot_bodies` and of the IK, and the gait phase offsets.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from coadapt_core.errors import DesignError
from coadapt_core.robot import Leg, Robot, RobotModel, ValidationReport


def _floor_model(mjcf: str):
    """The robot's MJCF on a flat floor plane (conaffinity 1, as the simulators' terrains)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(mjcf)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], contype=0, conaffinity=1)
    return spec.compile()


def _qpos_addresses(mj, names: list[str]) -> np.ndarray:
    import mujoco

    return np.array([mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in names])


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
            mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
            for name in model.joint_names:
                assert mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name) >= 0, name
            for name in [*model.foot_bodies, model.base_body]:
                assert mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name) >= 0, name
            assert "<robot" in model.text("urdf")
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

    def test_one_actuator_per_joint(self, robot: Robot) -> None:
        """The MJCF contract: exactly one joint actuator per actuated joint (the simulators
        drive joint j through it), and no actuator on anything else."""
        import mujoco

        model = robot.build(robot.nominal_design())
        mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
        driven = []
        for a in range(mj.nu):
            assert mj.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT, f"actuator {a} does not drive a joint"
            driven.append(mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, int(mj.actuator_trnid[a, 0])))
        for name in model.joint_names:
            assert driven.count(name) == 1, f"joint '{name}' has {driven.count(name)} actuators (needs exactly 1)"
        assert sorted(driven) == sorted(model.joint_names), f"actuators on {driven}, joints {model.joint_names}"

    def test_validation_findings_are_plain_json(self, robot: Robot) -> None:
        """`coadapt robot show --json` and the results store write findings as JSON: `ok`
        must be a Python bool (not numpy's), value and limit plain numbers or None."""
        for design in [robot.nominal_design(), *robot.design_space().sample(2, rng=4)]:
            report = robot.validate(design)
            for f in report.findings:
                assert type(f.ok) is bool, f"finding {f.check}: ok is {type(f.ok).__name__}, not bool"
                assert isinstance(f.check, str) and isinstance(f.message, str)
                for value in (f.value, f.limit):
                    assert value is None or type(value) in (int, float), (
                        f"finding {f.check}: value/limit of type {type(value).__name__}")
            json.dumps(report.to_dict())
            json.dumps([vars(f) for f in report.findings])

    def test_legs_declared_in_foot_order(self, robot: Robot) -> None:
        """One `Leg` per foot body, offsets in [0, 1); the IK's legs are the same count."""
        import torch

        legs = robot.legs()
        model = robot.build(robot.nominal_design())
        assert all(isinstance(leg, Leg) for leg in legs)
        assert len(legs) == len(model.foot_bodies) >= 1
        assert len({leg.name for leg in legs}) == len(legs)
        assert all(0.0 <= leg.phase_offset < 1.0 for leg in legs)
        nominal = torch.as_tensor(robot.nominal_design(), dtype=torch.float64)[None]
        assert robot.default_foot_positions(nominal).shape == (1, len(legs), 3)

    def test_ik_leg_order_matches_foot_bodies(self, robot: Robot) -> None:
        """Moving IK leg l's foot target moves foot body l (and no other foot) in MuJoCo, by
        about the requested distance: the IK and `foot_bodies` list the legs alike."""
        import mujoco
        import torch

        design = robot.nominal_design()
        model = robot.build(design)
        mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
        data = mujoco.MjData(mj)
        addr = _qpos_addresses(mj, model.joint_names)
        feet_ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, f) for f in model.foot_bodies]
        base_id = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, model.base_body)
        designs = torch.as_tensor(design, dtype=torch.float64)[None]
        default_feet = robot.default_foot_positions(designs)

        def feet_in_base(q: np.ndarray) -> np.ndarray:
            data.qpos[:] = mj.qpos0
            data.qpos[addr] = q
            mujoco.mj_kinematics(mj, data)
            rot = data.xmat[base_id].reshape(3, 3)
            return np.stack([rot.T @ (data.xpos[i] - data.xpos[base_id]) for i in feet_ids])

        rest = feet_in_base(robot.leg_inverse_kinematics(designs, default_feet)[0].numpy())
        step = 0.02
        for leg in range(len(model.foot_bodies)):
            target = default_feet.clone()
            target[0, leg, 0] += step  # 2 cm forward
            moved = feet_in_base(robot.leg_inverse_kinematics(designs, target)[0].numpy()) - rest
            others = np.delete(np.linalg.norm(moved, axis=1), leg)
            assert np.all(others < 1e-6), f"IK leg {leg} moved other feet by {others}"
            assert abs(moved[leg, 0] - step) < 0.5 * step, (
                f"IK leg {leg} moved foot body '{model.foot_bodies[leg]}' by {moved[leg]} for a {step} m step in x")

    def test_stands_in_mujoco(self, robot: Robot) -> None:
        """Dropped at its standing height onto a flat floor and held at the default pose by
        its own PD gains (torques clipped to its limits), the nominal design stays up for
        1 s: the base keeps > 70 % of its standing height and stays within 30 deg of upright."""
        import mujoco

        model = robot.build(robot.nominal_design())
        mj = _floor_model(model.text("mjcf"))
        data = mujoco.MjData(mj)
        addr = _qpos_addresses(mj, model.joint_names)
        vaddr = np.array([mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in model.joint_names])
        act = {mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, int(mj.actuator_trnid[a, 0])): a for a in range(mj.nu)}
        order = np.array([act[n] for n in model.joint_names])
        gear = mj.actuator_gear[order, 0]
        data.qpos[:] = mj.qpos0
        data.qpos[2] = model.standing_base_height + 0.005
        data.qpos[3:7] = [1, 0, 0, 0]
        data.qpos[addr] = model.default_joint_pos
        dt = mj.opt.timestep
        for _ in range(int(round(1.0 / dt))):
            q, qd = data.qpos[addr], data.qvel[vaddr]
            tau = np.clip(model.kp * (model.default_joint_pos - q) - model.kd * qd, -model.torque_limit, model.torque_limit)
            data.ctrl[order] = tau / gear
            mujoco.mj_step(mj, data)
        height = float(data.qpos[2])
        w = float(data.qpos[3])
        tilt = math.degrees(2 * math.acos(min(1.0, abs(w))))
        assert height > 0.7 * model.standing_base_height, f"base fell to {height:.3f} m of {model.standing_base_height:.3f}"
        assert tilt < 30, f"base tilted {tilt:.0f} deg"
