"""The gait clock and the Raibert reference of the locomotion task (paper 3.2.3): per-leg
phases, the stance schedule, the von Mises swing height, the Raibert foot targets, the
design-aware reference (`task.gait.design_aware`), and `GaitClock`, the clock of a
`LocomotionEnv`'s environments.

Design-aware reference (off by default): every design gets the nominal design's gait in units
of its own leg length L (the robot's hip height at the standing pose, `Robot.hip_height`),
with s = L / L_nominal per environment: the placement clip and the swing apex scale by s, and
the clock's frequency by 1 / sqrt(s), the pendulum frequency sqrt(g / L) of dynamic similarity
(equal Froude number). The nominal design's reference is unchanged; a long leg takes longer,
slower, higher steps, a short one shorter, quicker, lower ones.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import torch

from coadapt_core.task.config import GaitConfig

if TYPE_CHECKING:
    from coadapt_core.robot import Robot

# -- the gait clock and the Raibert reference (paper 3.2.3): Raibert foot placement in x-y, a
# von Mises swing height in z, joint targets q* by the robot's leg IK. Leg l is in stance for
# its phase in [0, 0.5), else swings. Under a moving command the stance foot travels back
# relative to its hip at the commanded speed, from +v T_st / 2 at touchdown to -v T_st / 2 at
# lift-off, and swings forward again to the touchdown point v T_st / 2 + k (v - v_cmd).


def leg_phases(
    phase: torch.Tensor, num_legs: int, offsets: torch.Tensor | None = None
) -> torch.Tensor:
    """[N, L] per-leg phase in [0, 1) from the clock phase [N]: (phase + offsets[l]) mod 1,
    the robot's declared offsets (`Robot.legs()`), or l / L when none are given."""
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
    scale: torch.Tensor | None = None,  # [N] s = L / L_nominal (`gait_scales`); None: 1
) -> torch.Tensor:
    """[N, L, 3] foot targets relative to each hip, base frame; with `scale`, each design's
    stance time, placement clip and swing apex in units of its leg length."""
    gate = command_gate(command, config.command_full_scale)[:, None]  # [N, 1]
    swing = (leg_phase >= 0.5).to(default_feet.dtype)  # [N, L]
    tri = stance_triangle(leg_phase)  # [N, L]
    cmd_xy = command[:, None, :2]  # [N, 1, 2]
    feedback = config.raibert_gain * (base_lin_vel[:, None, :2] - cmd_xy)  # [N, 1, 2]
    if scale is None:  # the same reference for every design (bit for bit as before)
        t_stance = 0.5 / config.frequency
        offset_xy = (
            tri[..., None] * cmd_xy * (t_stance / 2.0) + (swing * gate)[..., None] * feedback
        )
        offset_xy = offset_xy.clamp(-config.raibert_max_offset, config.raibert_max_offset)
        offset_z = gate * von_mises_height(leg_phase, config.swing_height, config.von_mises_kappa)
    else:
        s = scale.to(default_feet.dtype)[:, None, None]  # [N, 1, 1]
        t_stance = 0.5 / clock_frequency(config, s)  # [N, 1, 1]
        offset_xy = (
            tri[..., None] * cmd_xy * (t_stance / 2.0) + (swing * gate)[..., None] * feedback
        )
        bound = config.raibert_max_offset * s
        offset_xy = torch.maximum(torch.minimum(offset_xy, bound), -bound)
        offset_z = (
            gate
            * s[..., 0]
            * von_mises_height(leg_phase, config.swing_height, config.von_mises_kappa)
        )
    target = default_feet.clone()
    target[..., :2] += offset_xy
    target[..., 2] += offset_z
    return target


def gait_scales(
    cfg: GaitConfig, leg_length: torch.Tensor, nominal_leg_length: float
) -> torch.Tensor:
    """[N] s = L / L_nominal of each environment's leg under the design-aware reference, else
    ones (the same reference for every design)."""
    if not cfg.design_aware:
        return torch.ones_like(leg_length)
    return leg_length / float(nominal_leg_length)


def clock_frequency(cfg: GaitConfig, scale: torch.Tensor) -> torch.Tensor:
    """[N] gait clock frequency, Hz: `cfg.frequency` x s^-1/2 (Froude scaling; s = 1: as set)."""
    return cfg.frequency / torch.sqrt(scale)


class GaitClock:
    """The gait clock of N environments: `phase` [N] in [0, 1), each leg's offset [L] (a
    trotting quadruped moves diagonal pairs together), the design-aware `scale` [N] of each
    environment's gait and the feet's `air_time` [N, L], s."""

    def __init__(
        self, cfg: GaitConfig, leg_offsets: torch.Tensor, n: int, dt: float, device: torch.device
    ):
        self.cfg = cfg
        self.dt = dt
        self.leg_offsets = leg_offsets
        self.phase = torch.zeros(n, device=device)
        self.air_time = torch.zeros(n, leg_offsets.numel(), device=device)
        self.scale = torch.ones(n, device=device)

    def rescale(self, default_feet: torch.Tensor, nominal_leg_length: float) -> None:
        """The gait scales of designs whose feet stand at `default_feet` [N, L, 3] (relative
        to the hips): leg length L, the hip height at the standing pose, against the nominal
        design's (1.0 when the reference is not design-aware)."""
        legs = -default_feet[..., 2].mean(dim=-1)
        self.scale = gait_scales(self.cfg, legs, nominal_leg_length)

    def advance(self, moving: torch.Tensor) -> None:
        """One policy step of the clock; `moving` [N]: the command is not zero."""
        cfg = self.cfg
        advance = moving if cfg.freeze_on_zero_command else torch.ones_like(moving)
        frequency = clock_frequency(cfg, self.scale) if cfg.design_aware else cfg.frequency
        self.phase = torch.remainder(self.phase + self.dt * frequency * advance, 1.0)

    def features(self) -> torch.Tensor:
        """[N, 2] the observation's clock: sin and cos of 2 pi phase."""
        angle = 2.0 * math.pi * self.phase
        return torch.stack([torch.sin(angle), torch.cos(angle)], dim=-1)

    def touch_down(self, contact: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(first contact [N, L], air time before this step's touch-downs [N, L]); the
        feet's air clocks advance and restart on contact."""
        first_contact = (self.air_time > 0) & contact
        self.air_time += self.dt
        air_time = self.air_time.clone()
        self.air_time *= ~contact
        return first_contact, air_time

    def reference(
        self,
        robot: Robot,
        designs: torch.Tensor,
        default_feet: torch.Tensor,
        command: torch.Tensor,
        lin_vel: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(q* [N, J], expected stance [N, L]) of the paper's Raibert reference at this phase
        for designs [N, D] standing with their feet at `default_feet`."""
        phases = leg_phases(self.phase, self.leg_offsets.numel(), self.leg_offsets)
        moving = command.abs().sum(dim=-1) > 0
        stance = expected_stance(phases)
        if self.cfg.freeze_on_zero_command:
            stance = stance | ~moving[:, None]
        scale = self.scale if self.cfg.design_aware else None
        feet = raibert_foot_targets(default_feet, phases, command, lin_vel, self.cfg, scale)
        with torch.no_grad():
            q_star = robot.leg_inverse_kinematics(designs, feet).to(command.device).float()
        return q_star, stance
