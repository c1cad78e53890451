"""`coadapt handoff`: a finished run's chosen design as one folder for whoever builds it.

The folder holds the design's MJCF and URDF with their assets (from the robot plugin), the
universal policy specialised to the design as ONNX (checked against torch with onnxruntime
on recorded observations), `policy.json` (observation and action layouts, PD gains, rates,
clock, command ranges, terrain), the design sheet (`design.md`, `design.json`: parameters,
links, motors, validation, costs against the nominal design on paired scenarios per
simulator, provenance), the run's best-vs-nominal GIF, a README and `check.py`, which walks
the robot with the ONNX controller in MuJoCo without importing coadapt.

The folder is built under a temporary name beside the target and renamed when complete, so
a refused or failed handoff leaves nothing half-written.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import __version__
from coadapt_core.errors import BackendUnavailable, CoadaptError, UserError
from coadapt_core.handoff import sheet
from coadapt_core.handoff.model_files import write_model_files
from coadapt_core.io import jsonable

FORMAT = "coadapt-handoff-1"
CHECK_SCRIPT = Path(__file__).with_name("check.py")
#: observations of the design's own rollout recorded for the ONNX check (agents x steps)
ROLLOUT_AGENTS, ROLLOUT_STEPS = 4, 100
#: evaluation-buffer rows of the run used for the ONNX check, at most
BUFFER_ROWS = 2000
#: rows of (observation, torch action) kept in reference.npz for check.py
REFERENCE_ROWS = 256
#: the check's forward command, m/s (clipped to the trained range)
CHECK_VX = 0.5

#: units and meaning of each slice of the policy observation (coadapt_core.task.observations)
OBS_UNITS = {
    "base_lin_vel": ("m/s", "base linear velocity (x forward, y left, z up) in the base frame", "base_lin_vel"),
    "base_ang_vel": ("rad/s", "base angular velocity in the base frame", "base_ang_vel"),
    "projected_gravity": ("1", "unit gravity vector (0, 0, -1) of the world in the base frame", "projected_gravity"),
    "command": ("m/s, m/s, rad/s", "velocity command: vx, vy (base frame), yaw rate", None),
    "joint_pos": ("rad", "joint positions minus the default pose, action joint order", "joint_pos"),
    "joint_vel": ("rad/s", "joint velocities, action joint order", "joint_vel"),
    "action_history": ("1", "the last raw actions (the ONNX `actions` output), newest first, each in joint order", None),
    "clock": ("1", "sin and cos of 2 pi x gait phase", None),
}


@dataclass
class HandoffOptions:
    design: np.ndarray | None = None  # None: the run's best design
    simulators: Sequence[str] | None = None  # None: the run's simulator and every other installed one
    agents: int = 16  # paired scenarios per design and simulator
    seconds: float = 4.0  # simulated seconds per scenario
    check: bool = True  # walk the folder's check.py once it is written
    check_seconds: float = 10.0
    video: bool = True  # render a GIF when the run has none for the design
    force: bool = False  # replace an existing folder


# -- the run --------------------------------------------------------------------------------
def find_run(text: str, runs_dir: Path = Path("runs")) -> Path:
    """A run folder given as a path or as a run id under `runs_dir`."""
    path = Path(text)
    for candidate in (path, runs_dir / text):
        if candidate.is_dir() and (candidate / "config.yaml").is_file():
            return candidate.resolve()
    raise UserError(f"run '{text}' is neither a run folder nor a run id under {runs_dir}/ (no config.yaml found)",
                    field="run")


def read_run(run_dir: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(config, summary) of a finished run; one-line errors otherwise."""
    import yaml

    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise UserError(f"run {run_dir.name}: config.yaml cannot be read ({type(exc).__name__})", field="run") from None
    summary_path = run_dir / "summary.json"
    if not summary_path.is_file():
        raise UserError(f"run {run_dir.name} has no summary.json: it has not finished (resume it with "
                        f"`coadapt run --resume {run_dir.name}`)", field="run")
    try:
        summary = json.loads(summary_path.read_text())
    except (OSError, ValueError) as exc:
        raise UserError(f"run {run_dir.name}: summary.json cannot be read ({type(exc).__name__})", field="run") from None
    if not isinstance(config, dict) or not isinstance(summary, dict) or not summary.get("best_design"):
        raise UserError(f"run {run_dir.name} recorded no best design; nothing to hand off", field="run")
    return config, summary


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _starting_policy(robot: Any, config: dict[str, Any]) -> dict[str, Any]:
    """The policy the run started from (the config's `checkpoint`: empty = the robot's shipped
    one for the terrain and space, `none` = from scratch) and its SHA-256."""
    given = str(config.get("checkpoint") or "")
    if given.lower() == "none":
        return {"policy": "none (trained from scratch in the run)", "sha256": None}
    path = Path(given) if given else robot.shipped_policy(config.get("terrain") or "flat", bool(config.get("mixed")))
    if path is None:
        return {"policy": "the robot's shipped policy (none found now)", "sha256": None}
    label = f"{path.name} (shipped with robot '{robot.name}')" if not given else str(path)
    return {"policy": label, "sha256": sha256(path) if Path(path).is_file() else None}


