"""`coadapt landscape`: the real cost over an n x n grid of leg scales, stored as a run."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common import ctrl_c_once, fail, interrupted, invocation, resolve
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import options_of, settings_from
from coadapt_core.cli.options import register as register_command
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.plugins import default_plugin
from coadapt_core.settings import Int, setting, settings, shared
from coadapt_core.threads import apply_threads


@settings
class LandscapeSettings:
    """Every setting of `coadapt landscape`: each field is an option (`--cost-cap`); the
    settings it shares with `coadapt run` are `CoadaptConfig`'s own declarations."""

    objective: str = setting(
        default_factory=lambda: default_plugin("objective"),
        plugin="objective",
        help="Objective (comma list for several).",
    )
    grid: Int = setting(11, "Points per axis (grid x grid designs).", ge=2, le=101)
    terrain: Any = shared(CoadaptConfig)
    sim: Any = shared(CoadaptConfig)
    robot: Any = shared(CoadaptConfig)
    checkpoint: str = setting(
        "", "Universal policy checkpoint (default: the robot's shipped policy for the terrain)."
    )
    agents: Int | None = setting(
        None,
        "Paired scenarios (agents) per design (default: the quick preset's evaluation size).",
        ge=1,
    )
    steps: Int | None = setting(
        None, "Policy steps per agent, T_eval (default: the quick preset's).", ge=1
    )
    seed: Any = shared(CommonOptions)
    cost_rule: Any = shared(CoadaptConfig)
    cost_cap: Any = shared(CoadaptConfig)
    device: Any = shared(CoadaptConfig)
    threads: Any = shared(CommonOptions)
    store: Any = shared(CommonOptions)
    resume: str | None = setting(None, "Continue an interrupted landscape run (its id).")
    as_json: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)

    @property
    def objectives(self) -> list[str]:
        return [o.strip() for o in self.objective.split(",") if o.strip()]


def landscape_line(summary: dict, agents: int, steps: int, unit: str = "") -> str:
    """One line: the grid optimum and the nominal design, costs (in `unit`, the first
    objective's) with standard errors, improvement with its paired standard error, fall rates,
    and the protocol the costs belong to."""
    from coadapt_core.cli.run_summary import better_by  # improvements in one direction (issue 43)

    def se(key: str, scale: float = 1.0) -> str:
        value = summary.get(key)
        return "" if value is None else f" +- {scale * value:.2g}"

    def rate(key: str) -> str:
        value = summary.get(key)
        return "-" if value is None else f"{value:.3f}{se(key + '_se')}"

    unit = f" {unit}" if unit else ""
    line = (
        f"landscape {summary['run_id']} (costs{unit} per step over {agents} paired scenarios x "
        f"{steps} steps per design, {summary.get('cost_rule', 'capped')} cost: the landscape's "
        "protocol, comparable within it, not with `coadapt run`'s final check): grid optimum "
        f"{summary['best_design'][:2]} cost {summary['best_cost']:.4g}{se('best_cost_se')}{unit} "
        f"(fall rate {rate('best_fall_rate')}); nominal cost "
        f"{summary['nominal_cost']:.4g}{se('nominal_cost_se')}{unit} (fall rate "
        f"{rate('nominal_fall_rate')}); improvement: "
        f"{better_by(summary['improvement'], summary.get('improvement_se'))}"
    )
    if summary.get("improvement_plain") is not None:
        line += (
            f"; plain mean (eq. 4) {summary['best_plain_mean']:.4g}{se('best_plain_mean_se')} vs "
            f"{summary['nominal_plain_mean']:.4g}{se('nominal_plain_mean_se')}, improvement: "
            f"{better_by(summary['improvement_plain'], summary.get('improvement_plain_se'))}"
        )
    return line


def with_resume(argv: list[str], run_id: str) -> list[str]:
    """The command's arguments with `--resume <run_id>` in place of any --resume given."""
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
            continue
        if arg == "--resume":
            skip = True
            continue
        if arg.startswith("--resume="):
            continue
        out.append(arg)
    return [*out, "--resume", run_id]


def _checkpoint(s: LandscapeSettings, robot_cls: type) -> Path:
    """The policy the landscape evaluates: --checkpoint (made for this robot), else the one
    the robot ships for the terrain; one line and exit 2 otherwise."""
    if not s.checkpoint:
        shipped = robot_cls().shipped_policy(s.terrain, False)
        if shipped is None:
            fail(
                f"no --checkpoint given and robot '{s.robot}' ships no policy for terrain "
                f"'{s.terrain}'; train one with `coadapt train --robot {s.robot} --terrain "
                f"{s.terrain}` or pass a run's checkpoint"
            )
        return Path(shipped)
    checkpoint = Path(s.checkpoint)
    if not checkpoint.exists():
        fail(f"--checkpoint {checkpoint} does not exist")
    from coadapt_core.learning.checkpoints import read_checkpoint

    state = read_checkpoint(checkpoint)  # weights_only=True; one line if not a checkpoint
    trained_for = state.get("robot")
    if trained_for != s.robot:
        fail(f"--checkpoint {checkpoint} was trained for robot '{trained_for}', not '{s.robot}'")
    takes = (state.get("dims") or {}).get("num_design")
    wanted = robot_cls().design_space(False).dim
    if takes is not None and int(takes) != wanted:  # e.g. a policy of the mixed space
        fail(
            f"--checkpoint {checkpoint} takes {int(takes)} design values; the landscape maps "
            f"{s.robot}'s continuous design space of {wanted}: give a policy trained without "
            "--mixed"
        )
    return checkpoint


