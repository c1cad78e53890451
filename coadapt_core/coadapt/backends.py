"""The backend factory of a run: the learner's universal policy on the configured simulator
and terrain (`universal_policy_factory`), with the run's train, task and randomization keys
over the starting policy's (`learner_settings`); for a method without a shared policy, a
policy trained per design around it (`specialized_factory`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from coadapt_core.coadapt.config import SECTIONS, CoadaptConfig
from coadapt_core.coadapt.learner_overrides import resolve_learner
from coadapt_core.coadapt.specialized import SpecializedPolicyBackend
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import CoadaptError, UserError
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.objective import Objective
from coadapt_core.robot import Robot
from coadapt_core.settings import overrides


def check_device_available(device: str) -> None:
    """A CUDA device asked for where there is none: one line now, before a run folder exists."""
    if str(device).startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise UserError(
                f"device '{device}' requested but no CUDA device is available; use --device cpu",
                field="device",
            )


def universal_policy_factory(
    config: CoadaptConfig,
    robot: Robot,
    full_space: DesignSpace,
    objectives: Sequence[Objective],
    *,
    shared: bool,
    checkpoint: str | None,
) -> Callable[[int], CoadaptationBackend]:
    """The real backend: the learner's universal policy (`coadapt_core.learning.factory`) on
    the configured simulator and terrain, starting from `checkpoint` (None: from scratch).
    Without a `shared` policy (the BO baseline) it is one design's policy: trained from
    scratch (the paper's) or fine-tuned from the universal policy (`specialized_init:
    universal`), with the universal training's batch (K x agents environments) on that
    design."""
    from coadapt_core.plugins import get_registry

    simulator_cls = get_registry().get("simulator", config.sim)
    try:
        from coadapt_core.learning.factory import make_backend
    except ImportError as exc:
        raise CoadaptError(
            f"the universal-policy learner (coadapt_core.learning) is not available: {exc}"
        ) from None
    agents = config.agents_per_design if shared else config.population * config.agents_per_design
    learner = learner_settings(config, checkpoint)  # the run's train / task / randomization keys

    def factory(seed: int) -> CoadaptationBackend:
        return make_backend(
            robot,
            simulator_cls,
            list(objectives),
            terrain=config.terrain,
            design_space=full_space,
            agents_per_design=agents,
            device=config.device,
            seed=seed,
            checkpoint=checkpoint,
            **learner,
        )

    return factory


def learner_settings(config: CoadaptConfig, checkpoint: str | None) -> dict[str, Any]:
    """The backend's `train_config`, `task_config` and `randomization` where the run sets
    any of them: the starting policy's (the `checkpoint` file's; the defaults without one)
    with the run's keys applied. Sections the run leaves unset are not returned, so the
    backend takes them from the checkpoint as it always has."""
    changed = {name: overrides(getattr(config, name)) for name in SECTIONS}
    if not any(changed.values()):
        return {}
    saved = None
    if checkpoint:
        from coadapt_core.learning.trainer import read_checkpoint

        saved = read_checkpoint(checkpoint)
    return resolve_learner(saved, changed["train"], changed["task"], changed["randomization"])


def specialized_factory(
    config: CoadaptConfig, policy_factory: Callable[[int], CoadaptationBackend]
) -> Callable[[int], CoadaptationBackend]:
    """The backend of a method without a shared policy: `SpecializedPolicyBackend` training
    each design's policy (`policy_factory`) for `specialized_train_steps` interactions."""

    def factory(seed: int) -> CoadaptationBackend:
        return SpecializedPolicyBackend(
            policy_factory, train_steps=config.specialized_train_steps, seed=seed
        )

    return factory
