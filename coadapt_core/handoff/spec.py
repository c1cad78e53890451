"""policy.json of a handoff folder: everything needed to run `policy.onnx` on the robot
(observation and action layouts, scaling, noise, PD gains, rates, gait clock, commands,
terrain), and the foot facts it states."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from coadapt_core.io import jsonable

#: the format of a handoff folder (policy.json and design.json say it)
FORMAT = "coadapt-handoff-1"

#: units and meaning of each slice of the policy observation (coadapt_core.task.observations)
OBS_UNITS = {
    "base_lin_vel": (
        "m/s",
        "base linear velocity (x forward, y left, z up) in the base frame",
        "base_lin_vel",
    ),
    "base_ang_vel": ("rad/s", "base angular velocity in the base frame", "base_ang_vel"),
    "projected_gravity": (
        "1",
        "unit gravity vector (0, 0, -1) of the world in the base frame",
        "projected_gravity",
    ),
    "command": ("m/s, m/s, rad/s", "velocity command: vx, vy (base frame), yaw rate", None),
    "joint_pos": ("rad", "joint positions minus the default pose, action joint order", "joint_pos"),
    "joint_vel": ("rad/s", "joint velocities, action joint order", "joint_vel"),
    "action_history": (
        "1",
        "the last raw actions (the ONNX `actions` output), newest first, each in joint order",
        None,
    ),
    "clock": ("1", "sin and cos of 2 pi x gait phase", None),
}


# -- policy.json -------------------------------------------------------------------------------
def _trained_command_ranges(task: Any, commands_state: dict[str, Any] | None) -> dict[str, Any]:
    cfg = task.commands
    limit = (
        float(commands_state["limit"])
        if commands_state and "limit" in commands_state
        else (cfg.curriculum_start if cfg.curriculum else math.inf)
    )
    names = ("vx", "vy", "yaw_rate")
    configured = (cfg.vx_range, cfg.vy_range, cfg.yaw_range)
    reached = {
        n: [max(lo, -limit), min(hi, limit)] for n, (lo, hi) in zip(names, configured, strict=True)
    }
    return {
        "configured": {n: list(r) for n, r in zip(names, configured, strict=True)},
        "curriculum_limit": None if math.isinf(limit) else limit,
        "trained": reached,
        "units": {"vx": "m/s", "vy": "m/s", "yaw_rate": "rad/s"},
        "zero_threshold": cfg.zero_threshold,
        "note": "the command box the policy reached in training (configured ranges clipped to "
        "+-curriculum_limit); a planar command slower than zero_threshold was given as "
        "exactly 0",
    }


def _observation(task: Any, policy: Any, num_joints: int) -> dict[str, Any]:
    """The observation's slices (units, meaning, training noise) and its normalisation."""
    from coadapt_core.task.observations import policy_layout

    mean, std, clip = policy.actor.normalisation()
    slices, start = [], 0
    noise = task.noise
    for name, size in policy_layout(num_joints, task.history):
        units, meaning, noise_key = OBS_UNITS[name]
        scale = float(getattr(noise, noise_key)) if noise_key else 0.0
        slices.append(
            {
                "name": name,
                "start": start,
                "stop": start + size,
                "size": size,
                "units": units,
                "meaning": meaning,
                "scaling": "none: raw values in these units (the ONNX graph normalises)",
                "training_noise": {"kind": noise.kind, "scale": scale}
                if (noise.enabled and scale > 0)
                else None,
            }
        )
        start += size
    return {
        "size": start,
        "history": task.history,
        "slices": slices,
        "normalisation": {
            "inside_graph": True,
            "rule": "clip((obs - mean) / std, -clip, clip)",
            "mean": [float(x) for x in mean],
            "std": [float(x) for x in std],
            "clip": clip,
        },
    }


def _onnx(size: int, num_joints: int, verification: dict[str, float]) -> dict[str, Any]:
    return {
        "input": {"name": "obs", "shape": ["batch", size], "dtype": "float32"},
        "outputs": [
            {
                "name": "actions",
                "shape": ["batch", num_joints],
                "dtype": "float32",
                "meaning": "raw action, clipped to +-action.clip; feed it back into the action "
                "history",
            },
            {
                "name": "joint_targets",
                "shape": ["batch", num_joints],
                "dtype": "float32",
                "units": "rad",
                "meaning": "default_joint_pos + action.scale x actions: PD position targets",
            },
        ],
        "tolerance": verification["tolerance"],
        "max_abs_action_difference": verification["max_abs_action_difference"],
        "recorded_observations": verification["observations"],
        "exporter": "torch.onnx.export(dynamo=True)",
    }


def _joints(model: Any) -> dict[str, Any]:
    return {
        "names": list(model.joint_names),
        "kp": [float(x) for x in model.kp],
        "kd": [float(x) for x in model.kd],
        "torque_limit": [float(x) for x in model.torque_limit],
        "speed_limit": [float(x) for x in model.speed_limit],
        "lower": [float(x) for x in model.joint_lower],
        "upper": [float(x) for x in model.joint_upper],
        "units": {
            "kp": "N m/rad",
            "kd": "N m s/rad",
            "torque_limit": "N m",
            "speed_limit": "rad/s",
            "lower": "rad",
            "upper": "rad",
        },
        "pd_law": "tau = kp (target - q) - kd dq at every physics step, then clipped to the "
        "motor's torque-speed envelope [-torque_limit clip(1 + dq / speed_limit, 0, 1), "
        "torque_limit clip(1 - dq / speed_limit, 0, 1)]",
    }