def _evaluation_size(s: LandscapeSettings) -> tuple[int, int]:
    """(agents, steps): the settings', else the quick preset's evaluation size."""
    from coadapt_core.coadapt.config import PRESETS

    quick = PRESETS["quick"]
    agents = (
        s.agents
        if s.agents is not None
        else (quick.get("eval_agents") or quick["agents_per_design"])
    )
    return agents, s.steps if s.steps is not None else quick["eval_steps"]


def _prepare(s: LandscapeSettings, resume: str | None) -> dict[str, Any]:
    """Everything the landscape runs with, checked (one line and exit 2 otherwise): backend,
    objectives, design space, recorder, recorded config and evaluation size."""
    from coadapt_core.errors import BackendUnavailable
    from coadapt_core.learning.factory import make_backend, resolve_plugins
    from coadapt_core.results.recorders import SqliteRecorder

    for name in s.objectives:
        resolve("objective", name)
    resolve("simulator", s.sim)
    robot_cls = resolve("robot", s.robot)
    agents, steps = _evaluation_size(s)
    checkpoint = _checkpoint(s, robot_cls)
    robot_obj = robot_cls()
    space = robot_obj.design_space()
    try:
        robot_obj, sim_cls, objectives = resolve_plugins(robot_obj, s.sim, s.objectives)
        backend = make_backend(
            robot_obj,
            sim_cls,
            objectives,
            terrain=s.terrain,
            design_space=space,
            checkpoint=str(checkpoint),
            agents_per_design=agents,
            device=s.device,
            seed=s.seed,
        )
    except BackendUnavailable as exc:
        fail(f"cannot evaluate designs: {exc}")
    recorder = SqliteRecorder(s.store or None)
    config = {
        "objective": ",".join(s.objectives),
        "terrain": s.terrain,
        "sim": s.sim,
        "robot": s.robot,
        "checkpoint": str(checkpoint),
        "device": s.device,
        "design_space": space.to_dict(),
        "threads": s.threads,
    }
    if resume:
        if not recorder.store.has_run(resume):
            fail(f"--resume: run '{resume}' is not in store {recorder.url}")
        config["run_id"] = resume
    return dict(
        backend=backend,
        objectives=objectives,
        recorder=recorder,
        config=config,
        low=space.lower[:2],
        high=space.upper[:2],
        nominal=robot_obj.nominal_design(),
        agents=agents,
        steps=steps,
    )


def _run(s: LandscapeSettings, job: dict[str, Any]) -> dict[str, Any]:
    """Run the landscape with a progress line; Ctrl-C says how to resume it."""
    from coadapt_core.cli.progress import ProgressLine
    from coadapt_core.costs import CostRule
    from coadapt_core.experiments.landscape import run_landscape

    started: list[str] = []
    argv = invocation()
    agents, steps, recorder = job["agents"], job["steps"], job["recorder"]
    with (
        ctrl_c_once(),
        ProgressLine("landscape", s.grid, unit=" rows", enabled=not s.quiet) as line,
    ):

        def on_row(row: int, total: int) -> None:
            line.update(
                row + 1,
                f"{s.grid} designs a row, {agents} agents x {steps} steps each",
                total=total,
            )

        def on_start(run_id: str) -> None:
            started.append(run_id)
            print(f"landscape {run_id}: store {recorder.url}", file=sys.stderr, flush=True)

        try:
            return run_landscape(
                job["backend"],
                job["objectives"],
                recorder,
                config=job["config"],
                grid=s.grid,
                low=job["low"],
                high=job["high"],
                nominal=job["nominal"],
                agents=agents,
                steps=steps,
                seed=s.seed,
                on_row=on_row,
                rule=CostRule(s.cost_rule, s.cost_cap),
                on_start=on_start,
            )
        except KeyboardInterrupt:
            line.close()
            if not started:
                interrupted("the landscape had not started; nothing to resume", None)
            interrupted(
                f"landscape {started[0]} stopped; its finished rows are stored and the store marks "
                "it interrupted",
                shlex.join(["coadapt", *with_resume(argv, started[0])]),
            )


def register(app: typer.Typer) -> None:
    options = options_of(LandscapeSettings)

    def landscape_command(**values: Any) -> None:
        """Evaluate the real cost (Algorithm 2) of a grid over the robot's first two design
        variables (Kuafu: thigh and shank scale) with the universal policy; reports draw it as
        a heat-map and mark each method's optimum."""
        s = settings_from(LandscapeSettings, values, options)
        s.threads = apply_threads(s.threads)  # physics and torch alike; recorded with the run
        job = _prepare(s, s.resume)
        summary = _run(s, job)
        print(
            landscape_line(
                summary, job["agents"], job["steps"], getattr(job["objectives"][0], "unit", "")
            )
        )
        if s.as_json:
            print(json.dumps(summary))

    register_command(app, "landscape", landscape_command, options)
