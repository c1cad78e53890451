"""The gait clock and the foot-trajectory reference of the paper's Raibert term
(section 3.2.3): Raibert foot placement in x-y and a von Mises swing height in z, turned into
joint targets q* by the robot's leg inverse kinematics.

Leg l has phase (phase + offset_l) mod 1, offset_l from the robot's `legs()` (default
l / L); it is in stance for phase in [0, 0.5) and swings in [0.5, 1). Under a moving command the stance foot travels backwards relative to its hip at
the commanded speed, from +v T_st / 2 at touchdown to -v T_st / 2 at lift-off, and swings
forward again to the Raibert touchdown point v T_st / 2 + k (v - v_cmd).
"""

from __future__ import annotations

import math

import torch

from coadapt_core.task.config import GaitConfig


def leg_phases(phase: torch.Tensor, num_legs: int, offsets: torch.Tensor | None = None) -> torch.Tensor:
    """[N, L] per-leg phase in [0, 1) from the clock phase [N]: leg l's is
    (phase + offsets[l]) mod 1, with the robot's declared offsets (`Robot.legs()`), or evenly
    spread ones (l / L) when none are given."""
    if offsets is None:
        offsets = torch.arange(num_legs, device=phase.device, dtype=phase.dtype) / num_legs
    offsets = offsets.to(device=phase.device, dtype=phase.dtype)
    return torch.remainder(phase[:, None] + offsets[None, :], 1.0)


def half_stance(contact: torch.Tensor) -> torch.Tensor:
    """[N] float from foot contacts [N, L]: 1 where exactly half of the feet touch the ground
    (one of a biped's two; two of a trotting quadruped's four), else 0 — the share of such
    steps is the "foot alternation" metric. It does not apply to an odd number of legs: NaN."""
    legs = contact.shape[-1]
    if legs % 2:
        return torch.full(contact.shape[:-1], float("nan"), device=contact.device)
    return (contact.sum(dim=-1) == legs // 2).float()


def expected_stance(leg_phase: torch.Tensor) -> torch.Tensor:
    """[N, L] bool: the clock puts this foot on the ground."""
    return leg_phase < 0.5


def stance_triangle(leg_phase: torch.Tensor) -> torch.Tensor:
    """[N, L] +1 at touchdown, -1 at lift-off, linear through stance and back through swing."""
    return torch.where(leg_phase < 0.5, 1.0 - 4.0 * leg_phase, -1.0 + 4.0 * (leg_phase - 0.5))


def von_mises_height(leg_phase: torch.Tensor, apex: float, kappa: float) -> torch.Tensor:
    """[N, L] swing height: a von Mises bump centred on mid-swing (phase 0.75), apex at 1.
    Normalised so the peak is `apex` and the bump is ~0 (exp(-2 kappa)) at mid-stance."""
    return apex * torch.exp(kappa * (torch.cos(2.0 * math.pi * (leg_phase - 0.75)) - 1.0))


def command_gate(command: torch.Tensor, full_scale: float) -> torch.Tensor:
    """[N] in [0, 1]: how much of the stepping reference a command asks for (0 when still)."""
    speed = command[:, :2].norm(dim=-1) + 0.5 * command[:, 2].abs()
    return torch.clamp(speed / full_scale, 0.0, 1.0)


def raibert_foot_targets(
    default_feet: torch.Tensor,  # [N, L, 3] feet relative to hips at the standing pose, base frame
    leg_phase: torch.Tensor,  # [N, L]
    command: torch.Tensor,  # [N, 3]
    base_lin_vel: torch.Tensor,  # [N, 3] base frame
    config: GaitConfig,
) -> torch.Tensor:
    """[N, L, 3] foot targets relative to each hip, base frame."""
    t_stance = 0.5 / config.frequency
    gate = command_gate(command, config.command_full_scale)[:, None]  # [N, 1]
    swing = (leg_phase >= 0.5).to(default_feet.dtype)  # [N, L]
    tri = stance_triangle(leg_phase)  # [N, L]
    cmd_xy = command[:, None, :2]  # [N, 1, 2]
    feedback = config.raibert_gain * (base_lin_vel[:, None, :2] - cmd_xy)  # [N, 1, 2]
    offset_xy = tri[..., None] * cmd_xy * (t_stance / 2.0) + (swing * gate)[..., None] * feedback
    offset_xy = offset_xy.clamp(-config.raibert_max_offset, config.raibert_max_offset)
    offset_z = gate * von_mises_height(leg_phase, config.swing_height, config.von_mises_kappa)
    target = default_feet.clone()
    target[..., :2] += offset_xy
    target[..., 2] += offset_z
    return target