def _gait(task: Any, robot: Any) -> dict[str, Any]:
    return {
        "frequency": task.gait.frequency,
        "legs": [{"name": leg.name, "phase_offset": leg.phase_offset} for leg in robot.legs()],
        "freeze_on_zero_command": task.gait.freeze_on_zero_command,
        "zero_command_phase": 0.25,
        "rule": "phase in [0, 1) advances by control_dt x frequency after every policy step while "
        "the command is not zero (held at zero_command_phase under a zero command when "
        "freeze_on_zero_command); the observation's clock is (sin, cos)(2 pi phase); "
        "training started each episode at a random phase",
    }


def _simulation(model: Any, foot: dict[str, Any]) -> dict[str, Any]:
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.physics.simulator import SPAWN_CLEARANCE

    return {
        "base_body": model.base_body,
        "foot_bodies": list(model.foot_bodies),
        "standing_base_height": float(model.standing_base_height),
        "spawn_clearance": SPAWN_CLEARANCE,
        "foot_xy": foot["foot_xy"],
        "foot_radius": foot["foot_radius"],
        "friction": RandomizationConfig.NOMINAL["friction"],
        "nominal_physics": dict(RandomizationConfig.NOMINAL),
    }


def policy_spec(
    *,
    robot: Any,
    model: Any,
    design: np.ndarray,
    space: Any,
    state: dict[str, Any],
    rollout: dict[str, Any],
    terrain: str,
    verification: dict[str, float],
    foot: dict[str, Any],
    files: dict[str, str],
) -> dict[str, Any]:
    """Everything needed to run `policy.onnx` on the robot: layouts, scaling, noise, PD,
    rates, clock, commands, terrain."""
    from coadapt_core.physics.terrain import SLOPE_DEGREES

    task = rollout["task"]
    num_joints = model.num_joints
    observation = _observation(task, rollout["policy"], num_joints)
    return {
        "format": FORMAT,
        "robot": robot.name,
        "design": dict(zip(space.names, (float(x) for x in design), strict=True)),
        "design_text": "("
        + ", ".join(f"{n} {x:g}" for n, x in zip(space.names, design, strict=True))
        + ")",
        "design_input": [float(x) for x in rollout["design_obs"]],
        "design_input_rule": "each design variable mapped linearly from the robot's design-space "
        "bounds to [-1, 1]; baked into policy.onnx as a constant",
        "files": files,
        "onnx": _onnx(observation["size"], num_joints, verification),
        "observation": observation,
        "action": {
            "size": num_joints,
            "joint_order": list(model.joint_names),
            "scale": task.action_scale,
            "clip": task.action_clip,
            "default_joint_pos": [float(x) for x in rollout["default_joint_pos"]],
            "rule": "joint_targets = default_joint_pos + scale x clip(action, -clip, clip)",
        },
        "joints": _joints(model),
        "rates": {
            "physics_dt": rollout["physics_dt"],
            "decimation": rollout["decimation"],
            "control_dt": rollout["control_dt"],
            "control_hz": 1.0 / rollout["control_dt"],
            "physics_hz": 1.0 / rollout["physics_dt"],
        },
        "gait": _gait(task, robot),
        "commands": _trained_command_ranges(task, state.get("commands")),
        "terrain": {
            "name": terrain,
            "slope_degrees": SLOPE_DEGREES,
            "note": "the ground trained on; slope_degrees is the slope terrain's rise along +x",
        },
        "termination": {
            "min_base_height": task.min_base_height,
            "max_tilt_cos": task.max_tilt_cos,
            "rule": "a fall: base height above the ground < min_base_height x its standing "
            "height, or projected gravity z > -max_tilt_cos",
        },
        "simulation": _simulation(model, foot),
        "training": {
            "randomization": jsonable(rollout["randomization"].to_dict()),
            "observation_noise": jsonable(task.noise),
            "simulator": state.get("simulator"),
            "total_steps": int(state.get("total_steps") or 0),
        },
    }


def foot_facts(model: Any, tools: Any) -> dict[str, Any]:
    """Each foot body's origin relative to the base (x, y) at the default pose, read with the
    simulator's model `tools`, and a sole's reach around it (the spawn rule of
    `coadapt_core.physics.simulator.spawn_base_height`)."""
    xy = np.asarray(tools.foot_positions(model, model.default_joint_pos), dtype=float)[:, :2]
    pts = np.asarray(model.foot_contact_points, dtype=float).reshape(-1, 3)
    radius = float(np.max(np.linalg.norm(pts[:, :2], axis=1))) if len(pts) else 0.15
    return {"foot_xy": xy.tolist(), "foot_radius": radius}


# -- evaluation ------------------------------------------------------------------------------------