def _recorded_commit(run_dir: Path, run_id: str) -> dict[str, Any]:
    """The run's code version and git commit as its results store recorded them (the
    default store beside the runs folder, read only); empty when there is none."""
    store_file = run_dir.parent.parent / "coadapt.db"
    if not store_file.is_file():
        return {}
    try:
        from coadapt_core.results.store import ResultsStore

        store = ResultsStore(str(store_file), create=False)
        try:
            row = store.get_run(run_id)
        finally:
            store.close()
        return {"code_version": row.get("code_version"), "git_commit": row.get("git_commit")}
    except Exception:  # a store of another layout or a locked file: provenance goes without it
        return {}


# -- recorded observations -------------------------------------------------------------------
def _buffer_observations(run_dir: Path, num_obs: int) -> np.ndarray:
    """[n, num_obs] policy observations (noise-free) from the run's newest evaluation buffer."""
    from coadapt_core.statefile import read_npz

    found = sorted(run_dir.glob("buffer-*.npz"), key=lambda p: int("".join(c for c in p.stem if c.isdigit()) or 0))
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


def _rollout(robot: Any, sim_cls: type, design: np.ndarray, state: dict[str, Any], terrain: str, seed: int,
             ) -> dict[str, Any]:
    """The design walking under the specialised policy on the run's simulator with the
    training randomization and observation noise, commands drawn from the trained box:
    the observations it saw [ROLLOUT_AGENTS * ROLLOUT_STEPS, num_obs], its design input,
    default pose, rates, and the simulator's foot facts."""
    import torch

    from coadapt_core.handoff.policy import SpecialisedPolicy
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.task import LocomotionEnv, TaskConfig

    task = TaskConfig.from_dict(state["task_config"])
    randomization = RandomizationConfig.recorded(state["train_config"].get("extra") or {})
    sim = sim_cls(robot, np.tile(design, (ROLLOUT_AGENTS, 1)), terrain=terrain, randomization=randomization, seed=seed)
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


# -- policy.json -------------------------------------------------------------------------------
def _trained_command_ranges(task: Any, commands_state: dict[str, Any] | None) -> dict[str, Any]:
    cfg = task.commands
    limit = float(commands_state["limit"]) if commands_state and "limit" in commands_state else (
        cfg.curriculum_start if cfg.curriculum else math.inf)
    names = ("vx", "vy", "yaw_rate")
    configured = (cfg.vx_range, cfg.vy_range, cfg.yaw_range)
    reached = {n: [max(lo, -limit), min(hi, limit)] for n, (lo, hi) in zip(names, configured, strict=True)}
    return {
        "configured": {n: list(r) for n, r in zip(names, configured, strict=True)},
        "curriculum_limit": None if math.isinf(limit) else limit,
        "trained": reached,
        "units": {"vx": "m/s", "vy": "m/s", "yaw_rate": "rad/s"},
        "zero_threshold": cfg.zero_threshold,
        "note": "the command box the policy reached in training (configured ranges clipped to +-curriculum_limit); "
                "a planar command slower than zero_threshold was given as exactly 0",
    }


