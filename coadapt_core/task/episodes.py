"""The episodes' statistics of a `LocomotionEnv`: per environment, sums over the running
episode (return, tracking, forward speed and command), added at every step on the device,
and what the episodes that end report (`StepResult.info["episode"]`, the command
curriculum's record)."""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass
class EndedEpisodes:
    """What the episodes that ended at one step add up to (host numbers)."""

    count: int
    falls: float
    moving_tracking: float  # the tracking term summed over steps with a moving command
    moving_steps: float
    seconds: float  # their lengths together, s
    report: dict  # `StepResult.info["episode"]`: means over them


class EpisodeSums:
    """Sums [N] over each environment's running episode: `reward`, `tracking` (of the
    unweighted linear tracking term), `moving_tracking` and `moving_steps` (over steps with a
    moving command), `speed` (base-frame vx) and `command` (commanded vx)."""

    def __init__(self, n: int, device: torch.device):
        self.reward = torch.zeros(n, device=device)
        self.tracking = torch.zeros(n, device=device)
        self.moving_tracking = torch.zeros(n, device=device)
        self.moving_steps = torch.zeros(n, device=device)
        self.speed = torch.zeros(n, device=device)
        self.command = torch.zeros(n, device=device)

    def restart(self, ids: torch.Tensor) -> None:
        """Zero the sums of environments `ids` (their new episodes start)."""
        for sums in (
            self.reward,
            self.tracking,
            self.moving_tracking,
            self.moving_steps,
            self.speed,
            self.command,
        ):
            sums[ids] = 0.0

    def add(
        self,
        reward: torch.Tensor,
        tracking: torch.Tensor | None,
        moving: torch.Tensor,
        vx: torch.Tensor,
        command_vx: torch.Tensor,
    ) -> None:
        """Add one step: its reward, tracking term (None when the task has none), whether
        the command moves, forward speed and commanded forward speed, each [N]."""
        self.reward += reward
        if tracking is not None:
            self.tracking += tracking
            self.moving_tracking += tracking * moving
        self.moving_steps += moving.float()
        self.speed += vx
        self.command += command_vx

    def over_ended(
        self, ended: torch.Tensor, terminated: torch.Tensor, lengths: torch.Tensor
    ) -> torch.Tensor:
        """[9] on the device: the sums over the environments that `ended` (float [N]) of
        1, terminated, the return, the length in steps (`lengths` [N], >= 1), and the
        per-step means of tracking, speed and command, then `moving_tracking` and
        `moving_steps`; `ended_episodes` reads them on the host."""
        return torch.stack(
            [
                ended.sum(),
                (terminated.float() * ended).sum(),
                (self.reward * ended).sum(),
                (lengths * ended).sum(),
                (self.tracking / lengths * ended).sum(),
                (self.speed / lengths * ended).sum(),
                (self.command / lengths * ended).sum(),
                (self.moving_tracking * ended).sum(),
                (self.moving_steps * ended).sum(),
            ]
        )


def ended_episodes(values: list[float], count: int, dt: float) -> EndedEpisodes:
    """The record of `count` episodes that ended, from `EpisodeSums.over_ended`'s [9] values
    on the host; `dt` is the policy period, s."""
    total, falls, returns, length, tracking, speed, command, moving_tracking, moving_steps = values
    report = {
        "reward": returns / total,
        "length_s": length / total * dt,
        "tracking_fraction": tracking / total,
        "vx": speed / total,
        "command_vx": command / total,
        "fell": falls / total,
        "count": count,
    }
    return EndedEpisodes(count, falls, moving_tracking, moving_steps, length * dt, report)
