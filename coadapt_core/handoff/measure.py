"""What a handoff measures: the design walking under its specialised policy (the
observations the ONNX check replays), fresh paired evaluations against the nominal design
per simulator, the run's own final check, the folder's check.py run once, and the GIF."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.errors import BackendUnavailable, CoadaptError, UserError

#: observations of the design's own rollout recorded for the ONNX check (agents x steps)
ROLLOUT_AGENTS, ROLLOUT_STEPS = 4, 100
#: evaluation-buffer rows of the run used for the ONNX check, at most
BUFFER_ROWS = 2000


# -- recorded observations -------------------------------------------------------------------
def buffer_observations(run_dir: Path, num_obs: int) -> np.ndarray:
    """[n, num_obs] policy observations (noise-free) from the run's newest evaluation buffer."""
    from coadapt_core.statefile import read_npz

    found = sorted(
        run_dir.glob("buffer-*.npz"),
        key=lambda p: int("".join(c for c in p.stem if c.isdigit()) or 0),
    )
    if not found:
        return np.zeros((0, num_obs), dtype=np.float32)
    try:
        buffer = read_npz(found[-1], what="evaluation buffer")
    except CoadaptError:
        return np.zeros((0, num_obs), dtype=np.float32)
    rows = getattr(buffer, "critic_obs", None)
    if rows is None or rows.ndim != 2 or rows.shape[1] < num_obs:
        return np.zeros((0, num_obs), dtype=np.float32)
    rows = np.asarray(rows[:, :num_obs], dtype=np.float32)
    if len(rows) > BUFFER_ROWS:
        rows = rows[np.random.default_rng(0).choice(len(rows), BUFFER_ROWS, replace=False)]
    return rows


def rollout(
    robot: Any,
    sim_cls: type,
    design: np.ndarray,
    state: dict[str, Any],
    terrain: str,
    seed: int,
) -> dict[str, Any]:
    """The design walking under the specialised policy on the run's simulator with the
    training randomization and observation noise, commands drawn from the trained box:
    the observations it saw [ROLLOUT_AGENTS * ROLLOUT_STEPS, num_obs], its design input,
    default pose, rates, and the simulator's foot facts."""
    import torch

    from coadapt_core.handoff.policy import SpecialisedPolicy
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.task.config import TaskConfig
    from coadapt_core.task.env import LocomotionEnv

    task = TaskConfig.from_dict(state["task_config"])
    randomization = RandomizationConfig.recorded(state["train_config"].get("extra") or {})
    sim = sim_cls(
        robot,
        np.tile(design, (ROLLOUT_AGENTS, 1)),
        terrain=terrain,
        randomization=randomization,
        seed=seed,
    )
    try:
        env = LocomotionEnv(sim, robot, task, [], seed=seed)
        if state.get("commands"):
            env.commands.load_state_dict(state["commands"])
        design_obs = env.design_obs[0].cpu().numpy()
        default = env.default_joint_pos[0].cpu().numpy()
        policy = SpecialisedPolicy(state, design_obs, default, task.action_scale, task.action_clip)
        obs, _, _ = env.reset()
        seen = []
        with torch.no_grad():
            for _ in range(ROLLOUT_STEPS):
                seen.append(obs.float().cpu().numpy())
                actions, _ = policy(obs.float().cpu())
                obs = env.step(actions).obs
        return {
            "obs": np.concatenate(seen).astype(np.float32),
            "design_obs": design_obs,
            "default_joint_pos": default,
            "physics_dt": float(sim.physics_dt),
            "decimation": int(sim.decimation),
            "control_dt": float(sim.control_dt),
            "policy": policy,
            "task": task,
            "randomization": randomization,
        }
    finally:
        sim.close()


