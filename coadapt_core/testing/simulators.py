"""Conformance suite for `Simulator` plugins.

Supply fixtures `robot` (a Robot instance) and `simulator_cls` (the Simulator class). The
suite builds small batches (a few environments) of the robot's designs.
"""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.errors import DesignError, UserError
from coadapt_core.physics.actuation import pd_torque
from coadapt_core.physics.randomization import RandomizationConfig, sample_env_params
from coadapt_core.physics.simulator import (
    SPAWN_MARGIN,
    SPAWN_STREAM_KEY,
    SimState,
    Simulator,
    quat_rotate,
)
from coadapt_core.robot import Robot


def _designs(robot: Robot, n: int) -> np.ndarray:
    space = robot.design_space()
    designs = space.sample(n, rng=0)
    designs[0] = robot.nominal_design()
    return designs


def _assert_state(state: SimState, n: int, j: int) -> None:
    import torch

    shapes = {
        "base_pos": (n, 3),
        "base_quat": (n, 4),
        "base_lin_vel": (n, 3),
        "base_ang_vel": (n, 3),
        "joint_pos": (n, j),
        "joint_vel": (n, j),
        "joint_torque": (n, j),
        "foot_contact": None,
        "terrain_height": (n,),
        "diverged": (n,),
    }
    for name, shape in shapes.items():
        value = getattr(state, name)
        assert isinstance(value, torch.Tensor), name
        if shape is not None:
            assert tuple(value.shape) == shape, (name, tuple(value.shape))
        if value.dtype != torch.bool:
            assert torch.isfinite(value).all(), name
    assert state.foot_pos.shape[0] == n and state.foot_pos.shape[2] == 3
    assert state.foot_contact.dtype == torch.bool
    assert torch.allclose(
        state.base_quat.norm(dim=-1), torch.ones(n, dtype=state.base_quat.dtype), atol=1e-4
    )


