"""Evaluating a policy checkpoint on one design under a fixed command (`coadapt eval`, and
the rollouts behind a run's best-vs-nominal video): survival, forward speed, the three
locomotion costs with their standard errors over the agents, and optionally the recorded
base poses and joint angles of agent 0 for rendering."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError


def _mean_se(values: Any) -> float:
    import numpy as np

    v = np.asarray(values, dtype=float)
    return float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else 0.0


def evaluate_checkpoint(
    checkpoint: Path | str,
    robot_obj: Any,
    sim_cls: type,
    design: Any,
    *,
    terrain: str,
    command: list[float],
    agents: int,
    seconds: float,
    device: str = "cpu",
    seed: int = 0,
    randomize: bool = True,
    record: bool = False,
    progress: Any = None,
    objectives: Sequence[str] = (),
) -> dict[str, Any]:
    """Survival, mean forward speed and costs of a policy on one design under a fixed
    command (the policy mean; falls auto-reset but count against survival). `objectives`
    names further installed objectives (a plugin's included, built with their default
    options): `costs` and `costs_se` hold each one's mean cost per step and its standard
    error over the agents."""
    import numpy as np
    import torch

    from coadapt_core.fitness import scenario_seed
    from coadapt_core.learning import TrainConfig, Trainer, read_checkpoint
    from coadapt_core.learning.evaluate import rollout
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.plugins import get_registry
    from coadapt_core.scenarios.sets import apply_scenarios
    from coadapt_core.task import LocomotionEnv, TaskConfig

    state = read_checkpoint(checkpoint)
    if state["robot"] != robot_obj.name:
        raise UserError(f"checkpoint '{checkpoint}' was trained for robot '{state['robot']}', not '{robot_obj.name}'", field="checkpoint")
    registry = get_registry()
    metric_names = ["tracking", "power", "torque"]
    metric_names += [n for n in dict.fromkeys(objectives) if n not in metric_names]
    requested = list(dict.fromkeys(objectives))
    objectives = [registry.get("objective", n)() for n in metric_names]
    config = TrainConfig.from_dict(state["train_config"])
    config.device = device
    task = TaskConfig.from_dict(state["task_config"])
    task.commands.resample_seconds = 0.0
    task.episode_seconds = seconds + 1.0
    trainer = Trainer(robot_obj, sim_cls, objectives, terrain=terrain, train_config=config, task_config=task, device=device, seed=seed)
    trainer.load(checkpoint, optimizers=False)
    randomization = RandomizationConfig() if randomize else RandomizationConfig.off()
    designs = np.tile(np.asarray(design, dtype=float), (agents, 1))
    sim = sim_cls(robot_obj, designs, terrain=terrain, randomization=randomization, seed=seed)
    env = LocomotionEnv(sim, robot_obj, task, objectives, seed=seed, device=device)
    trainer.ensure_ppo(env)
    # the scenario set of `seed` (as `coadapt run/landscape --seed`), under the given command
    apply_scenarios(env, agents, 1, scenario_seed(seed), commands=torch.tensor(command, dtype=torch.float32).expand(agents, 3))
    steps = max(1, int(round(seconds / env.dt)))
    frames: list[dict] = []

    def capture(e: LocomotionEnv) -> None:
        s = e.state
        frames.append({
            "pos": s.base_pos[0].tolist(), "quat": s.base_quat[0].tolist(), "q": s.joint_pos[0].tolist(),
        })

    done = [0]
    divergences = [0]  # agent-steps whose physics blew up (the simulator reset those agents)

    def on_step(e: LocomotionEnv) -> None:
        diverged = getattr(e.state, "diverged", None)
        if diverged is not None:
            divergences[0] += int(torch.as_tensor(diverged).sum())
        if record:
            capture(e)
        done[0] += 1
        if progress is not None:
            progress(done[0], f"{agents} agents on one design, {seconds:g} s simulated", total=steps)

    result = rollout(trainer.ppo, env, 1, steps, seed=seed, on_step=on_step)
    sim.close()
    out: dict[str, Any] = {
        "robot": robot_obj.name,
        "design": [float(x) for x in np.asarray(design, dtype=float)],
        "survival": float(result.survival[0]),
        "vx_mean": float(result.vx[0]),
        "tracking_error": float(result.metrics[0, 0]),
        "torque_cost": float(result.metrics[0, 2]),
        "power_cost": float(result.metrics[0, 1]),
        "vx_command": float(command[0]),
        # the yaw rate the robots turned at (mean over agents of each one's mean before its
        # first fall) against the commanded one
        "yaw_rate_mean": float(result.yaw_rate[0]),
        "yaw_rate_command": float(command[2]),
        "foot_alternation": None if not math.isfinite(float(result.alternation[0])) else float(result.alternation[0]),
        # standard errors over the agents (paired scenarios) of the speeds and the three costs
        "vx_mean_se": _mean_se(result.per_agent_velocity[0, :, 0]),
        "yaw_rate_mean_se": _mean_se(result.per_agent_velocity[0, :, 2]),
        "tracking_error_se": _mean_se(result.per_agent[0, :, 0]),
        "power_cost_se": _mean_se(result.per_agent[0, :, 1]),
        "torque_cost_se": _mean_se(result.per_agent[0, :, 2]),
        "fall_rate": float(1.0 - result.survival[0]),
        "fall_rate_se": _mean_se(1.0 - (np.asarray(result.falls[0]) > 0)) if result.falls is not None else None,
        # one design alone, so no nominal reference for the capped rule: the costs above are
        # the paper's plain mean (eq. 4) over the agents; `coadapt landscape` and the run's
        # final check give the capped cost beside it
        "cost_rule": "mean",
        "steps": int(result.steps),
        "divergences": int(divergences[0]),
        "dt": float(env.dt),
    }
    if requested:  # each asked-for objective: mean cost per step and its SE over the agents
        out["costs"] = {n: float(result.metrics[0, metric_names.index(n)]) for n in requested}
        out["costs_se"] = {n: _mean_se(result.per_agent[0, :, metric_names.index(n)]) for n in requested}
    if record:
        out["_trajectory"] = {"frames": frames, "dt": env.dt, "terrain": terrain}
    return out


__all__ = ["evaluate_checkpoint"]
