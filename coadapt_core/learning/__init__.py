"""The learner: PPO (TorchRL ClipPPOLoss + GAE) for the universal policy pi(a | o, xi), its
critic V(s, xi) and the pseudo-critics V_pseudo(s, xi); training across designs,
checkpoints, evaluation and the `UniversalPolicyBackend` of the co-adaptation loop.

Imports torch and torchrl: import it lazily from plugin modules and the CLI."""

from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.ppo import PPO, Dims
from coadapt_core.learning.trainer import (
    IterationStats,
    Trainer,
    read_checkpoint,
    widen_design_input,
)

__all__ = ["PPO", "Dims", "IterationStats", "TrainConfig", "Trainer", "read_checkpoint", "shipped_checkpoint", "widen_design_input"]


def shipped_checkpoint(robot, terrain: str, mixed: bool = False):
    """The policy a robot plugin ships for a terrain and the continuous (or, `mixed`, the
    mixed) design space, or None: the robot's `Robot.shipped_policy` hook. `robot` is a
    `Robot` instance or a registered robot name."""
    if isinstance(robot, str):
        from coadapt_core.plugins import get_registry

        robot = get_registry().create("robot", robot)
    return robot.shipped_policy(terrain, mixed)
