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


def shipped_checkpoint(robot: str, terrain: str, mixed: bool = False):
    """The policy shipped with a built-in robot for a terrain, or None when none is shipped:
    `plugins/robots/<robot>/policies/<terrain>.pt` for the continuous design space,
    `<terrain>-mixed.pt` for the mixed one (discrete variables such as motor types too)."""
    from pathlib import Path

    import coadapt_plugins

    name = f"{terrain}-mixed.pt" if mixed else f"{terrain}.pt"
    path = Path(coadapt_plugins.__file__).parent / "robots" / robot / "policies" / name
    return path if path.is_file() else None
