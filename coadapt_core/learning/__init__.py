"""The learner: PPO (TorchRL ClipPPOLoss + GAE) for the universal policy pi(a | o, xi), its
critic V(s, xi) and the pseudo-critics V_pseudo(s, xi); training across designs,
checkpoints, evaluation and the `UniversalPolicyBackend` of the co-adaptation loop.

Import each name from the module that defines it (`config`, `ppo`, `trainer`, `checkpoints`,
...): a light submodule (the settings in `coadapt_core.learning.config`, which the CLI reads to
build its options) does not pay for torchrl and tensordict."""

__all__ = ["shipped_checkpoint"]


def shipped_checkpoint(robot, terrain: str, mixed: bool = False):
    """The policy a robot plugin ships for a terrain and the continuous (or, `mixed`, the
    mixed) design space, or None: the robot's `Robot.shipped_policy` hook. `robot` is a
    `Robot` instance or a registered robot name."""
    if isinstance(robot, str):
        from coadapt_core.plugins import get_registry

        robot = get_registry().create("robot", robot)
    return robot.shipped_policy(terrain, mixed)
