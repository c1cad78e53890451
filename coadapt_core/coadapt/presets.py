"""The presets of `coadapt run` (`--preset`): the settings each one changes, as plain data,
so that a mistyped preset is refused (`check_preset`) before the config's settings classes load
(`coadapt_core.coadapt.config`, which declares the defaults these override)."""

from __future__ import annotations

from typing import Any

from coadapt_core.errors import UserError, did_you_mean

#: presets: only the fields that differ from the dataclass defaults (which are the paper's)
PRESETS: dict[str, dict[str, Any]] = {
    # seconds on a laptop: for tests and for checking that everything is wired
    "smoke": dict(
        outer_iterations=2,
        population=4,
        optimizer_iterations=2,
        agents_per_design=2,
        train_steps=400,
        retrain_steps=200,
        eval_steps=20,
        surrogate_samples=64,
        bo_designs=2,
        specialized_train_steps=200,
    ),
    # meaningful on a 2-core laptop in <= 30 min, starting from the shipped universal policy.
    # Real evaluation 32 paired scenarios x 250 steps per design (8,000 interactions, as many as
    # the 16 x 500 before): the smallest size measured to rank a 5 x 5 grid alike under two
    # scenario seeds (Spearman 0.95-0.97 for tracking, power, torque; benchmarks/fitness_noise.py).
    # The surrogate: 1 024 buffer states, ranking as 4 096 did (docs/training.md, issue 25)
    "quick": dict(
        outer_iterations=3,
        population=16,
        optimizer_iterations=5,
        agents_per_design=16,
        train_steps=200_000,
        retrain_steps=100_000,
        eval_agents=32,
        eval_steps=250,
        surrogate_samples=1024,
        bo_designs=20,
        specialized_train_steps=100_000,
        specialized_init="universal",
    ),
    # section 4.1.3 (N = 3, K = 100, J = 5, 50 agents, w = 0.5): the declared defaults below are
    # the paper's, and so are the optimizer plugin's declared options
    "paper": dict(surrogate_probability=0.5),
}


def check_preset(preset: str | None) -> None:
    """A preset name that is none of `PRESETS` is a one-line `UserError` naming the nearest."""
    if preset is not None and preset not in PRESETS:
        raise UserError(
            f"preset '{preset}' is not one of {', '.join(PRESETS)}{did_you_mean(preset, PRESETS)}",
            field="preset",
        )