class SimulatorConformance:
    """Every simulator backend: shapes, subset reset, re-design, limits, terrains."""

    num_envs = 3

    def make(self, simulator_cls, robot, n=None, **kwargs) -> Simulator:
        kwargs.setdefault("randomization", RandomizationConfig.off())
        return simulator_cls(robot, _designs(robot, n or self.num_envs), **kwargs)

    def test_is_simulator_with_name(self, simulator_cls) -> None:
        assert issubclass(simulator_cls, Simulator)
        assert simulator_cls.name
        assert "flat" in simulator_cls.terrains

    def test_declares_the_model_formats_it_reads(self, simulator_cls, robot) -> None:
        """`model_formats` names formats the robot model carries (`RobotModel.formats`): what
        the backend asks the robot for, so a robot that writes them runs on it."""
        formats = simulator_cls.model_formats
        assert isinstance(formats, tuple) and all(isinstance(f, str) and f for f in formats)
        model = robot.build(robot.nominal_design())
        for fmt in formats:
            assert model.text(fmt).strip(), fmt

    def test_reset_and_step_shapes(self, simulator_cls, robot) -> None:
        import torch

        with self.make(simulator_cls, robot) as sim:
            state = sim.reset()
            _assert_state(state, sim.num_envs, sim.num_joints)
            assert sim.designs.shape == (sim.num_envs, robot.design_space().dim)
            targets = sim.default_joint_pos.clone()
            for _ in range(5):
                state = sim.step(targets)
            _assert_state(state, sim.num_envs, sim.num_joints)
            assert not bool(state.diverged.any())
            assert torch.all(state.base_pos[:, 2] > state.terrain_height)

    def test_standing_pose_holds_for_one_second(self, simulator_cls, robot) -> None:
        """Holding the default pose keeps the base near its standing height for 1 s."""
        with self.make(simulator_cls, robot) as sim:
            state = sim.reset()
            start = state.base_pos[:, 2].clone()
            steps = round(1.0 / sim.control_dt)
            for _ in range(steps):
                state = sim.step(sim.default_joint_pos)
            drop = (start - state.base_pos[:, 2]).abs()
            assert float(drop.max()) < 0.1, f"base height moved by {drop.tolist()} m"

    def test_reset_subset_leaves_others(self, simulator_cls, robot) -> None:
        import torch

        with self.make(simulator_cls, robot) as sim:
            sim.reset()
            targets = sim.default_joint_pos.clone()
            targets[:, 0] += 0.3
            for _ in range(10):
                sim.step(targets)
            before = sim.get_state()
            after = sim.reset(torch.tensor([0]))
            assert torch.allclose(after.joint_pos[1:], before.joint_pos[1:])
            assert torch.allclose(after.base_pos[1:], before.base_pos[1:])
            assert torch.allclose(after.joint_pos[0], sim.default_joint_pos[0], atol=1e-6)

    def test_set_designs_subset(self, simulator_cls, robot) -> None:
        with self.make(simulator_cls, robot) as sim:
            sim.reset()
            new = robot.design_space().sample(1, rng=5)
            sim.set_designs(np.array([1]), new)
            np.testing.assert_allclose(sim.designs[1], new[0])
            state = sim.step(sim.default_joint_pos)
            _assert_state(state, sim.num_envs, sim.num_joints)

    def test_designs_outside_the_space_are_refused_before_anything_changes(
        self, simulator_cls, robot
    ) -> None:
        space = robot.design_space()
        bad = space.upper + 0.5
        with pytest.raises(DesignError) as caught:
            simulator_cls(robot, np.stack([robot.nominal_design(), bad]))
        assert caught.value.field == space.names[0]
        with self.make(simulator_cls, robot) as sim:
            sim.reset()
            before = sim.designs.copy()
            with pytest.raises(DesignError) as caught:
                sim.set_designs(np.array([0, 1]), np.stack([space.lower, bad]))
            assert caught.value.field == space.names[0]
            np.testing.assert_array_equal(
                sim.designs, before
            )  # the good row was not applied either
            _assert_state(sim.step(sim.default_joint_pos), sim.num_envs, sim.num_joints)

    def test_torque_never_exceeds_motor_limit(self, simulator_cls, robot) -> None:
        import torch

        rand = RandomizationConfig(
            friction=(1.0, 1.0),
            restitution=(0.0, 0.0),
            com_shift=(0.0, 0.0),
            delay=(0.0, 0.0),
            pd_factor=(1.1, 1.1),
            motor_strength=(1.1, 1.1),
        )
        with self.make(simulator_cls, robot, randomization=rand) as sim:
            sim.reset()
            limits = torch.as_tensor(
                np.stack([robot.build(d).torque_limit for d in sim.designs]), dtype=torch.float64
            )
            targets = sim.default_joint_pos + 3.0  # far beyond reach
            for _ in range(20):
                state = sim.step(targets)
                assert torch.all(state.joint_torque.abs().double() <= limits * (1 + 1e-6))

    @pytest.mark.parametrize("terrain", ["flat", "slope", "random"])
    def test_terrains_spawn_above_ground(self, simulator_cls, robot, terrain) -> None:
        import torch

        if terrain not in simulator_cls.terrains:
            pytest.skip(f"{simulator_cls.name} does not offer terrain {terrain}")
        with self.make(simulator_cls, robot, terrain=terrain) as sim:
            state = sim.reset()
            assert torch.all(state.foot_pos[..., 2] >= state.terrain_height[:, None] - 0.05)
            state = sim.step(sim.default_joint_pos)
            assert not bool(state.diverged.any())

    def test_reseed_restarts_random_streams(self, simulator_cls, robot) -> None:
        """After `reseed(s)` the randomized resets and trajectory repeat exactly (exact
        resume of co-adaptation runs depends on it)."""
        import torch

        terrain = "random" if "random" in simulator_cls.terrains else "flat"  # spawn points too
        with self.make(
            simulator_cls, robot, randomization=RandomizationConfig(), seed=3, terrain=terrain
        ) as sim:
            finals, frictions, spawns = [], [], []
            for _ in range(2):
                sim.reseed(21)
                spawns.append(sim.reset().base_pos.clone())
                frictions.append(sim.env_params.friction.clone())
                for _ in range(5):
                    state = sim.step(sim.default_joint_pos)
                finals.append(state.joint_pos.clone())
            assert torch.equal(frictions[0], frictions[1])
            assert torch.equal(spawns[0], spawns[1])
            assert torch.equal(finals[0], finals[1])
            sim.reseed(22)
            sim.reset()
            assert not torch.equal(
                sim.env_params.friction, frictions[0]
            )  # a different seed draws anew

    def test_bad_options_are_one_line_user_errors(self, simulator_cls, robot) -> None:
        for option, value in (
            ("terrain", "mars"),
            ("decimation", 0),
            ("physics_dt", -0.005),
            ("num_threads", 0),
        ):
            with pytest.raises(UserError) as info:
                self.make(simulator_cls, robot, **{option: value})
            assert info.value.field == option and "\n" not in str(info.value)
        with self.make(simulator_cls, robot) as sim, pytest.raises(UserError) as info:
            sim.reset(np.array([sim.num_envs]))
        assert info.value.field == "env_ids"

    def test_env_params_are_tensors_on_the_simulators_device(self, simulator_cls, robot) -> None:
        import torch

        with self.make(simulator_cls, robot, randomization=RandomizationConfig()) as sim:
            sim.reset()
            params = sim.env_params
            n = sim.num_envs
            for name, value in vars(params).items():
                assert isinstance(value, torch.Tensor), name
                assert value.device == torch.device(sim.device) and value.dtype == sim.dtype, name
                assert tuple(value.shape) == ((n, 3) if name == "com_shift" else (n,)), name
            assert params.privileged().device == torch.device(sim.device)

    def test_one_seed_draws_the_shared_parameters_and_spawn_points(
        self, simulator_cls, robot
    ) -> None:
        """Construction draws nothing; the first reset draws Table 2 parameters from the
        "params" stream (default_rng(seed)) and, on the random terrain, spawn points from the
        "spawn" stream: the same numbers on every backend."""
        import torch

        terrain = "random" if "random" in simulator_cls.terrains else "flat"
        rand = RandomizationConfig()
        with self.make(simulator_cls, robot, randomization=rand, seed=13, terrain=terrain) as sim:
            state = sim.reset()
            expected = sample_env_params(rand, sim.num_envs, np.random.default_rng(13))
            for name, value in vars(sim.env_params).items():
                assert torch.equal(value.cpu(), getattr(expected, name).to(sim.dtype)), name
            if terrain == "random":
                half = sim.terrain_model.size / 2 - SPAWN_MARGIN
                xy = np.random.default_rng([13, SPAWN_STREAM_KEY]).uniform(
                    -half, half, (sim.num_envs, 2)
                )
                np.testing.assert_allclose(
                    state.base_pos[:, :2].double().cpu().numpy(), xy, atol=1e-5
                )

    def test_torque_is_the_shared_actuation_law(self, simulator_cls, robot) -> None:
        """With decimation 1 the reported torque is `pd_torque` at the state before the step,
        with each environment's own PD factor and motor strength (and the robot's gains and
        motor limits); far targets make the torque-speed envelope clip part of it."""
        import torch

        rand = RandomizationConfig(
            friction=(1.0, 1.0), restitution=(0.0, 0.0), com_shift=(0.0, 0.0), delay=(0.0, 0.0)
        )
        with self.make(
            simulator_cls, robot, randomization=rand, decimation=1, fixed_base=True
        ) as sim:
            state = sim.reset()
            params = sim.env_params
            models = [robot.build(d) for d in sim.designs]
            gains = [
                torch.as_tensor(np.stack([getattr(m, k) for m in models]), dtype=torch.float64)
                for k in ("kp", "kd", "torque_limit", "speed_limit")
            ]
            offsets = torch.linspace(-2.0, 2.0, sim.num_joints, dtype=torch.float64)
            targets = sim.default_joint_pos.double().cpu() + offsets
            for _ in range(3):
                before = state
                state = sim.step(targets.to(sim.default_joint_pos))
                expected = pd_torque(
                    targets,
                    before.joint_pos.double().cpu(),
                    before.joint_vel.double().cpu(),
                    *gains,
                    params.pd_factor.double().cpu(),
                    params.motor_strength.double().cpu(),
                )
                torch.testing.assert_close(
                    state.joint_torque.double().cpu(), expected, rtol=1e-4, atol=2e-2
                )

    def test_same_seed_same_trajectory(self, simulator_cls, robot) -> None:
        import torch

        finals = []
        for _ in range(2):
            with self.make(
                simulator_cls, robot, randomization=RandomizationConfig(), seed=11
            ) as sim:
                sim.reset()
                for _ in range(10):
                    state = sim.step(sim.default_joint_pos)
                finals.append(state.joint_pos.clone())
        assert torch.allclose(finals[0], finals[1])

    def test_model_tools_keep_their_contract(self, simulator_cls, robot) -> None:
        """A backend declaring `model_tools` (coadapt_core.physics.model_tools): the module
        imports, and on the robot's nominal model its link facts name every joint, foot and
        the base and weigh what the model says, its foot positions at the default pose are the
        simulator's own (base frame, the base welded at its spawn point), its
        actuators drive each joint once, and its handoff script, when it has one, exists."""
        import importlib
        from pathlib import Path

        if not simulator_cls.model_tools:
            pytest.skip(f"{simulator_cls.name} declares no model tools")
        tools = importlib.import_module(simulator_cls.model_tools)
        model = robot.build(robot.nominal_design())
        if not set(simulator_cls.model_formats) & set(model.formats):
            pytest.skip(f"{simulator_cls.name} reads none of the robot's model formats")
        facts = tools.link_facts(model)
        names = {link["name"] for link in facts["links"]}
        assert {model.base_body, *model.foot_bodies} <= names
        assert set(model.joint_names) <= {j for link in facts["links"] for j in link["joints"]}
        assert facts["total_mass"] == pytest.approx(model.total_mass, rel=1e-6)
        feet = np.asarray(tools.foot_positions(model, model.default_joint_pos), dtype=float)
        assert feet.shape == (len(model.foot_bodies), 3) and np.all(np.isfinite(feet))
        with self.make(
            simulator_cls, robot, n=1, fixed_base=True
        ) as sim:  # the nominal design, default pose
            state = sim.reset()
            q = state.base_quat[0].double().cpu().numpy()
            inverse = np.array([q[0], -q[1], -q[2], -q[3]])
            rel = (
                (state.foot_pos[0] - state.base_pos[0]).double().cpu().numpy()
            )  # [F, 3] world frame
            own = quat_rotate(np.tile(inverse, (len(rel), 1)), rel)
        np.testing.assert_allclose(
            feet, own, atol=2e-3, err_msg="model tools' feet vs the simulator's, base frame"
        )
        driven = tools.actuated_joints(model)
        assert sorted(d for d in driven if d is not None) == sorted(model.joint_names)
        check = getattr(tools, "HANDOFF_CHECK", None)
        assert check is None or Path(check).is_file(), check
        if check is not None:
            assert tools.handoff_usage(
                {"physics_dt": 0.005, "control_dt": 0.02, "decimation": 4, "control_hz": 50},
                "robot.xml",
            ).strip()
