"""Conformance suite for `Robot` plugins. Supply a fixture `robot` (an instance).

Besides shapes and consistency it checks the contracts the loop and the task rely on: the
model contract (one actuator per actuated joint; the model stands on flat ground under its
own PD gains in every installed simulator that reads one of its formats), validation
findings that are plain JSON, legs declared in the order of `foot_bodies` and of the IK, and
the gait phase offsets. Model facts (names, mass, actuators, feet at a pose) are read with a
simulator's model tools (`coadapt_core.physics.model_tools`), so the suite serves robots of
any format that an installed simulator reads.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from coadapt_core.errors import DesignError
from coadapt_core.robot import Leg, Robot, RobotModel, ValidationReport


def _tools(model: RobotModel):
    """The model tools of an installed simulator that reads one of the model's formats (the
    default simulator's first); skipped, with the reason, where none is installed."""
    from coadapt_core.errors import UserError
    from coadapt_core.physics.model_tools import tools_for
    from coadapt_core.plugins import get_registry

    try:
        return tools_for(get_registry(), model)[1]
    except UserError as exc:
        pytest.skip(str(exc))


def _reading_simulators(model: RobotModel) -> list[type]:
    """Every installed simulator class that reads one of the model's formats."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    classes = [registry.get("simulator", n) for n in registry.names("simulator")]
    found = [c for c in classes if set(getattr(c, "model_formats", ())) & set(model.formats)]
    if not found:
        pytest.skip(
            f"no installed simulator reads the model formats {', '.join(sorted(model.formats))}"
        )
    return found


class RobotConformance:
    """Every robot: design spaces, models an installed simulator reads, validation and
    leg kinematics."""

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
        models = [robot.build(design) for design in robot.design_space().sample(3, rng=0)]
        for model in models:
            assert isinstance(model, RobotModel)
            j = model.num_joints
            for name in (
                "default_joint_pos",
                "kp",
                "kd",
                "torque_limit",
                "speed_limit",
                "joint_lower",
                "joint_upper",
            ):
                assert getattr(model, name).shape == (j,), name
            assert np.all(model.torque_limit > 0) and np.all(model.speed_limit > 0)
            assert np.all(model.joint_lower < model.joint_upper)
            assert np.all(model.default_joint_pos >= model.joint_lower)
            assert np.all(model.default_joint_pos <= model.joint_upper)
            assert model.total_mass > 0 and model.standing_base_height > 0
        tools = _tools(
            models[0]
        )  # the model's own facts: skipped (with why) where no simulator reads it
        for model in models:
            facts = tools.link_facts(model)
            bodies = {link["name"] for link in facts["links"]}
            joints = {name for link in facts["links"] for name in link["joints"]}
            for name in model.joint_names:
                assert name in joints, name
            for name in [*model.foot_bodies, model.base_body]:
                assert name in bodies, name
            assert facts["total_mass"] == pytest.approx(model.total_mass, rel=1e-6)

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
        """The model contract: exactly one joint actuator per actuated joint (the simulators
        drive joint j through it), and no actuator on anything else."""
        model = robot.build(robot.nominal_design())
        driven = _tools(model).actuated_joints(model)
        for a, name in enumerate(driven):
            assert name is not None, f"actuator {a} does not drive a joint"
        for name in model.joint_names:
            assert driven.count(name) == 1, (
                f"joint '{name}' has {driven.count(name)} actuators (needs exactly 1)"
            )
        assert sorted(driven) == sorted(model.joint_names), (
            f"actuators on {driven}, joints {model.joint_names}"
        )

    def test_validation_findings_are_plain_json(self, robot: Robot) -> None:
        """`coadapt robot show --json` and the results store write findings as JSON: `ok`
        must be a Python bool (not numpy's), value and limit plain numbers or None."""
        for design in [robot.nominal_design(), *robot.design_space().sample(2, rng=4)]:
            report = robot.validate(design)
            for f in report.findings:
                assert type(f.ok) is bool, (
                    f"finding {f.check}: ok is {type(f.ok).__name__}, not bool"
                )
                assert isinstance(f.check, str) and isinstance(f.message, str)
                for value in (f.value, f.limit):
                    assert value is None or type(value) in (int, float), (
                        f"finding {f.check}: value/limit of type {type(value).__name__}"
                    )
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
        """Moving IK leg l's foot target moves foot body l (and no other foot) in the model, by
        about the requested distance: the IK and `foot_bodies` list the legs alike."""
        import torch

        design = robot.nominal_design()
        model = robot.build(design)
        tools = _tools(model)
        designs = torch.as_tensor(design, dtype=torch.float64)[None]
        default_feet = robot.default_foot_positions(designs)

        def feet_in_base(q: np.ndarray) -> np.ndarray:
            return np.asarray(tools.foot_positions(model, q), dtype=float)

        rest = feet_in_base(robot.leg_inverse_kinematics(designs, default_feet)[0].numpy())
        step = 0.02
        for leg in range(len(model.foot_bodies)):
            target = default_feet.clone()
            target[0, leg, 0] += step  # 2 cm forward
            moved = feet_in_base(robot.leg_inverse_kinematics(designs, target)[0].numpy()) - rest
            others = np.delete(np.linalg.norm(moved, axis=1), leg)
            assert np.all(others < 1e-6), f"IK leg {leg} moved other feet by {others}"
            assert abs(moved[leg, 0] - step) < 0.5 * step, (
                f"IK leg {leg} moved foot body '{model.foot_bodies[leg]}' by {moved[leg]} "
                f"for a {step} m step in x"
            )

    def test_stands_in_each_simulator(self, robot: Robot) -> None:
        """Spawned at its standing height on flat ground (nominal physics, no randomization)
        and held at the default pose by its own PD gains (the simulator's actuation: torque
        limits, torque-speed envelope), the nominal design stays up for 1 s in every installed
        simulator that reads one of its formats: the base keeps > 70 % of its standing
        height and stays within 30 deg of upright."""
        from coadapt_core.physics.randomization import RandomizationConfig

        design = robot.nominal_design()
        model = robot.build(design)
        for sim_cls in _reading_simulators(model):
            if "flat" not in sim_cls.terrains:
                continue
            with sim_cls(
                robot, design[None], terrain="flat", randomization=RandomizationConfig.off(), seed=0
            ) as sim:
                sim.reset()
                targets = sim.default_joint_pos.clone()
                for _ in range(int(round(1.0 / sim.control_dt))):
                    state = sim.step(targets)
                height = float(state.base_pos[0, 2] - state.terrain_height[0])
                w = float(state.base_quat[0, 0])
            tilt = math.degrees(2 * math.acos(min(1.0, abs(w))))
            where = f"in {sim_cls.name}"
            assert height > 0.7 * model.standing_base_height, (
                f"base fell to {height:.3f} m of {model.standing_base_height:.3f} {where}"
            )
            assert tilt < 30, f"base tilted {tilt:.0f} deg {where}"
