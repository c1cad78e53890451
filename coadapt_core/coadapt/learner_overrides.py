"""The learner's settings of a run: a starting policy's train, task and randomization
settings (or the defaults) with the run's overrides applied (`resolve_learner`).
`coadapt run` and `coadapt train` both resolve their learner here."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coadapt_core.learning.config import TrainConfig
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.settings import apply_overrides
from coadapt_core.task.config import TaskConfig


def resolve_learner(
    saved: Mapping[str, Any] | None,
    train: dict[str, Any],
    task: dict[str, Any],
    randomization: dict[str, Any],
    fresh: TrainConfig | None = None,
    fresh_task: TaskConfig | None = None,
) -> dict[str, Any]:
    """`train_config`, `task_config` and `randomization` for the learner: a checkpoint's
    (`saved`, None: the defaults) with the given nested overrides applied; only the parts
    with overrides are returned. A randomization `preset` replaces the checkpoint's before
    single ranges apply; the train config records both (`extra`), so a resumed training
    draws the same ranges. `fresh`, `fresh_task`: the train and task configs a run without
    `saved` starts from (default: TrainConfig's and TaskConfig's defaults)."""
    out: dict[str, Any] = {}
    saved_train = (
        TrainConfig.from_dict(saved["train_config"]) if saved else (fresh or TrainConfig())
    )
    randomization = dict(randomization)
    preset = randomization.pop("preset", None)
    if train or preset or randomization:
        config = apply_overrides(saved_train, train)
        extra = dict(config.extra)
        if preset:
            extra.update(randomization=preset, randomization_ranges={})
        if randomization:
            extra["randomization_ranges"] = {
                **extra.get("randomization_ranges", {}),
                **randomization,
            }
        config.extra = extra
        out["train_config"] = config
        if preset or randomization:
            out["randomization"] = RandomizationConfig.recorded(extra)
    if task:
        out["task_config"] = apply_overrides(
            TaskConfig.from_dict(saved["task_config"]) if saved else (fresh_task or TaskConfig()),
            task,
        )
    return out