def policy_spec(*, robot: Any, model: Any, design: np.ndarray, space: Any, state: dict[str, Any],
                rollout: dict[str, Any], terrain: str, verification: dict[str, float], foot: dict[str, Any],
                files: dict[str, str]) -> dict[str, Any]:
    """Everything needed to run `policy.onnx` on the robot: layouts, scaling, noise, PD,
    rates, clock, commands, terrain."""
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.physics.simulator import SPAWN_CLEARANCE
    from coadapt_core.physics.terrain import SLOPE_DEGREES
    from coadapt_core.task.observations import policy_layout

    task = rollout["task"]
    num_joints = model.num_joints
    layout = policy_layout(num_joints, task.history)
    policy = rollout["policy"]
    mean, std = policy.obs_mean.numpy(), policy.obs_std.numpy()
    slices, start = [], 0
    noise = task.noise
    for name, size in layout:
        units, meaning, noise_key = OBS_UNITS[name]
        scale = float(getattr(noise, noise_key)) if noise_key else 0.0
        slices.append({
            "name": name, "start": start, "stop": start + size, "size": size, "units": units, "meaning": meaning,
            "scaling": "none: raw values in these units (the ONNX graph normalises)",
            "training_noise": {"kind": noise.kind, "scale": scale} if (noise.enabled and scale > 0) else None,
        })
        start += size
    return {
        "format": FORMAT,
        "robot": robot.name,
        "design": dict(zip(space.names, (float(x) for x in design), strict=True)),
        "design_text": "(" + ", ".join(f"{n} {x:g}" for n, x in zip(space.names, design, strict=True)) + ")",
        "design_input": [float(x) for x in rollout["design_obs"]],
        "design_input_rule": "each design variable mapped linearly from the robot's design-space bounds to [-1, 1]; "
                             "baked into policy.onnx as a constant",
        "files": files,
        "onnx": {
            "input": {"name": "obs", "shape": ["batch", start], "dtype": "float32"},
            "outputs": [
                {"name": "actions", "shape": ["batch", num_joints], "dtype": "float32",
                 "meaning": "raw action, clipped to +-action.clip; feed it back into the action history"},
                {"name": "joint_targets", "shape": ["batch", num_joints], "dtype": "float32", "units": "rad",
                 "meaning": "default_joint_pos + action.scale x actions: PD position targets"},
            ],
            "tolerance": verification["tolerance"],
            "max_abs_action_difference": verification["max_abs_action_difference"],
            "recorded_observations": verification["observations"],
            "exporter": "torch.onnx.export(dynamo=True)",
        },
        "observation": {
            "size": start,
            "history": task.history,
            "slices": slices,
            "normalisation": {"inside_graph": True, "rule": "clip((obs - mean) / std, -clip, clip)",
                              "mean": [float(x) for x in mean], "std": [float(x) for x in std],
                              "clip": policy.obs_clip},
        },
        "action": {
            "size": num_joints,
            "joint_order": list(model.joint_names),
            "scale": task.action_scale,
            "clip": task.action_clip,
            "default_joint_pos": [float(x) for x in rollout["default_joint_pos"]],
            "rule": "joint_targets = default_joint_pos + scale x clip(action, -clip, clip)",
        },
        "joints": {
            "names": list(model.joint_names),
            "kp": [float(x) for x in model.kp],
            "kd": [float(x) for x in model.kd],
            "torque_limit": [float(x) for x in model.torque_limit],
            "speed_limit": [float(x) for x in model.speed_limit],
            "lower": [float(x) for x in model.joint_lower],
            "upper": [float(x) for x in model.joint_upper],
            "units": {"kp": "N m/rad", "kd": "N m s/rad", "torque_limit": "N m", "speed_limit": "rad/s", "lower": "rad",
                      "upper": "rad"},
            "pd_law": "tau = kp (target - q) - kd dq at every physics step, then clipped to the motor's torque-speed "
                      "envelope [-torque_limit clip(1 + dq / speed_limit, 0, 1), torque_limit clip(1 - dq / speed_limit, 0, 1)]",
        },
        "rates": {
            "physics_dt": rollout["physics_dt"],
            "decimation": rollout["decimation"],
            "control_dt": rollout["control_dt"],
            "control_hz": 1.0 / rollout["control_dt"],
            "physics_hz": 1.0 / rollout["physics_dt"],
        },
        "gait": {
            "frequency": task.gait.frequency,
            "legs": [{"name": leg.name, "phase_offset": leg.phase_offset} for leg in robot.legs()],
            "freeze_on_zero_command": task.gait.freeze_on_zero_command,
            "zero_command_phase": 0.25,
            "rule": "phase in [0, 1) advances by control_dt x frequency after every policy step while the command is "
                    "not zero (held at zero_command_phase under a zero command when freeze_on_zero_command); the "
                    "observation's clock is (sin, cos)(2 pi phase); training started each episode at a random phase",
        },
        "commands": _trained_command_ranges(task, state.get("commands")),
        "terrain": {"name": terrain, "slope_degrees": SLOPE_DEGREES,
                    "note": "the ground trained on; slope_degrees is the slope terrain's rise along +x"},
        "termination": {"min_base_height": task.min_base_height, "max_tilt_cos": task.max_tilt_cos,
                        "rule": "a fall: base height above the ground < min_base_height x its standing height, or "
                                "projected gravity z > -max_tilt_cos"},
        "simulation": {
            "base_body": model.base_body,
            "foot_bodies": list(model.foot_bodies),
            "standing_base_height": float(model.standing_base_height),
            "spawn_clearance": SPAWN_CLEARANCE,
            "foot_xy": foot["foot_xy"],
            "foot_radius": foot["foot_radius"],
            "friction": RandomizationConfig.NOMINAL["friction"],
            "nominal_physics": dict(RandomizationConfig.NOMINAL),
        },
        "training": {
            "randomization": jsonable(rollout["randomization"].to_dict()),
            "observation_noise": jsonable(task.noise),
            "simulator": state.get("simulator"),
            "total_steps": int(state.get("total_steps") or 0),
        },
    }


