"""Conformance suite for `Simulator` plugins.

Supply fixtures `robot` (a Robot instance) and `simulator_cls` (the Simulator class). The
suite builds small batches (a few environments) of the robot's designs.
"""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import SimState, Simulator
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
    assert torch.allclose(state.base_quat.norm(dim=-1), torch.ones(n, dtype=state.base_quat.dtype), atol=1e-4)


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

    def test_torque_never_exceeds_motor_limit(self, simulator_cls, robot) -> None:
        import torch

        rand = RandomizationConfig(
            friction=(1.0, 1.0), restitution=(0.0, 0.0), com_shift=(0.0, 0.0), delay=(0.0, 0.0),
            pd_factor=(1.1, 1.1), motor_strength=(1.1, 1.1),
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

        with self.make(simulator_cls, robot, randomization=RandomizationConfig(), seed=3) as sim:
            finals, frictions = [], []
            for _ in range(2):
                sim.reseed(21)
                sim.reset()
                frictions.append(sim.env_params.friction.copy())
                for _ in range(5):
                    state = sim.step(sim.default_joint_pos)
                finals.append(state.joint_pos.clone())
            np.testing.assert_array_equal(frictions[0], frictions[1])
            assert torch.equal(finals[0], finals[1])

    def test_same_seed_same_trajectory(self, simulator_cls, robot) -> None:
        import torch

        finals = []
        for _ in range(2):
            with self.make(simulator_cls, robot, randomization=RandomizationConfig(), seed=11) as sim:
                sim.reset()
                for _ in range(10):
                    state = sim.step(sim.default_joint_pos)
                finals.append(state.joint_pos.clone())
        assert torch.allclose(finals[0], finals[1])
