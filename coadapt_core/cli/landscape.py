"""`coadapt landscape`: the real cost over an n x n grid of leg scales, stored as a run."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from coadapt_core.cli.common import choice_help, default_help, fail, plugin_name, resolve


def landscape_line(summary: dict, agents: int, steps: int) -> str:
    """One line: the grid optimum and the nominal design, costs with standard errors,
    improvement with its paired standard error, fall rates."""

    def se(key: str, scale: float = 1.0) -> str:
        value = summary.get(key)
        return "" if value is None else f" +- {scale * value:.2g}"

    def rate(key: str) -> str:
        value = summary.get(key)
        return "-" if value is None else f"{value:.3f}{se(key + '_se')}"

    line = (
        f"landscape {summary['run_id']} ({agents} paired scenarios x {steps} steps per design, "
        f"{summary.get('cost_rule', 'capped')} cost): grid optimum "
        f"{summary['best_design'][:2]} cost {summary['best_cost']:.4g}{se('best_cost_se')} (fall rate {rate('best_fall_rate')}); "
        f"nominal cost {summary['nominal_cost']:.4g}{se('nominal_cost_se')} (fall rate {rate('nominal_fall_rate')}); "
        f"improvement {100 * summary['improvement']:+.1f}{se('improvement_se', 100.0)} %"
    )
    if summary.get("improvement_plain") is not None:
        line += (f"; plain mean (eq. 4) {summary['best_plain_mean']:.4g}{se('best_plain_mean_se')} vs "
                 f"{summary['nominal_plain_mean']:.4g}{se('nominal_plain_mean_se')}, improvement "
                 f"{100 * summary['improvement_plain']:+.1f}{se('improvement_plain_se', 100.0)} %")
    return line


def register(app: typer.Typer) -> None:
    @app.command("landscape")
    def landscape_command(
        objective: str = typer.Option("torque", help=choice_help("objective", "Objective (comma list for several).")),
        grid: int = typer.Option(11, help="Points per axis (grid x grid designs)."),
        terrain: str = typer.Option("flat", help="Terrain: flat, slope or random."),
        sim: str = typer.Option(None, help=default_help("simulator", "Simulator backend.")),
        robot: str = typer.Option(None, help=default_help("robot", "Robot.")),
        checkpoint: Path = typer.Option(None, help="Universal policy checkpoint (default: the robot's shipped policy for the terrain)."),
        agents: int = typer.Option(None, help="Paired scenarios (agents) per design (default: the quick preset's evaluation size)."),
        steps: int = typer.Option(None, help="Policy steps per agent, T_eval (default: the quick preset's)."),
        seed: int = typer.Option(0, help="Random seed."),
        cost_rule: str = typer.Option("capped", "--cost-rule", help="How scenarios make a cost: capped, mean (eq. 4) or trimmed (docs/settings.md)."),
        cost_cap: float = typer.Option(3.0, "--cost-cap", help="capped rule: cap and fall cost in units of the nominal design's median scenario."),
        device: str = typer.Option("cpu", help="Torch device for the policy."),
        resume: str = typer.Option(None, "--resume", help="Continue an interrupted landscape run (its id)."),
        store: str = typer.Option(None, "--store", help="Results store: a path or SQLAlchemy URL (default $COADAPT_STORE or ./coadapt.db)."),
        as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON on the last line."),
    ) -> None:
        """Evaluate the real cost (Algorithm 2) of a grid over the robot's first two design
        variables (Kuafu: thigh and shank scale) with the universal policy; reports draw it as
        a heat-map and mark each method's optimum."""
        from coadapt_core.errors import BackendUnavailable
        from coadapt_core.experiments.landscape import run_landscape
        from coadapt_core.learning.factory import make_backend, resolve_plugins
        from coadapt_core.physics.terrain import TERRAINS
        from coadapt_core.results.recorders import SqliteRecorder

        sim, robot = plugin_name("simulator", sim), plugin_name("robot", robot)
        names = [o.strip() for o in objective.split(",") if o.strip()]
        for name in names:
            resolve("objective", name)
        resolve("simulator", sim)
        robot_cls = resolve("robot", robot)
        if terrain not in TERRAINS:
            fail(f"--terrain '{terrain}' is not one of {', '.join(TERRAINS)}")
        from coadapt_core.fitness import COST_RULES, CostRule

        if cost_rule not in COST_RULES:
            fail(f"--cost-rule '{cost_rule}' is not one of {', '.join(COST_RULES)}")
        if not cost_cap > 1:
            fail(f"--cost-cap must be > 1, got {cost_cap}")
        if grid < 2 or grid > 101:
            fail(f"--grid must be between 2 and 101 points per axis, got {grid}")
        from coadapt_core.coadapt.config import PRESETS

        quick = PRESETS["quick"]
        if agents is None:
            agents = quick.get("eval_agents") or quick["agents_per_design"]
        if steps is None:
            steps = quick["eval_steps"]
        if agents < 1 or steps < 1:
            fail("--agents and --steps must be >= 1")
        from coadapt_core.coadapt.config import check_device

        check_device(device, field="--device")
        if checkpoint is None:
            shipped = robot_cls().shipped_policy(terrain, False)
            if shipped is None:
                fail(f"no --checkpoint given and robot '{robot}' ships no policy for terrain '{terrain}'; "
                     f"train one with `coadapt train --robot {robot} --terrain {terrain}` or pass a run's checkpoint")
            checkpoint = shipped
        elif not checkpoint.exists():
            fail(f"--checkpoint {checkpoint} does not exist")
        else:
            from coadapt_core.learning import read_checkpoint

            trained_for = read_checkpoint(checkpoint).get("robot")  # weights_only=True; one line if not a checkpoint
            if trained_for != robot:
                fail(f"--checkpoint {checkpoint} was trained for robot '{trained_for}', not '{robot}'")
        robot_obj = robot_cls()
        space = robot_obj.design_space()
        try:
            robot_obj, sim_cls, objectives = resolve_plugins(robot_obj, sim, names)
            backend = make_backend(robot_obj, sim_cls, objectives, terrain=terrain, design_space=space,
                                   checkpoint=str(checkpoint), agents_per_design=agents, device=device, seed=seed)
        except BackendUnavailable as exc:
            fail(f"cannot evaluate designs: {exc}")
        low, high = space.lower[:2], space.upper[:2]
        recorder = SqliteRecorder(store)
        config = {"objective": ",".join(names), "terrain": terrain, "sim": sim, "robot": robot, "checkpoint": str(checkpoint),
                  "device": device, "design_space": space.to_dict()}
        if resume:
            if not recorder.store.has_run(resume):
                fail(f"--resume: run '{resume}' is not in store {recorder.url}")
            config["run_id"] = resume

        from coadapt_core.cli.progress import ProgressLine

        with ProgressLine("landscape", grid, unit=" rows") as line:

            def on_row(row: int, total: int) -> None:
                line.update(row + 1, f"{grid} designs a row, {agents} agents x {steps} steps each", total=total)

            summary = run_landscape(
                backend, objectives, recorder, config=config, grid=grid, low=low, high=high,
                nominal=robot_obj.nominal_design(), agents=agents, steps=steps, seed=seed, on_row=on_row,
                rule=CostRule(cost_rule, cost_cap),
            )
        print(landscape_line(summary, agents, steps))
        if as_json:
            print(json.dumps(summary))