# -- evaluation ------------------------------------------------------------------------------------
def evaluate_on(
    simulator: str,
    *,
    robot: Any,
    checkpoint: Path,
    objectives: list[str],
    design: np.ndarray,
    nominal: np.ndarray,
    terrain: str,
    seed: int,
    agents: int,
    steps: int | None,
    config: dict[str, Any] | None = None,
    nominal_checkpoint: Path | None = None,
) -> dict[str, Any]:
    """The design against the nominal one on `simulator` under the sim-to-sim protocol that
    `coadapt report` uses (`coadapt_core.sim_to_sim`: `agents` paired scenarios of `steps`
    policy steps, default the run's evaluation length, the run's cost rule and fall gate):
    costs with standard errors, plain means, fall rates, the paired improvements and the
    protocol's one line (`sim_to_sim`). Both designs run under the run's policy
    `checkpoint`, or, given a different `nominal_checkpoint` (a run without a shared policy),
    each under its own on the same scenarios."""
    from coadapt_core import sim_to_sim
    from coadapt_core.costs import CostRule
    from coadapt_core.experiments.transfer import evaluate_pair
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    protocol = sim_to_sim.protocol_of(config, agents, steps)
    rule = CostRule.from_config(config)
    out: dict[str, Any] = {
        "simulator": simulator,
        "source": f"evaluated by coadapt handoff ({protocol.scenarios} paired scenarios)",
        "scenarios": protocol.scenarios,
        "steps": protocol.steps,
        "scenario_seed": protocol.seed(seed),
        "cost_rule": rule.rule,
    }
    try:
        robot, sim_cls, made = resolve_plugins(robot, simulator, objectives)
        if terrain not in getattr(sim_cls, "terrains", (terrain,)):
            raise BackendUnavailable(f"{simulator} offers no terrain '{terrain}'")
        space = robot.design_space_for(design)

        def make(policy: Path) -> Any:
            return make_backend(
                robot,
                sim_cls,
                made,
                terrain=terrain,
                design_space=space,
                agents_per_design=protocol.scenarios,
                device=str((config or {}).get("device", "cpu")),
                seed=seed,
                checkpoint=str(policy),
            )

        files = {"best": checkpoint, "nominal": nominal_checkpoint or checkpoint}
        pair = {"best": design, "nominal": nominal}
        fit = evaluate_pair(make, files, pair, made, protocol, seed)
    except (BackendUnavailable, UserError, ImportError) as exc:
        out["error"] = " ".join(str(exc).split())
        return out
    rows = sim_to_sim.figures(fit, made, rule, sim_to_sim.gate_of(config), protocol)
    out.update(_paired_rows(made, fit, rows, rule.rule), seconds=float(fit.seconds))
    return out


def _paired_rows(
    made: list[Any], fit: Any, rows: list[dict[str, float]] | None, rule: str
) -> dict[str, Any]:
    """Per objective the design's and the nominal design's cost (the run's rule) with their
    SE, their plain means and the paired improvements under both; the fall rates; the
    protocol's line and answer of the first objective. Without per-scenario costs, the
    backend's costs alone."""
    from coadapt_core import sim_to_sim
    from coadapt_core.analysis.measures import improvement_measure

    if rows is None:
        costs = np.asarray(fit.costs, dtype=float).reshape(2, -1)
        objectives = {
            o.name: {
                "design": float(costs[0, j]),
                "nominal": float(costs[1, j]),
                "improvement": float(o.improvement(float(costs[0, j]), float(costs[1, j]))),
            }
            for j, o in enumerate(made)
        }
        return {"objectives": objectives, "design_fall_rate": None, "nominal_fall_rate": None}
    best, nominal = rows

    def value(row: dict[str, float], key: str) -> float | None:
        x = row.get(key)
        return None if x is None or not np.isfinite(x) else float(x)

    objectives = {
        o.name: {
            "design": value(best, o.name),
            "nominal": value(nominal, o.name),
            "design_se": value(best, f"{o.name}/se"),
            "nominal_se": value(nominal, f"{o.name}/se"),
            "design_plain": value(best, f"{o.name}/plain"),
            "nominal_plain": value(nominal, f"{o.name}/plain"),
            **{k: value(best, f"{o.name}/{k}") for k in sim_to_sim.IMPROVEMENT_KEYS},
        }
        for o in made
    }
    read = sim_to_sim.reading(best, nominal, made[0].name)
    assert read is not None  # the rows are the protocol's
    return {
        "objectives": objectives,
        "design_fall_rate": value(best, "falls"),
        "nominal_fall_rate": value(nominal, "falls"),
        "fall_rate_difference": value(best, "falls/difference"),
        "fall_rate_difference_se": value(best, "falls/difference_se"),
        "answer": read.answer,
        "refusal": read.refusal or None,
        "warning": read.warning or None,
        "sim_to_sim": sim_to_sim.line(read, rule, improvement_measure(made[0])),
    }


