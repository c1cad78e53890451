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


def reported_objectives(requested: Sequence[str] = ()) -> tuple[list[str], list[str]]:
    """(the installed objectives `coadapt eval` always reports: those that declare a
    `summary_key`, in the registry's order; the names it evaluates: those, then `requested`)."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    always = [
        n
        for n in registry.names("objective")
        if getattr(registry.get("objective", n), "summary_key", "")
    ]
    return always, always + [n for n in dict.fromkeys(requested) if n not in always]


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
    command (the policy mean; falls auto-reset but count against survival). Every installed
    objective that declares a `summary_key` is reported under that key (and `<key>_se`);
    `objectives` names further installed objectives (a plugin's included, built with their
    default options): `costs` and `costs_se` hold each one's mean cost per step and its
    standard error over the agents."""
    from coadapt_core.learning.evaluate import rollout
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    always, metric_names = reported_objectives(objectives)
    requested = list(dict.fromkeys(objectives))
    objective_objs = [registry.get("objective", n)() for n in metric_names]
    trainer, task = _checkpoint_trainer(
        checkpoint,
        robot_obj,
        sim_cls,
        objective_objs,
        terrain=terrain,
        seconds=seconds,
        device=device,
        seed=seed,
    )
    sim, env = _design_env(
        robot_obj,
        sim_cls,
        task,
        objective_objs,
        design,
        terrain=terrain,
        agents=agents,
        seed=seed,
        device=device,
        randomize=randomize,
    )
    trainer.ensure_ppo(env)
    _hold_command(env, agents, seed, command)
    steps = max(1, int(round(seconds / env.dt)))
    watch = _Watch(
        record=record,
        progress=progress,
        total=steps,
        detail=f"{agents} agents on one design, {seconds:g} s simulated",
    )
    result = rollout(trainer.ppo.action_distribution, env, 1, steps, seed=seed, on_step=watch)
    sim.close()
    keys = {n: registry.get("objective", n).summary_key for n in always}
    out = _summary(
        result,
        robot_obj.name,
        design,
        command,
        keys,
        metric_names,
        requested,
        divergences=watch.divergences,
        dt=env.dt,
    )
    if record:
        out["_trajectory"] = {"frames": watch.frames, "dt": env.dt, "terrain": terrain}
    return out


def _design_env(
    robot_obj: Any,
    sim_cls: type,
    task: Any,
    objective_objs: list,
    design: Any,
    *,
    terrain: str,
    agents: int,
    seed: int,
    device: str,
    randomize: bool,
) -> tuple[Any, Any]:
    """(simulator, env) of `agents` copies of `design`, randomized or not."""
    import numpy as np

    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.task.env import LocomotionEnv

    randomization = RandomizationConfig() if randomize else RandomizationConfig.off()
    designs = np.tile(np.asarray(design, dtype=float), (agents, 1))
    sim = sim_cls(robot_obj, designs, terrain=terrain, randomization=randomization, seed=seed)
    env = LocomotionEnv(sim, robot_obj, task, objective_objs, seed=seed, device=device)
    return sim, env


def _hold_command(env: Any, agents: int, seed: int, command: list[float]) -> None:
    """Give the env's agents the scenario set of `seed` (as `coadapt run/landscape --seed`),
    every agent under the given command."""
    import torch

    from coadapt_core.learning.evaluate import apply_scenarios
    from coadapt_core.scenarios.seeds import scenario_seed

    apply_scenarios(
        env,
        agents,
        1,
        scenario_seed(seed),
        commands=torch.tensor(command, dtype=torch.float32).expand(agents, 3),
    )


def _checkpoint_trainer(
    checkpoint: Path | str,
    robot_obj: Any,
    sim_cls: type,
    objective_objs: list,
    *,
    terrain: str,
    seconds: float,
    device: str,
    seed: int,
) -> tuple[Any, Any]:
    """(a Trainer holding the checkpoint's policy, the checkpoint's task set to hold one
    command for `seconds`); a checkpoint of another robot is refused."""
    from coadapt_core.learning.checkpoints import read_checkpoint
    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.trainer import Trainer
    from coadapt_core.task.config import TaskConfig

    state = read_checkpoint(checkpoint)
    if state["robot"] != robot_obj.name:
        raise UserError(
            f"checkpoint '{checkpoint}' was trained for robot '{state['robot']}', "
            f"not '{robot_obj.name}'",
            field="checkpoint",
        )
    config = TrainConfig.from_dict(state["train_config"])
    config.device = device
    task = TaskConfig.from_dict(state["task_config"])
    task.commands.resample_seconds = 0.0
    task.episode_seconds = seconds + 1.0
    trainer = Trainer(
        robot_obj,
        sim_cls,
        objective_objs,
        terrain=terrain,
        train_config=config,
        task_config=task,
        device=device,
        seed=seed,
    )
    trainer.load(checkpoint, optimizers=False)
    return trainer, task


#: the walking-gate check at the end of `coadapt train`: agents, simulated seconds (250
#: policy steps at 0.02 s, past the gate's `MIN_JUDGED_STEPS`) and `coadapt eval`'s command
VERDICT_AGENTS, VERDICT_SECONDS, VERDICT_COMMAND = 16, 5.0, [0.5, 0.0, 0.0]


