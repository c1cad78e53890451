"""The simulator-agnostic locomotion task: commands, gait clock, observations (o in R^70,
xi, critic state), rewards (paper Table 1 plus ours), noise, termination, objective metrics."""

from coadapt_core.task.config import (
    EXTRA_REWARD_WEIGHTS,
    PAPER_REWARD_WEIGHTS,
    CommandConfig,
    GaitConfig,
    NoiseConfig,
    RewardConfig,
    TaskConfig,
)
from coadapt_core.task.env import LocomotionEnv, StepResult

__all__ = [
    "EXTRA_REWARD_WEIGHTS",
    "PAPER_REWARD_WEIGHTS",
    "CommandConfig",
    "GaitConfig",
    "LocomotionEnv",
    "NoiseConfig",
    "RewardConfig",
    "StepResult",
    "TaskConfig",
]
