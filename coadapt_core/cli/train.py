"""`coadapt train` and `coadapt eval`: the universal locomotion policy."""

from __future__ import annotations

import typer

from coadapt_core.cli.common import not_available


def register(app: typer.Typer) -> None:
    @app.command("train")
    def train_command() -> None:
        """Train the universal policy pi(a|o, xi) with its critic and pseudo-critics (PPO)."""
        not_available("train", "the locomotion task and PPO learner (issue 5)")

    @app.command("eval")
    def eval_command() -> None:
        """Roll out a policy on one design and report survival, speed and costs."""
        not_available("eval", "the locomotion task and PPO learner (issue 5)")
