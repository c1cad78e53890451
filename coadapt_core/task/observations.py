"""Observation layouts and the step's record (`StepResult`): the policy observation o (70
values for an 8-joint biped with 5 actions of history), the design input xi and the critic
state s.

Policy observation o, in order (J actuated joints, H = history):

| slice (J=8, H=5) | name              | size | notes                                  |
|------------------|-------------------|------|----------------------------------------|
| 0:3              | base_lin_vel      | 3    | base frame, m/s, noise 0.01            |
| 3:6              | base_ang_vel      | 3    | base frame, rad/s, noise 0.2           |
| 6:9              | projected_gravity | 3    | gravity unit vector in the base frame, noise 0.05 |
| 9:12             | command           | 3    | vx, vy (m/s), yaw rate (rad/s)         |
| 12:20            | joint_pos         | J    | relative to the default pose, noise 0.01 |
| 20:28            | joint_vel         | J    | rad/s, noise 1.5                       |
| 28:68            | action_history    | H*J  | a_{t-1}, a_{t-2}, ... (newest first)   |
| 68:70            | clock             | 2    | sin, cos of 2 pi phase                 |

Design input xi: each design variable mapped linearly from the robot's full design-space
bounds to [-1, 1] (a separate policy input; bounds fixed, so narrowing does not move it).

Critic state s = o without noise, then privileged extras: base height above the terrain (1),
foot contacts (L, 0/1), foot heights above the terrain under the base (L), and the
randomized parameters friction, restitution, PD factor, motor strength, delay (s) and base
CoM shift (3).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch


def policy_layout(num_joints: int, history: int) -> list[tuple[str, int]]:
    return [
        ("base_lin_vel", 3),
        ("base_ang_vel", 3),
        ("projected_gravity", 3),
        ("command", 3),
        ("joint_pos", num_joints),
        ("joint_vel", num_joints),
        ("action_history", history * num_joints),
        ("clock", 2),
    ]


def privileged_layout(num_legs: int) -> list[tuple[str, int]]:
    return [
        ("base_height", 1),
        ("foot_contact", num_legs),
        ("foot_height", num_legs),
        ("friction", 1),
        ("restitution", 1),
        ("pd_factor", 1),
        ("motor_strength", 1),
        ("delay", 1),
        ("com_shift", 3),
    ]


def slices(layout: list[tuple[str, int]]) -> dict[str, slice]:
    """{name: slice} of a layout."""
    out, start = {}, 0
    for name, size in layout:
        out[name] = slice(start, start + size)
        start += size
    return out


def size(layout: list[tuple[str, int]]) -> int:
    return sum(n for _, n in layout)


@dataclass
class StepResult:
    """What `LocomotionEnv.step` returns (also unpackable as a 7-tuple).

    `info` holds: `metrics` [N, M] per-step objective costs (order of the env's
    `objectives`); `final_critic_obs` [N, C] critic state before auto-reset (for
    bootstrapping timeouts); `terminated` [N]; `base_lin_vel`, `base_ang_vel` [N, 3] (base
    frame), `foot_contact` [N, L] and `command` [N, 3] of the step; `half_stance` [N] 1 where
    exactly half of the feet touch the ground (the foot-alternation metric; NaN for an odd
    leg count); `reward_terms` {name: mean weighted value, a 0-dim tensor}; and `episode`
    {name: mean over the episodes that just ended} when any ended.
    """

    obs: torch.Tensor  # [N, num_obs] policy observation after auto-reset (noisy)
    critic_obs: torch.Tensor  # [N, num_critic_obs] critic state after auto-reset
    design_obs: torch.Tensor  # [N, D] normalised design
    reward: torch.Tensor  # [N]
    done: torch.Tensor  # [N] bool, the episode ended (fall or timeout) and was reset
    timeout: torch.Tensor  # [N] bool, ended by the time limit (bootstrap, not a failure)
    info: dict = field(default_factory=dict)

    def __iter__(self):
        return iter(
            (
                self.obs,
                self.critic_obs,
                self.design_obs,
                self.reward,
                self.done,
                self.timeout,
                self.info,
            )
        )
