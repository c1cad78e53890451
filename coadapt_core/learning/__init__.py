"""The learner: PPO (TorchRL ClipPPOLoss + GAE) for the universal policy pi(a | o, xi), its
critic V(s, xi) and the pseudo-critics V_pseudo(s, xi); training across designs,
checkpoints, evaluation and the `UniversalPolicyBackend` of the co-adaptation loop.

Imports torch and torchrl when its learner is used (the names below are looked up lazily)."""

from importlib import import_module
from typing import Any

#: what the package exports, imported on first use: importing a light submodule (the
#: settings in `coadapt_core.learning.config`, which the CLI reads to build its options)
#: does not pay for torchrl and tensordict
_EXPORTS = {
    "TrainConfig": "coadapt_core.learning.config",
    "PPO": "coadapt_core.learning.ppo",
    "Dims": "coadapt_core.learning.ppo",
    "IterationStats": "coadapt_core.learning.trainer",
    "Trainer": "coadapt_core.learning.trainer",
    "read_checkpoint": "coadapt_core.learning.checkpoints",
    "widen_design_input": "coadapt_core.learning.checkpoints",
}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'coadapt_core.learning' has no attribute '{name}'")


__all__ = ["PPO", "Dims", "IterationStats", "TrainConfig", "Trainer", "read_checkpoint", "shipped_checkpoint", "widen_design_input"]


def shipped_checkpoint(robot, terrain: str, mixed: bool = False):
    """The policy a robot plugin ships for a terrain and the continuous (or, `mixed`, the
    mixed) design space, or None: the robot's `Robot.shipped_policy` hook. `robot` is a
    `Robot` instance or a registered robot name."""
    if isinstance(robot, str):
        from coadapt_core.plugins import get_registry

        robot = get_registry().create("robot", robot)
    return robot.shipped_policy(terrain, mixed)