def foot_facts(model: Any) -> dict[str, Any]:
    """Each foot body's origin relative to the base (x, y) at the default pose, and a sole's
    reach around it (the spawn rule of `coadapt_core.physics.simulator.spawn_base_height`)."""
    import mujoco

    mj = mujoco.MjModel.from_xml_string(model.mjcf)
    data = mujoco.MjData(mj)
    for name, q in zip(model.joint_names, model.default_joint_pos, strict=True):
        data.qpos[mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)]] = q
    mujoco.mj_kinematics(mj, data)
    base = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, model.base_body)
    feet = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, f) for f in model.foot_bodies]
    xy = data.xpos[feet, :2] - data.xpos[base, :2]
    pts = np.asarray(model.foot_contact_points, dtype=float).reshape(-1, 3)
    radius = float(np.max(np.linalg.norm(pts[:, :2], axis=1))) if len(pts) else 0.15
    return {"foot_xy": xy.tolist(), "foot_radius": radius}


# -- evaluation ------------------------------------------------------------------------------------
def evaluate_on(simulator: str, *, robot: Any, checkpoint: Path, objectives: list[str], design: np.ndarray,
                nominal: np.ndarray, terrain: str, seed: int, agents: int, steps: int) -> dict[str, Any]:
    """Costs, standard errors, fall rates and paired improvements of the design against the
    nominal one on `simulator`: the run's policy, the run's final-check scenario block 1."""
    from coadapt_core.fitness import improvement_se, scenario_seed
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    out: dict[str, Any] = {"simulator": simulator, "source": f"evaluated by coadapt handoff ({agents} paired scenarios)",
                           "scenarios": agents, "steps": steps, "scenario_seed": scenario_seed(seed, 1)}
    try:
        robot, sim_cls, made = resolve_plugins(robot, simulator, objectives)
        if terrain not in getattr(sim_cls, "terrains", (terrain,)):
            raise BackendUnavailable(f"{simulator} offers no terrain '{terrain}'")
        space = robot.design_space_for(design)
        backend = make_backend(robot, sim_cls, made, terrain=terrain, design_space=space, agents_per_design=agents,
                               seed=seed, checkpoint=str(checkpoint))
        try:
            fit = backend.real_fitness(np.stack([design, nominal]), made, agents=agents, steps=steps,
                                       seed=scenario_seed(seed, 1))
        finally:
            close = getattr(backend, "close", None)
            if callable(close):
                close()
    except (BackendUnavailable, UserError, ImportError) as exc:
        out["error"] = " ".join(str(exc).split())
        return out
    costs = np.asarray(fit.costs, dtype=float).reshape(2, -1)
    se = None if fit.cost_se is None else np.asarray(fit.cost_se, dtype=float).reshape(2, -1)
    per = None if fit.per_scenario is None else np.asarray(fit.per_scenario, dtype=float)
    rows = {}
    for j, o in enumerate(made):
        paired = None if per is None else improvement_se(o, per[0, :, j], per[1, :, j])
        rows[o.name] = {
            "design": float(costs[0, j]), "nominal": float(costs[1, j]),
            "design_se": None if se is None else float(se[0, j]), "nominal_se": None if se is None else float(se[1, j]),
            "improvement": float(o.improvement(float(costs[0, j]), float(costs[1, j]))),
            "improvement_se": None if paired is None or not np.isfinite(paired) else float(paired),
        }
    falls = None if fit.fall_rate is None else np.asarray(fit.fall_rate, dtype=float)
    out.update({
        "objectives": rows,
        "design_fall_rate": None if falls is None else float(falls[0]),
        "nominal_fall_rate": None if falls is None else float(falls[1]),
        "seconds": float(fit.seconds),
    })
    return out


def run_final_check(summary: dict[str, Any], config: dict[str, Any], simulator: str) -> dict[str, Any]:
    """The run's own final check of its best design (its summary), on the run's simulator."""
    names = list((summary.get("best_costs") or {}).keys())
    rows = {}
    for name in names:
        improvements = summary.get("improvements") or {}
        rows[name] = {
            "design": summary["best_costs"].get(name), "nominal": (summary.get("nominal_costs") or {}).get(name),
            "design_se": (summary.get("best_costs_se") or {}).get(name),
            "nominal_se": (summary.get("nominal_costs_se") or {}).get(name),
            "improvement": improvements.get(name), "improvement_se": (summary.get("improvements_se") or {}).get(name),
        }
    return {"simulator": simulator, "source": "the run's final check", "scenarios": summary.get("final_scenarios"),
            "steps": config.get("eval_steps"), "objectives": rows, "design_fall_rate": summary.get("best_fall_rate"),
            "nominal_fall_rate": summary.get("nominal_fall_rate"), "significant": summary.get("significant")}


