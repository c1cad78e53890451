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


#: the rows of a `LocomotionEnv`'s episode sums [ROWS, N] (`new_sums`), each a sum over
#: every environment's running episode: 0 the return, 1 the unweighted linear tracking term,
#: 2 that term and 3 the step count over steps with a moving command, 4 the base-frame vx,
#: 5 the commanded vx. The env zeroes an environment's column when its episode restarts.
ROWS = 6


def new_sums(n: int, device: torch.device) -> torch.Tensor:
    """[ROWS, N] zero sums for `n` environments."""
    return torch.zeros(ROWS, n, device=device)


def add_step(
    sums: torch.Tensor,
    reward: torch.Tensor,
    tracking: torch.Tensor | None,
    moving: torch.Tensor,
    vx: torch.Tensor,
    command_vx: torch.Tensor,
) -> None:
    """Add one step to `sums` [ROWS, N] in place: its reward, tracking term (None when the task
    has none), whether the command moves, forward speed and commanded forward speed, each
    [N]."""
    total, track, moving_track, moving_steps, speed, command = sums
    total += reward
    if tracking is not None:
        track += tracking
        moving_track += tracking * moving
    moving_steps += moving.float()
    speed += vx
    command += command_vx


def over_ended(
    sums: torch.Tensor, ended: torch.Tensor, terminated: torch.Tensor, lengths: torch.Tensor
) -> torch.Tensor:
    """[9] on the device: the sums over the environments that `ended` (float [N]) of
    1, terminated, the return, the length in steps (`lengths` [N], >= 1), and the
    per-step means of tracking, speed and command, then `moving_tracking` and
    `moving_steps` (of `sums` [ROWS, N]); `ended_episodes` reads them on the host."""
    reward, tracking, moving_tracking, moving_steps, speed, command = sums
    return torch.stack(
        [
            ended.sum(),
            (terminated.float() * ended).sum(),
            (reward * ended).sum(),
            (lengths * ended).sum(),
            (tracking / lengths * ended).sum(),
            (speed / lengths * ended).sum(),
            (command / lengths * ended).sum(),
            (moving_tracking * ended).sum(),
            (moving_steps * ended).sum(),
        ]
    )


def ended_episodes(values: list[float], count: int, dt: float) -> EndedEpisodes:
    """The record of `count` episodes that ended, from `over_ended`'s [9] values
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
