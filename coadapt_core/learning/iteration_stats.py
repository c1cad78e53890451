"""What one training iteration reports (`Trainer.learn`): the sums its rollout keeps while it
runs (`RolloutSums`) and the `IterationStats` made of them, which the runner writes to
progress.jsonl and the trackers."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import torch

if TYPE_CHECKING:
    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.task.env import LocomotionEnv


@dataclass
class IterationStats:
    iteration: int
    total_steps: int
    mean_reward: float  # per-step reward over the rollout
    episode_reward: float  # mean return of the episodes that ended (nan if none)
    episode_length_s: float
    tracking_error: float  # mean |v_xy_cmd - v_xy| over the rollout, m/s
    vx: float  # mean base-frame forward speed over envs with a forward command
    command_vx: float
    alternation: float  # share of steps with exactly half of the feet down (NaN: odd leg count)
    fall_rate: float  # falls per env per second
    command_limit: float  # curriculum half-width
    collect_steps_per_s: float
    update_samples_per_s: float
    physics_share: float
    task_share: float
    learner_share: float
    losses: dict[str, float]
    reward_terms: dict[str, float] = field(default_factory=dict)  # mean weighted value per step

    def to_dict(self) -> dict:
        out = {k: v for k, v in self.__dict__.items() if k not in ("losses", "reward_terms")}
        out.update({f"loss/{k}": v for k, v in self.losses.items()})
        out.update({f"reward/{k}": v for k, v in self.reward_terms.items()})
        return out


@dataclass
class RolloutSums:
    """What one training rollout sums up for its statistics (`Trainer._collect`), on the
    device: no host synchronisation inside the rollout."""

    vx_sum: torch.Tensor  # forward speed over envs with a forward command, on the device
    cmd_sum: torch.Tensor
    vx_count: torch.Tensor
    rewards: list[torch.Tensor] = field(default_factory=list)  # per step
    errors: list[torch.Tensor] = field(default_factory=list)
    alternation: list[torch.Tensor] = field(default_factory=list)
    episodes: list[dict] = field(default_factory=list)
    visited: list[torch.Tensor] = field(default_factory=list)  # critic states
    term_sums: dict[str, torch.Tensor] = field(default_factory=dict)

    @classmethod
    def zeros(cls, device: torch.device) -> RolloutSums:
        return cls(*(torch.zeros((), device=device) for _ in range(3)))

    def add_step(self, reward: torch.Tensor, info: dict) -> None:
        """Add one step's reward [N] and the statistics in its `StepResult.info`."""
        self.rewards.append(reward.mean())
        lin, command = info["base_lin_vel"], info["command"]
        self.errors.append((command[:, :2] - lin[:, :2]).norm(dim=-1).mean())
        self.alternation.append(info["half_stance"].mean())
        forward = (command[:, 0] > 0.1).float()
        self.vx_sum += (lin[:, 0] * forward).sum()
        self.cmd_sum += (command[:, 0] * forward).sum()
        self.vx_count += forward.sum()
        for name, value in info["reward_terms"].items():
            self.term_sums[name] = self.term_sums.get(name, 0.0) + value
        if "episode" in info:
            self.episodes.append(info["episode"])


@dataclass
class IterationClock:
    """Where one iteration's wall seconds went: collecting (of which `physics` inside the
    simulator and `task` in the rest of the environment's step) and updating."""

    collect: float
    update: float
    physics: float
    task: float


def iteration_stats(
    sums: RolloutSums,
    losses: dict,
    clock: IterationClock,
    *,
    env: LocomotionEnv,
    config: TrainConfig,
    iteration: int,
    total_steps: int,
) -> IterationStats:
    """The statistics of one iteration of `config.steps_per_env` steps on `env`."""
    episodes = sums.episodes
    samples = env.num_envs * config.steps_per_env
    total = clock.collect + clock.update
    physics, task = clock.physics, clock.task
    falls = sum(e["fell"] * e["count"] for e in episodes)
    vx_count = sums.vx_count
    return IterationStats(
        iteration=iteration,
        total_steps=total_steps,
        mean_reward=float(torch.stack(sums.rewards).mean()),
        episode_reward=_weighted_mean(episodes, "reward"),
        episode_length_s=_weighted_mean(episodes, "length_s"),
        tracking_error=float(torch.stack(sums.errors).mean()),
        vx=float(sums.vx_sum / vx_count) if float(vx_count) > 0 else float("nan"),
        command_vx=float(sums.cmd_sum / vx_count) if float(vx_count) > 0 else float("nan"),
        alternation=float(torch.stack(sums.alternation).mean()),
        fall_rate=falls / (env.num_envs * config.steps_per_env * env.dt),
        command_limit=float(env.commands.limit),
        collect_steps_per_s=samples / clock.collect,
        update_samples_per_s=samples * config.epochs / clock.update,
        physics_share=physics / total,
        task_share=task / total,
        learner_share=1.0 - (physics + task) / total,
        losses=losses,
        reward_terms={k: float(v) / config.steps_per_env for k, v in sums.term_sums.items()},
    )


def _weighted_mean(episodes: list[dict], key: str) -> float:
    """Mean of an episode statistic over the episodes that ended (nan when none did)."""
    count = sum(e["count"] for e in episodes)
    return sum(e[key] * e["count"] for e in episodes) / count if count else float("nan")
