"""`coadapt run`: the co-adaptation loop (Algorithm 4) on one robot, simulator and objective."""

from __future__ import annotations

import typer

from coadapt_core.cli.common import choice_help, not_available, resolve


def register(app: typer.Typer) -> None:
    @app.command("run")
    def run_command(
        optimizer: str = typer.Option("pso", help=choice_help("optimizer", "Design optimizer.")),
        sim: str = typer.Option("mujoco", help=choice_help("simulator", "Simulator backend.")),
        objective: str = typer.Option("torque", help=choice_help("objective", "Objective to minimise.")),
        robot: str = typer.Option("kuafu", help=choice_help("robot", "Robot.")),
        terrain: str = typer.Option("flat", help="Terrain: flat, slope or random."),
        seed: int = typer.Option(0, help="Random seed."),
    ) -> None:
        """Co-adapt design and policy: universal policy + pseudo-critics, PSO with hybrid
        real/surrogate fitness, range narrowing (paper Algorithm 4)."""
        for kind, name in (("optimizer", optimizer), ("simulator", sim), ("objective", objective), ("robot", robot)):
            resolve(kind, name)
        not_available("run", "the co-adaptation loop (issue 6: objectives, fitness, optimizers, Algorithm 4)")