def run_final_check(
    summary: dict[str, Any], config: dict[str, Any], simulator: str
) -> dict[str, Any]:
    """The run's own final check of its best design (its summary), on the run's simulator."""
    names = list((summary.get("best_costs") or {}).keys())
    rows = {}
    for name in names:
        improvements = summary.get("improvements") or {}
        rows[name] = {
            "design": summary["best_costs"].get(name),
            "nominal": (summary.get("nominal_costs") or {}).get(name),
            "design_se": (summary.get("best_costs_se") or {}).get(name),
            "nominal_se": (summary.get("nominal_costs_se") or {}).get(name),
            "improvement": improvements.get(name),
            "improvement_se": (summary.get("improvements_se") or {}).get(name),
        }
    return {
        "simulator": simulator,
        "source": "the run's final check",
        "scenarios": summary.get("final_scenarios"),
        "steps": config.get("eval_steps"),
        "objectives": rows,
        "design_fall_rate": summary.get("best_fall_rate"),
        "nominal_fall_rate": summary.get("nominal_fall_rate"),
        "significant": summary.get("significant"),
    }


def front_index(summary: dict[str, Any], design: Any) -> int | None:
    """The index of `design` in the run's stored Pareto front (`coadapt handoff --pick`),
    None when the run has no front or the design is not on it."""
    front = summary.get("pareto_front")
    if not isinstance(front, dict) or not front.get("designs"):
        return None
    x = np.asarray(design, dtype=float)
    for i, row in enumerate(front["designs"]):
        if len(row) == len(x) and np.allclose(np.asarray(row, dtype=float), x):
            return i
    return None


def front_final_check(
    summary: dict[str, Any], config: dict[str, Any], simulator: str, index: int
) -> dict[str, Any]:
    """The run's own final check of front design `index` (its summary's Pareto front) against
    the nominal design on the same scenarios; the improvement is left to the fresh paired
    evaluations (the front stores no paired errors)."""
    front = summary["pareto_front"]
    costs, ses = front["costs"][index], (front.get("costs_se") or [{}] * len(front["costs"]))[index]
    nominal, nominal_se = summary.get("nominal_costs") or {}, summary.get("nominal_costs_se") or {}
    rows = {
        name: {
            "design": value,
            "nominal": nominal.get(name),
            "design_se": ses.get(name),
            "nominal_se": nominal_se.get(name),
            "improvement": None,
            "improvement_se": None,
        }
        for name, value in costs.items()
    }
    return {
        "simulator": simulator,
        "source": f"the run's final check (Pareto front design {index})",
        "scenarios": summary.get("final_scenarios"),
        "steps": config.get("eval_steps"),
        "objectives": rows,
        "design_fall_rate": None,
        "nominal_fall_rate": summary.get("nominal_fall_rate"),
        "significant": None,
    }


def run_check(folder: Path, seconds: float, vx: float) -> dict[str, Any]:
    """Run the folder's check.py in a fresh interpreter (its own imports only) and return its
    JSON result, or {"error": ...}."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    try:
        done = subprocess.run(
            [sys.executable, "check.py", "--json", "--seconds", f"{seconds:g}", "--vx", f"{vx:g}"],
            cwd=folder,
            capture_output=True,
            text=True,
            timeout=600,
            env=env,
        )
    except (OSError, subprocess.SubprocessError) as exc:
        return {"error": f"check.py did not run ({type(exc).__name__})"}
    lines = done.stdout.strip().splitlines()
    if done.returncode != 0 or not lines:
        tail = " ".join((done.stderr or "").split())[-300:]
        return {"error": f"check.py exited {done.returncode}: {tail}"}
    try:
        return json.loads(lines[-1])
    except ValueError:
        return {"error": "check.py printed no JSON"}


def copy_or_render_video(
    run_dir: Path,
    folder: Path,
    config: dict[str, Any],
    summary: dict[str, Any],
    design: np.ndarray,
    nominal: np.ndarray,
    policies: dict[str, Path],
    is_best: bool,
    render: bool,
    name: str,
) -> str:
    """The run's best-vs-nominal GIF (and MP4) when it shows this design; else a fresh one
    when `render`, each design under its policy in `policies` ("best": the design's,
    "nominal"); a line saying which."""
    if is_best and (run_dir / f"{name}.gif").is_file():
        for suffix in (".gif", ".mp4"):
            if (run_dir / f"{name}{suffix}").is_file():
                shutil.copy2(run_dir / f"{name}{suffix}", folder / f"{name}{suffix}")
        return f"{name}.gif copied from the run"
    if not render:
        return "none (the run has no GIF of this design; --no-video)"
    import io

    from coadapt_core.viz.video import render_run_video

    stream = io.StringIO()
    written = render_run_video(
        folder,
        {"best_design": [float(x) for x in design], "nominal_design": [float(x) for x in nominal]},
        config,
        stream=stream,
        policies=policies,
    )
    if written:
        return f"{name}.gif rendered by coadapt handoff"
    return "none (" + " ".join(stream.getvalue().split())[:200] + ")"
