"""Reward terms of the locomotion task, each a pure function of batched tensors returning
the unweighted value [N]. Paper Table 1 terms first, then ours (see config.py for which is
which and the weights). `combine` applies weights, the dt scaling and the clipping."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from coadapt_core.task.config import RewardConfig


@dataclass
class RewardInputs:
    """One policy step of N environments; velocities in the base frame."""

    command: torch.Tensor  # [N, 3]
    base_lin_vel: torch.Tensor  # [N, 3]
    base_ang_vel: torch.Tensor  # [N, 3]
    projected_gravity: torch.Tensor  # [N, 3]
    joint_pos: torch.Tensor  # [N, J]
    default_joint_pos: torch.Tensor  # [N, J]
    joint_acc: torch.Tensor  # [N, J] finite difference over the policy period
    joint_torque: torch.Tensor  # [N, J]
    action: torch.Tensor  # [N, J] raw policy action a_t
    last_action: torch.Tensor  # [N, J] a_{t-1}
    raibert_targets: torch.Tensor  # [N, J] q* of the Raibert reference
    foot_contact: torch.Tensor  # [N, L] bool
    expected_stance: torch.Tensor  # [N, L] bool, from the gait clock
    first_contact: torch.Tensor  # [N, L] bool, touchdown this step
    air_time: torch.Tensor  # [N, L] s, airborne time that ended (valid where first_contact)
    moving_command: torch.Tensor  # [N] bool, the command is not zero
    terminated: torch.Tensor  # [N] bool, fell this step


# -- paper Table 1 ------------------------------------------------------------------------
def tracking_lin_vel(x: RewardInputs, sigma: float) -> torch.Tensor:
    error = ((x.command[:, :2] - x.base_lin_vel[:, :2]) ** 2).sum(dim=-1)
    return torch.exp(-error / sigma)


def tracking_ang_vel(x: RewardInputs, sigma: float) -> torch.Tensor:
    return torch.exp(-((x.command[:, 2] - x.base_ang_vel[:, 2]) ** 2) / sigma)


def lin_vel_z(x: RewardInputs) -> torch.Tensor:
    return x.base_lin_vel[:, 2] ** 2


def ang_vel_xy(x: RewardInputs) -> torch.Tensor:
    return (x.base_ang_vel[:, :2] ** 2).sum(dim=-1)


def torques(x: RewardInputs) -> torch.Tensor:
    return (x.joint_torque**2).sum(dim=-1)


def orientation(x: RewardInputs) -> torch.Tensor:
    return (x.projected_gravity[:, :2] ** 2).sum(dim=-1)


def dof_acc(x: RewardInputs) -> torch.Tensor:
    return (x.joint_acc**2).sum(dim=-1)


def action_rate(x: RewardInputs) -> torch.Tensor:
    return ((x.action - x.last_action) ** 2).sum(dim=-1)


def default_pos(x: RewardInputs) -> torch.Tensor:
    return ((x.joint_pos - x.default_joint_pos) ** 2).sum(dim=-1)


def raibert(x: RewardInputs) -> torch.Tensor:
    return ((x.joint_pos - x.raibert_targets) ** 2).sum(dim=-1)


# -- ours ---------------------------------------------------------------------------------
def contact_match(x: RewardInputs, mismatch: float) -> torch.Tensor:
    """Mean over feet of +1 (contact as the clock says) or `mismatch`. Under a zero command
    the clock is frozen with both feet in stance, so standing still is what matches."""
    match = x.foot_contact == x.expected_stance
    per_foot = torch.where(match, 1.0, mismatch)
    return per_foot.mean(dim=-1)


def feet_air_time(x: RewardInputs, offset: float) -> torch.Tensor:
    """Sum over touchdowns of (t_air - offset), only under a moving command."""
    value = ((x.air_time - offset) * x.first_contact).sum(dim=-1)
    return value * x.moving_command


def termination(x: RewardInputs) -> torch.Tensor:
    return x.terminated.to(x.command.dtype)


def compute_terms(x: RewardInputs, config: RewardConfig) -> dict[str, torch.Tensor]:
    """Unweighted value [N] of every term whose weight is non-zero."""
    fns = {
        "tracking_lin_vel": lambda: tracking_lin_vel(x, config.tracking_sigma),
        "tracking_ang_vel": lambda: tracking_ang_vel(x, config.tracking_sigma),
        "lin_vel_z": lambda: lin_vel_z(x),
        "ang_vel_xy": lambda: ang_vel_xy(x),
        "torques": lambda: torques(x),
        "orientation": lambda: orientation(x),
        "dof_acc": lambda: dof_acc(x),
        "action_rate": lambda: action_rate(x),
        "default_pos": lambda: default_pos(x),
        "raibert": lambda: raibert(x),
        "contact_match": lambda: contact_match(x, config.contact_mismatch),
        "feet_air_time": lambda: feet_air_time(x, config.air_time_offset),
        "termination": lambda: termination(x),
    }
    return {name: fn() for name, fn in fns.items() if config.weights.get(name, 0.0) != 0.0}


def combine(
    terms: dict[str, torch.Tensor], config: RewardConfig, dt: float
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Total reward [N] and the weighted terms. Every weight is scaled by dt (when
    `scale_by_dt`); the sum of all terms but `termination` is clipped at zero (when
    `clip_at_zero`, walking-notes remedy 5) and the termination penalty added after."""
    scale = dt if config.scale_by_dt else 1.0
    weighted = {name: value * (config.weights[name] * scale) for name, value in terms.items()}
    total = torch.zeros_like(next(iter(terms.values()))) if terms else None
    for name, value in weighted.items():
        if name != "termination":
            total = total + value
    if config.clip_at_zero:
        total = total.clamp(min=0.0)
    if "termination" in weighted:
        total = total + weighted["termination"]
    return total, weighted