# -- README ------------------------------------------------------------------------------------
def readme_text(spec: dict[str, Any], sheet_data: dict[str, Any], files: list[str]) -> str:
    obs = spec["observation"]
    layout = "\n".join(f"| {s['start']}:{s['stop']} | {s['name']} | {s['units']} | {s['meaning']} |" for s in obs["slices"])
    check = sheet_data.get("controller_check") or {}
    walked = ("" if not check or check.get("error") else
              f"\nWhen this folder was written, `python check.py` printed: survival {check['survival']:.2f}, mean forward "
              f"speed {check['vx_mean']:.3f} m/s under a {check['command'][0]:g} m/s command for {check['seconds']:g} s.\n")
    rates = spec["rates"]
    return f"""# {spec['robot']} {spec['design_text']}: model, controller and design sheet

Written by `coadapt handoff` (coadapt {__version__}) from run `{sheet_data['provenance']['run_id']}`.

| file | what |
|---|---|
{chr(10).join(f"| `{name}` | {what} |" for name, what in files)}

## Load the model and run the controller (numpy, mujoco, onnxruntime)

The policy was trained with the robot on a ground plane at a physics step of
{rates['physics_dt']:g} s and a policy period of {rates['control_dt']:g} s ({rates['decimation']} physics steps per
action, {rates['control_hz']:g} Hz). `check.py` is the full version of this (clock, falls, speed):

```python
import json, math, mujoco, numpy as np, onnxruntime as ort
p = json.load(open("policy.json")); J = p["action"]["joint_order"]; g = np.array([0.0, 0.0, -1.0])
spec = mujoco.MjSpec.from_file("robot.xml"); spec.option.timestep = p["rates"]["physics_dt"]
spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=0, conaffinity=1)
for a in spec.actuators: a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
m = spec.compile(); d = mujoco.MjData(m); policy = ort.InferenceSession("policy.onnx")
qa = m.jnt_qposadr[[m.joint(n).id for n in J]]; va = m.jnt_dofadr[[m.joint(n).id for n in J]]
q0 = np.array(p["action"]["default_joint_pos"]); kp, kd = np.array(p["joints"]["kp"]), np.array(p["joints"]["kd"])
d.qpos[:7] = [0, 0, p["simulation"]["standing_base_height"] + 0.002, 1, 0, 0, 0]; d.qpos[qa] = q0; mujoco.mj_forward(m, d)
rot = lambda q, v: v * (2 * q[0] ** 2 - 1) - np.cross(q[1:], v) * 2 * q[0] + q[1:] * 2 * q[1:] @ v  # world -> base
hist, phase, cmd = np.zeros((p["observation"]["history"], len(J))), 0.0, np.array([0.5, 0.0, 0.0])
for step in range(round(10 / p["rates"]["control_dt"])):  # 10 s
    obs = np.concatenate([rot(d.qpos[3:7], d.qvel[:3]), d.qvel[3:6], rot(d.qpos[3:7], g), cmd, d.qpos[qa] - q0,
                          d.qvel[va], hist.ravel(), [math.sin(2 * math.pi * phase), math.cos(2 * math.pi * phase)]])
    action, target = policy.run(None, {{"obs": obs[None].astype(np.float32)}})
    for _ in range(p["rates"]["decimation"]):  # PD at the physics rate (check.py adds the motor envelope)
        d.ctrl[:] = kp * (target[0] - d.qpos[qa]) - kd * d.qvel[va]; mujoco.mj_step(m, d)
    hist = np.roll(hist, 1, axis=0); hist[0] = action[0]; phase = (phase + p["rates"]["control_dt"] * p["gait"]["frequency"]) % 1
print("base x after 10 s:", d.qpos[0])
```

(This sketch assumes the free joint is the model's first joint and one actuator per joint in
joint order, as the robot's MJCF has them; `check.py` looks both up by name.)
{walked}
## The observation (`obs`, {obs['size']} float32 values, SI units, no scaling)

| slice | name | units | meaning |
|---|---|---|---|
{layout}

The graph normalises the observation itself (the training normaliser's mean and std, clipped
at ±{obs['normalisation']['clip']:g}) and returns `actions` (raw, feed back into the history) and
`joint_targets` = default pose + {spec['action']['scale']:g} x actions (rad). Observation
noise used in training is listed per slice in `policy.json` (`training_noise`); add none on
the robot. Commands the policy was trained on: `policy.json` `commands.trained`.

## Check it

    python check.py             # 10 s at 0.5 m/s on the model: survival, speed, ONNX vs torch
    python check.py --json --seconds 20 --vx 0.3

The design sheet is `design.md` (`design.json` holds the same as data).
"""


