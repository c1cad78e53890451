"""Fakes for the locomotion task and learner tests: a two-legged robot with closed-form leg
kinematics and a deterministic kinematic `Simulator` (not registered) whose base speed
follows the hip-pitch targets, so a policy can learn to track commands in a few seconds.
Real-physics tests use the Kuafu robot on MuJoCo."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from coadapt_core.design_space import Continuous, DesignSpace
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import SimState, Simulator
from coadapt_core.robot import Robot, RobotModel, ValidationReport

DEFAULT_LEG = np.array([0.0, -0.4, 0.8, -0.4])  # hip roll, hip pitch, knee, ankle


class FakeBiped(Robot):
    """Two legs of (hip roll, hip pitch, knee, ankle); thigh 0.35 xi0, shank 0.35 xi1."""

    name = "fake_biped"

    def design_space(self, mixed: bool = False) -> DesignSpace:
        return DesignSpace(
            [Continuous("thigh_scale", 0.5, 1.5), Continuous("shank_scale", 0.5, 1.5)]
        )

    def nominal_design(self, mixed: bool = False) -> np.ndarray:
        return np.array([1.0, 1.0])

    def build(self, design: np.ndarray) -> RobotModel:  # the fake simulator needs no model
        raise NotImplementedError("FakeBiped has no model files")

    def validate(self, design: np.ndarray) -> ValidationReport:
        return ValidationReport(np.asarray(design), [])

    @staticmethod
    def lengths(designs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return 0.35 * designs[:, 0], 0.35 * designs[:, 1]

    def forward_kinematics(self, designs: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        """[n, 2, 3] feet relative to hips for joint angles q [n, 8]."""
        l0, l1 = self.lengths(designs)
        legs = q.view(-1, 2, 4)
        roll, pitch, knee = legs[..., 0], legs[..., 1], legs[..., 2]
        x = l0[:, None] * torch.sin(pitch) + l1[:, None] * torch.sin(pitch + knee)
        down = l0[:, None] * torch.cos(pitch) + l1[:, None] * torch.cos(pitch + knee)
        return torch.stack([x, down * torch.sin(roll), -down * torch.cos(roll)], dim=-1)

    def leg_inverse_kinematics(self, designs: torch.Tensor, foot_pos: torch.Tensor) -> torch.Tensor:
        l0, l1 = (v[:, None] for v in self.lengths(designs))
        x, y, z = foot_pos[..., 0], foot_pos[..., 1], foot_pos[..., 2]
        roll = torch.atan2(y, -z)
        down = torch.sqrt(y**2 + z**2)
        d2 = x**2 + down**2
        cos_knee = ((d2 - l0**2 - l1**2) / (2 * l0 * l1)).clamp(-1.0, 1.0)
        knee = torch.acos(cos_knee)
        pitch = torch.atan2(x, down) - torch.atan2(l1 * torch.sin(knee), l0 + l1 * torch.cos(knee))
        ankle = -(pitch + knee)
        return torch.stack([roll, pitch, knee, ankle], dim=-1).reshape(-1, 8)

    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        q = torch.as_tensor(np.tile(DEFAULT_LEG, 2), dtype=designs.dtype).expand(
            designs.shape[0], 8
        )
        return self.forward_kinematics(designs, q)


class FakeSim(Simulator):
    """Kinematic stand-in: joints follow targets with a first-order lag; the base moves
    forward at 2 x the mean hip-pitch offset from the default pose (m/s per rad), sinks with
    bent knees; a foot is in contact when its knee is less bent than the default + 0.1."""

    name = "fake"

    def __init__(self, robot, designs, **kwargs):
        super().__init__(robot, designs, **kwargs)
        n = self.num_envs
        self.q0 = torch.as_tensor(np.tile(DEFAULT_LEG, 2), dtype=torch.float32).expand(n, 8).clone()
        self.reset()

    @property
    def num_joints(self) -> int:
        return 8

    @property
    def default_joint_pos(self) -> torch.Tensor:
        return self.q0

    def _height(self) -> torch.Tensor:
        designs = torch.as_tensor(self._designs, dtype=torch.float32)
        return -self.robot.default_foot_positions(designs)[..., 2].mean(-1) + 0.05

    def reset(self, env_ids=None) -> SimState:
        n = self.num_envs
        ids = (
            torch.arange(n)
            if env_ids is None
            else torch.as_tensor(np.asarray(env_ids), dtype=torch.long)
        )
        if not hasattr(self, "q"):
            self.q = self.q0.clone()
            self.dq = torch.zeros(n, 8)
            self.pos = torch.zeros(n, 3)
            self.vel = torch.zeros(n, 3)
            self.tau = torch.zeros(n, 8)
        self.q[ids] = self.q0[ids]
        self.dq[ids] = 0.0
        self.pos[ids] = 0.0
        self.pos[ids, 2] = self._height()[ids]
        self.vel[ids] = 0.0
        self.draw_env_params(ids.numpy())
        return self.get_state()

    def step(self, joint_targets: torch.Tensor) -> SimState:
        dt = self.control_dt
        target = joint_targets.float()
        new_q = self.q + 0.5 * (target - self.q)
        self.tau = 100.0 * (target - self.q) - 2.0 * self.dq
        self.dq = (new_q - self.q) / dt
        self.q = new_q
        offset = self.q - self.q0
        self.vel[:, 0] = 2.0 * offset[:, [1, 5]].mean(-1)
        self.vel[:, 2] = 0.0
        self.pos += self.vel * dt
        self.pos[:, 2] = self._height() - 0.3 * offset[:, [2, 6]].abs().mean(-1)
        return self.get_state()

    def set_designs(self, env_ids, designs) -> None:
        self._designs[np.asarray(env_ids)] = designs
        self.reset(env_ids)

    def get_state(self) -> SimState:
        n = self.num_envs
        designs = torch.as_tensor(self._designs, dtype=torch.float32)
        feet = self.robot.forward_kinematics(designs, self.q) + self.pos[:, None, :]
        contact = (self.q[:, [2, 6]] - self.q0[:, [2, 6]]) < 0.1
        quat = torch.zeros(n, 4)
        quat[:, 0] = 1.0
        return SimState(
            base_pos=self.pos.clone(),
            base_quat=quat,
            base_lin_vel=self.vel.clone(),
            base_ang_vel=torch.zeros(n, 3),
            joint_pos=self.q.clone(),
            joint_vel=self.dq.clone(),
            joint_torque=self.tau.clone(),
            foot_pos=feet,
            foot_contact=contact,
            foot_contact_force=contact.float() * 200.0,
            terrain_height=torch.zeros(n),
            diverged=torch.zeros(n, dtype=torch.bool),
        )


@pytest.fixture
def fake_robot() -> FakeBiped:
    return FakeBiped()


@pytest.fixture
def fake_sim_factory(fake_robot):
    def make(
        num_envs: int = 8, designs: np.ndarray | None = None, randomize: bool = False, seed: int = 0
    ):
        if designs is None:
            designs = np.tile(fake_robot.nominal_design(), (num_envs, 1))
        config = RandomizationConfig() if randomize else RandomizationConfig.off()
        return FakeSim(fake_robot, designs, randomization=config, seed=seed)

    return make


@pytest.fixture
def fake_sim_cls(fake_sim_factory):
    """A simulator class over the fake backend with Table 2 randomization off (what the
    learner tests train on)."""
    sim_type = type(fake_sim_factory(1))

    def build(robot, designs, **kwargs):
        kwargs["randomization"] = RandomizationConfig.off()
        return sim_type(robot, designs, **kwargs)

    build.name = "fake"
    return build