def training_verdict(
    checkpoint: Path | str,
    robot_obj: Any,
    sim_cls: type,
    space: Any,
    *,
    terrain: str,
    device: str = "cpu",
    seed: int = 0,
) -> dict[str, Any]:
    """`coadapt run`'s walking gate on a policy `coadapt train` just wrote: `evaluate_checkpoint`
    of `VERDICT_AGENTS` x `VERDICT_SECONDS` under `VERDICT_COMMAND` at the robot's nominal
    design (clipped into the trained range `space`), with randomization as in training."""
    import numpy as np

    nominal = np.asarray(robot_obj.nominal_design(space.is_mixed), dtype=float)
    design = np.clip(nominal, space.lower, space.upper)
    result = evaluate_checkpoint(
        checkpoint,
        robot_obj,
        sim_cls,
        design,
        terrain=terrain,
        command=VERDICT_COMMAND,
        agents=VERDICT_AGENTS,
        seconds=VERDICT_SECONDS,
        device=device,
        seed=seed,
    )
    keys = (
        "design",
        "survival",
        "vx_mean",
        "vx_command",
        "tracking_ratio",
        "walking",
        "walking_gate",
    )
    return {key: result[key] for key in keys} | {
        "agents": VERDICT_AGENTS,
        "seconds": VERDICT_SECONDS,
    }


class _Watch:
    """The rollout's `on_step`: counts diverged agent-steps (the simulator reset those
    agents), records agent 0's base pose and joint angles when asked, reports progress."""

    def __init__(self, *, record: bool, progress: Any, total: int, detail: str):
        self.record, self.progress, self.total, self.detail = record, progress, total, detail
        self.frames: list[dict] = []
        self.done = 0
        self.divergences = 0

    def __call__(self, env: Any) -> None:
        import torch

        diverged = getattr(env.state, "diverged", None)
        if diverged is not None:
            self.divergences += int(torch.as_tensor(diverged).sum())
        if self.record:
            s = env.state
            self.frames.append(
                {
                    "pos": s.base_pos[0].tolist(),
                    "quat": s.base_quat[0].tolist(),
                    "q": s.joint_pos[0].tolist(),
                }
            )
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.detail, total=self.total)


def _gate(result: Any, command: list[float]) -> dict[str, Any]:
    """`coadapt run`'s walking gate on this evaluation (coadapt/reliability.py): the share of
    agents that never fell, the tracking ratio (the RMS over agents of each one's mean
    velocity error against the command, over the command's size; None under a zero
    command), the verdict and its reason."""
    from coadapt_core.coadapt.reliability import judge_policy

    size = sum(float(c) ** 2 for c in command)
    error = None if result.mean_velocity_error is None else float(result.mean_velocity_error[0])
    ratio = math.sqrt(error / size) if error is not None and size > 1e-4 else None
    survival = float(result.survival[0])
    agents = result.per_agent.shape[1]  # one design: steps per agent = interactions / agents
    walking, reason = judge_policy(survival, ratio, int(result.steps) // agents)
    return {"tracking_ratio": ratio, "walking": walking, "walking_gate": reason}


def _summary(
    result: Any,
    robot: str,
    design: Any,
    command: list[float],
    keys: dict[str, str],
    metric_names: list[str],
    requested: list[str],
    *,
    divergences: int,
    dt: float,
) -> dict[str, Any]:
    """The result of `evaluate_checkpoint` from the rollout's: `keys` maps each objective
    always reported to its summary key; `requested` ones go under `costs` / `costs_se`."""
    import numpy as np

    def cost(name: str) -> float:
        return float(result.metrics[0, metric_names.index(name)])

    def cost_se(name: str) -> float:
        return _mean_se(result.per_agent[0, :, metric_names.index(name)])

    out: dict[str, Any] = {
        "robot": robot,
        "design": [float(x) for x in np.asarray(design, dtype=float)],
        "survival": float(result.survival[0]),
        "vx_mean": float(result.vx[0]),
        **{key: cost(name) for name, key in keys.items()},
        "vx_command": float(command[0]),
        # the yaw rate the robots turned at (mean over agents of each one's mean before its
        # first fall) against the commanded one
        "yaw_rate_mean": float(result.yaw_rate[0]),
        "yaw_rate_command": float(command[2]),
        "foot_alternation": None
        if not math.isfinite(float(result.alternation[0]))
        else float(result.alternation[0]),
        # standard errors over the agents (paired scenarios) of the speeds and the costs
        "vx_mean_se": _mean_se(result.per_agent_velocity[0, :, 0]),
        "yaw_rate_mean_se": _mean_se(result.per_agent_velocity[0, :, 2]),
        **{f"{key}_se": cost_se(name) for name, key in keys.items()},
        "fall_rate": float(1.0 - result.survival[0]),
        "fall_rate_se": _mean_se(1.0 - (np.asarray(result.falls[0]) > 0))
        if result.falls is not None
        else None,
        # one design alone, so no nominal reference for the capped rule: the costs above are
        # the paper's plain mean (eq. 4) over the agents; `coadapt landscape` and the run's
        # final check give the capped cost beside it
        "cost_rule": "mean",
        "steps": int(result.steps),
        "divergences": int(divergences),
        "dt": float(dt),
        **_gate(result, command),
    }
    if requested:  # each asked-for objective: mean cost per step and its SE over the agents
        out["costs"] = {n: cost(n) for n in requested}
        out["costs_se"] = {n: cost_se(n) for n in requested}
    return out


__all__ = ["evaluate_checkpoint", "reported_objectives", "training_verdict"]