# -- the folder --------------------------------------------------------------------------------
def make_handoff(run_dir: Path, out: Path, options: HandoffOptions | None = None,
                 progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Write the handoff folder `out` for the run in `run_dir`; returns what was written and
    measured (the `--json` line)."""
    from coadapt_core.handoff.policy import (
        ONNX_TOLERANCE,
        SpecialisedPolicy,
        export_onnx,
        torch_actions,
        verify_onnx,
    )
    from coadapt_core.learning.trainer import read_checkpoint
    from coadapt_core.plugins import get_registry
    from coadapt_core.viz.video import VIDEO_NAME, run_checkpoint

    options = options or HandoffOptions()
    say = progress or (lambda _line: None)
    started = time.perf_counter()
    run_dir = Path(run_dir).resolve()
    out = Path(out).absolute()
    config, summary = read_run(run_dir)
    _check_target(out, run_dir, options.force)
    registry = get_registry()
    robot = registry.create("robot", config.get("robot") or registry.default("robot"))
    sim_name = str(config.get("sim") or registry.default("simulator"))
    sim_cls = registry.get("simulator", sim_name)
    terrain = str(config.get("terrain") or "flat")
    seed = int(config.get("seed") or 0)
    checkpoint = run_checkpoint(run_dir, config)
    if checkpoint is None:
        raise UserError(f"run {run_dir.name} kept no universal policy checkpoint (a method without a shared policy "
                        "keeps none); there is no controller to hand off", field="run")
    state = read_checkpoint(checkpoint)
    if state.get("robot") != robot.name:
        raise UserError(f"the run's checkpoint was trained for robot '{state.get('robot')}', not '{robot.name}'",
                        field="run")
    best = np.asarray(summary["best_design"], dtype=float)
    design = best if options.design is None else np.asarray(options.design, dtype=float)
    nominal = summary.get("nominal_design")
    if not isinstance(nominal, list) or len(nominal) != len(design):
        nominal = robot.nominal_design(robot.design_space_for(design).is_mixed)
    nominal = np.asarray(nominal, dtype=float)
    num_design = int(state["dims"]["num_design"])
    if len(design) != num_design:
        raise UserError(f"--design has {len(design)} values; the run's policy takes {num_design} "
                        f"({', '.join(robot.design_space_for(best).names)})", field="design")
    space = robot.design_space_for(design)
    design = space.validate(design)
    is_best = bool(np.allclose(design, best))

    partial = out.parent / f".{out.name}.partial-{os.getpid()}"
    if partial.exists():
        shutil.rmtree(partial)
    partial.mkdir(parents=True)
    try:
        # -- model files
        try:
            model = robot.build(design)
        except NotImplementedError:
            raise UserError(f"robot '{robot.name}' supplies no model files (its build gives no MJCF and URDF); "
                            "there is nothing to hand off", field="robot") from None
        model_files = write_model_files(robot, model, partial)
        say(f"model: {model_files.mjcf.name}, {model_files.urdf.name}"
            + (f" and {len(model_files.assets)} asset files" if model_files.assets else " (no asset files referenced)"))

        # -- the controller: rollout, ONNX export, verification
        rollout = _rollout(robot, sim_cls, design, state, terrain, seed)
        policy: SpecialisedPolicy = rollout["policy"]
        task = rollout["task"]
        num_obs = int(state["dims"]["num_obs"])
        recorded = np.concatenate([_buffer_observations(run_dir, num_obs), rollout["obs"]])
        space_names = space.names
        metadata = {
            "description": f"coadapt universal policy specialised to {robot.name} design "
                           + ", ".join(f"{n}={x:g}" for n, x in zip(space_names, design, strict=True)),
            "robot": robot.name, "design": json.dumps([float(x) for x in design]), "run_id": str(summary.get("run_id")),
            "coadapt_version": __version__, "observation_layout": "see policy.json",
        }
        onnx_path = export_onnx(policy, partial / "policy.onnx", metadata)
        verification = verify_onnx(onnx_path, state, recorded, rollout["design_obs"], rollout["default_joint_pos"],
                                   task.action_scale, task.action_clip)
        say(f"ONNX vs torch on {verification['observations']} recorded observations: max |action difference| "
            f"{verification['max_abs_action_difference']:.2e} (tolerance {ONNX_TOLERANCE:g})")
        if not verification["max_abs_action_difference"] <= ONNX_TOLERANCE:
            raise HandoffRefused(
                f"the ONNX controller differs from the torch policy by {verification['max_abs_action_difference']:.2e} "
                f"> {ONNX_TOLERANCE:g} on the recorded observations; not handed off")
        pick = np.random.default_rng(0).choice(len(recorded), min(REFERENCE_ROWS, len(recorded)), replace=False)
        reference_obs = recorded[np.sort(pick)]
        reference_actions = np.clip(torch_actions(state, reference_obs, rollout["design_obs"]),
                                    -task.action_clip, task.action_clip).astype(np.float32)
        np.savez(partial / "reference.npz", obs=reference_obs, actions=reference_actions)

        files = {"mjcf": model_files.mjcf.name, "urdf": model_files.urdf.name, "onnx": onnx_path.name,
                 "reference": "reference.npz"}
        spec = policy_spec(robot=robot, model=model, design=design, space=space, state=state, rollout=rollout,
                           terrain=terrain, verification=verification, foot=foot_facts(model), files=files)
        (partial / "policy.json").write_text(json.dumps(jsonable(spec), indent=2) + "\n")
        shutil.copy(CHECK_SCRIPT, partial / "check.py")

        # -- measured: the run's final check and fresh paired evaluations per simulator
        evaluations = []
        if is_best and summary.get("best_costs"):
            evaluations.append(run_final_check(summary, config, sim_name))
        objectives = list((summary.get("best_costs") or {}).keys()) or [str(config.get("objective") or "")]
        simulators = list(options.simulators) if options.simulators else [sim_name] + [
            n for n in registry.names("simulator") if n != sim_name]
        steps = max(1, int(round(options.seconds / rollout["control_dt"])))
        for name in simulators:
            say(f"evaluating the design and the nominal one on {name} ({options.agents} paired scenarios x {steps} steps)")
            evaluations.append(evaluate_on(name, robot=robot, checkpoint=checkpoint, objectives=objectives,
                                           design=design, nominal=nominal, terrain=terrain, seed=seed,
                                           agents=options.agents, steps=steps))
            ev = evaluations[-1]
            say(f"  {name}: " + (ev["error"] if "error" in ev else "; ".join(
                f"{k} {v['design']:.4g} vs nominal {v['nominal']:.4g}" for k, v in ev["objectives"].items())
                + f"; fall rate {ev['design_fall_rate']:.2f} vs {ev['nominal_fall_rate']:.2f}"))

        # -- the picture
        gif_note = _copy_or_render_video(run_dir, partial, config, summary, design, nominal, checkpoint, is_best,
                                         options.video, VIDEO_NAME)
        say(f"picture: {gif_note}")

        # -- the sheet
        info = model.info if isinstance(model.info, dict) else {}
        body = sheet.link_facts(model)
        body["standing_base_height"] = float(model.standing_base_height)
        from coadapt_core.results.store import code_commit

        recorded_at_run = _recorded_commit(run_dir, str(summary.get("run_id") or run_dir.name))
        provenance = {
            "run_id": str(summary.get("run_id") or run_dir.name),
            "method": summary.get("method") or config.get("method"),
            "optimizer": summary.get("optimizer") or config.get("optimizer"),
            "objectives": objectives,
            "seed": seed,
            "simulator": sim_name,
            "preset": config.get("preset"),
            "starting_policy": (start := _starting_policy(robot, config))["policy"],
            "starting_policy_sha256": start["sha256"],
            "final_policy": str(checkpoint.relative_to(run_dir)) if run_dir in checkpoint.parents else checkpoint.name,
            "final_policy_sha256": sha256(checkpoint),
            "final_policy_steps": int(state.get("total_steps") or 0),
            "run_code_version": recorded_at_run.get("code_version"),
            "run_git_commit": recorded_at_run.get("git_commit"),
            "handoff_coadapt_version": __version__,
            "handoff_git_commit": code_commit(),
            "reliable": summary.get("reliable"),
            "reliability": summary.get("reliability"),
        }
        sheet_data = {
            "format": FORMAT,
            "robot": robot.name,
            "design_text": spec["design_text"],
            "design": [float(x) for x in design],
            "nominal_design": [float(x) for x in nominal],
            "is_run_best": is_best,
            "terrain": terrain,
            "parameters": sheet.design_parameters(space, design),
            "body": body,
            "robot_info": jsonable(info),
            "joints": sheet.joint_table(model),
            "validation": robot.validate(design).to_dict(),
            "evaluations": evaluations,
            "onnx": verification,
            "picture": gif_note,
            "provenance": provenance,
        }
        if options.check:
            vx = min(CHECK_VX, spec["commands"]["trained"]["vx"][1])
            sheet_data["controller_check"] = run_check(partial, options.check_seconds, vx)
            check = sheet_data["controller_check"]
            say("check.py: " + (check["error"] if "error" in check else
                f"survival {check['survival']:.2f}, mean forward speed {check['vx_mean']:.3f} m/s under "
                f"{vx:g} m/s for {check['seconds']:g} s"))
        (partial / "design.json").write_text(json.dumps(jsonable(sheet_data), indent=2) + "\n")
        (partial / "design.md").write_text(sheet.render_markdown(jsonable(sheet_data)))
        listing = [
            (files["mjcf"], "the design's MJCF (MuJoCo), from the robot plugin"),
            (files["urdf"], "the design's URDF (Pinocchio, PyBullet, ROS)"),
            *([("assets/", "files the models reference")] if model_files.assets else []),
            ("policy.onnx", "the controller: observation in, actions and joint targets out"),
            ("policy.json", "observation and action layouts, PD gains, rates, gait clock, commands, terrain"),
            ("design.md", "the design sheet (design.json: the same as data)"),
            ("check.py", "walks the model with the ONNX controller in MuJoCo (no coadapt needed)"),
            ("reference.npz", "recorded observations and the torch policy's actions on them"),
            *([(f"{VIDEO_NAME}.gif", "the design (left) and the nominal one (right) walking")]
              if (partial / f"{VIDEO_NAME}.gif").is_file() else []),
        ]
        (partial / "README.md").write_text(readme_text(spec, jsonable(sheet_data), listing))
        if out.exists():
            shutil.rmtree(out) if out.is_dir() else out.unlink()
        partial.rename(out)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    seconds = time.perf_counter() - started
    return {
        "out": str(out),
        "run_id": provenance["run_id"],
        "robot": robot.name,
        "design": [float(x) for x in design],
        "is_run_best": is_best,
        "max_abs_action_difference": verification["max_abs_action_difference"],
        "tolerance": ONNX_TOLERANCE,
        "evaluations": [{k: ev.get(k) for k in ("simulator", "source", "error", "design_fall_rate", "nominal_fall_rate")}
                        | {"objectives": ev.get("objectives")} for ev in evaluations],
        "controller_check": sheet_data.get("controller_check"),
        "files": sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()),
        "seconds": seconds,
    }


def _check_target(out: Path, run_dir: Path, force: bool) -> None:
    """`out` may be written: new, an empty folder, or (with --force) an earlier handoff
    folder; never the run folder, a folder holding it, or anything else that exists."""
    if out == run_dir or out in run_dir.parents:
        raise UserError(f"-o {out} is the run folder or holds it; give a new folder", field="out")
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return
    if not force:
        raise UserError(f"-o {out} exists; give another folder, or --force to replace an earlier handoff folder",
                        field="out")
    try:
        earlier = json.loads((out / "policy.json").read_text()).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        earlier = False
    if not earlier:
        raise UserError(f"-o {out} exists and is not a handoff folder (no policy.json of {FORMAT}); --force replaces "
                        "only those", field="out")


class HandoffRefused(CoadaptError):
    """The controller failed its own check (ONNX against torch): nothing is handed off."""


def run_check(folder: Path, seconds: float, vx: float) -> dict[str, Any]:
    """Run the folder's check.py in a fresh interpreter (its own imports only) and return its
    JSON result, or {"error": ...}."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    try:
        done = subprocess.run([sys.executable, "check.py", "--json", "--seconds", f"{seconds:g}", "--vx", f"{vx:g}"],
                              cwd=folder, capture_output=True, text=True, timeout=600, env=env)
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


def _copy_or_render_video(run_dir: Path, folder: Path, config: dict[str, Any], summary: dict[str, Any],
                          design: np.ndarray, nominal: np.ndarray, checkpoint: Path, is_best: bool, render: bool,
                          name: str) -> str:
    """The run's best-vs-nominal GIF (and MP4) when it shows this design; else a fresh one
    when `render`; a line saying which."""
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
    written = render_run_video(folder, {"best_design": [float(x) for x in design],
                                        "nominal_design": [float(x) for x in nominal]},
                               {**config, "checkpoint": str(checkpoint)}, stream=stream)
    if written:
        return f"{name}.gif rendered by coadapt handoff"
    return "none (" + " ".join(stream.getvalue().split())[:200] + ")"


__all__ = ["HandoffOptions", "HandoffRefused", "find_run", "make_handoff", "read_run"]
