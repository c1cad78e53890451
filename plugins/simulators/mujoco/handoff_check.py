#!/usr/bin/env python3
"""Run a handoff folder's ONNX controller on its robot model in MuJoCo, without coadapt.

Copied into every handoff folder as `check.py` (`coadapt handoff`). It needs numpy, mujoco
and onnxruntime only, and reads everything else from the folder: `policy.json` (layouts,
gains, rates, clock), the MJCF, `policy.onnx` and `reference.npz`. It rebuilds the policy
observation exactly as coadapt's locomotion task does in training (no observation noise,
nominal physics: no randomization, no delay), applies the PD law with the motors'
torque-speed envelope at the physics rate, and walks the robot under a constant command.

    python check.py                       # 10 s at vx = 0.5 m/s, prints survival and speed
    python check.py --seconds 20 --vx 0.3 --json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def quat_rotate_inverse(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """World vector `vec` [3] in the frame of unit quaternion `quat` (w, x, y, z) [4]."""
    w, u = quat[0], quat[1:4]
    return vec * (2.0 * w * w - 1.0) - np.cross(u, vec) * (2.0 * w) + u * (2.0 * np.dot(u, vec))


def pd_torque(spec: dict, target: np.ndarray, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """tau = kp (target - q) - kd dq, clipped to the torque-speed envelope of each motor:
    [-tau_max clip(1 + dq / dq_max, 0, 1), tau_max clip(1 - dq / dq_max, 0, 1)]."""
    joints = spec["joints"]
    kp, kd = np.array(joints["kp"]), np.array(joints["kd"])
    tau_max, dq_max = np.array(joints["torque_limit"]), np.array(joints["speed_limit"])
    ratio = dq / dq_max
    upper = tau_max * np.clip(1.0 - ratio, 0.0, 1.0)
    lower = -tau_max * np.clip(1.0 + ratio, 0.0, 1.0)
    return np.clip(kp * (target - q) - kd * dq, lower, upper)


def terrain_height(spec: dict, terrain: str, x: float) -> float:
    return (
        x * math.tan(math.radians(spec["terrain"]["slope_degrees"])) if terrain == "slope" else 0.0
    )


class Robot:
    """The folder's MJCF with the ground added, at the physics step the policy was trained at."""

    def __init__(self, spec: dict, folder: Path, terrain: str):
        import mujoco

        self.mujoco = mujoco
        self.spec, self.terrain = spec, terrain
        mjspec = mujoco.MjSpec.from_file(str(folder / spec["files"]["mjcf"]))
        mjspec.option.timestep = spec["rates"]["physics_dt"]
        slope = math.radians(spec["terrain"]["slope_degrees"]) if terrain == "slope" else 0.0
        # the plane rotated about y by -slope rises along +x; conaffinity 1 meets the robot's
        # contact geoms (contype 1, conaffinity 0)
        mjspec.worldbody.add_geom(
            name="ground",
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0, 0, 1],
            quat=[math.cos(-slope / 2), 0.0, math.sin(-slope / 2), 0.0],
            contype=0,
            conaffinity=1,
        )
        for actuator in mjspec.actuators:  # the motor envelope below is the one torque limit
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        self.model = model = mjspec.compile()
        model.geom_friction[:, 0] = spec["simulation"]["friction"]  # every geom, ground included
        self.data = mujoco.MjData(model)
        names = spec["action"]["joint_order"]
        jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        self.qadr = model.jnt_qposadr[jids]
        self.dadr = model.jnt_dofadr[jids]
        self.act = np.zeros(len(jids), dtype=int)
        for a in range(model.nu):
            self.act[jids.index(int(model.actuator_trnid[a, 0]))] = a
        base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, spec["simulation"]["base_body"])
        joint = model.body_jntadr[base]
        self.base_q, self.base_v = int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])
        self.default = np.array(spec["action"]["default_joint_pos"])

    def reset(self) -> None:
        """Standing pose, base upright at its standing height above the ground under the feet."""
        m, d, sim = self.model, self.data, self.spec["simulation"]
        self.mujoco.mj_resetData(m, d)
        ground = 0.0
        if self.terrain == "slope":  # the highest ground within reach of a sole
            reach = max(x for x, _ in sim["foot_xy"]) + sim["foot_radius"]
            ground = terrain_height(self.spec, self.terrain, reach)
        z = sim["standing_base_height"] + ground + sim["spawn_clearance"]
        d.qpos[self.base_q : self.base_q + 7] = [0.0, 0.0, z, 1.0, 0.0, 0.0, 0.0]
        d.qpos[self.qadr] = self.default
        self.mujoco.mj_forward(m, d)
        self.standing_height = z - terrain_height(self.spec, self.terrain, 0.0)

    def step(self, targets: np.ndarray) -> None:
        """One policy period: `decimation` physics steps holding the joint targets."""
        for _ in range(self.spec["rates"]["decimation"]):
            q, dq = self.data.qpos[self.qadr], self.data.qvel[self.dadr]
            self.data.ctrl[self.act] = pd_torque(self.spec, targets, q, dq)
            self.mujoco.mj_step(self.model, self.data)

    def base(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(position [3] world, quaternion [4], linear velocity [3] world, angular velocity [3] "
        "base frame)."""
        q, v = self.data.qpos, self.data.qvel
        b, w = self.base_q, self.base_v
        return (
            q[b : b + 3].copy(),
            q[b + 3 : b + 7].copy(),
            v[w : w + 3].copy(),
            v[w + 3 : w + 6].copy(),
        )


class Controller:
    """The policy observation (policy.json's layout), the gait clock and the action history."""

    def __init__(self, spec: dict, onnx_path: Path, command: np.ndarray, phase: float):
        import onnxruntime as ort

        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        self.session = ort.InferenceSession(
            str(onnx_path), options, providers=["CPUExecutionProvider"]
        )
        self.spec = spec
        self.command = np.asarray(command, dtype=float)
        joints = len(spec["action"]["joint_order"])
        self.history = np.zeros((spec["observation"]["history"], joints))  # newest first
        gait = spec["gait"]
        self.moving = bool(np.abs(self.command).sum() > 0)
        self.phase = (
            phase
            if (self.moving or not gait["freeze_on_zero_command"])
            else gait["zero_command_phase"]
        )

    def observe(self, robot: Robot) -> np.ndarray:
        _, quat, lin_world, ang_base = robot.base()
        parts = {
            "base_lin_vel": quat_rotate_inverse(quat, lin_world),
            "base_ang_vel": ang_base,
            "projected_gravity": quat_rotate_inverse(quat, np.array([0.0, 0.0, -1.0])),
            "command": self.command,
            "joint_pos": robot.data.qpos[robot.qadr] - robot.default,
            "joint_vel": robot.data.qvel[robot.dadr],
            "action_history": self.history.reshape(-1),
            "clock": np.array(
                [math.sin(2 * math.pi * self.phase), math.cos(2 * math.pi * self.phase)]
            ),
        }
        obs = np.concatenate([parts[item["name"]] for item in self.spec["observation"]["slices"]])
        return obs.astype(np.float32)[None, :]  # [1, num_obs]

    def act(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        actions, targets = self.session.run(["actions", "joint_targets"], {"obs": obs})
        return actions[0], targets[0]

    def advance(self, actions: np.ndarray) -> None:
        """After each policy period: the clock moves on (held under a zero command) and the
        action joins the history."""
        gait = self.spec["gait"]
        if self.moving or not gait["freeze_on_zero_command"]:
            self.phase = (self.phase + self.spec["rates"]["control_dt"] * gait["frequency"]) % 1.0
        self.history = np.roll(self.history, 1, axis=0)
        self.history[0] = actions


def fell(spec: dict, robot: Robot) -> bool:
    pos, quat, _, _ = robot.base()
    height = pos[2] - terrain_height(spec, robot.terrain, pos[0])
    gravity_z = quat_rotate_inverse(quat, np.array([0.0, 0.0, -1.0]))[2]
    end = spec["termination"]
    return bool(
        height < end["min_base_height"] * robot.standing_height or gravity_z > -end["max_tilt_cos"]
    )


def check_reference(spec: dict, folder: Path) -> tuple[float, int] | None:
    """(max |ONNX - torch| action difference, rows) on the recorded observations of "
    "reference.npz."""
    path = folder / spec["files"]["reference"]
    if not path.is_file():
        return None
    import onnxruntime as ort

    data = np.load(path, allow_pickle=False)
    session = ort.InferenceSession(
        str(folder / spec["files"]["onnx"]), providers=["CPUExecutionProvider"]
    )
    (actions,) = session.run(["actions"], {"obs": data["obs"].astype(np.float32)})
    return float(np.max(np.abs(actions - data["actions"]))), len(actions)


def walk(
    folder: Path,
    seconds: float,
    command: list[float],
    terrain: str | None = None,
    phase: float = 0.0,
) -> dict:
    spec = json.loads((folder / "policy.json").read_text())
    terrain = terrain or (
        spec["terrain"]["name"] if spec["terrain"]["name"] in ("flat", "slope") else "flat"
    )
    robot = Robot(spec, folder, terrain)
    robot.reset()
    controller = Controller(spec, folder / spec["files"]["onnx"], np.array(command), phase)
    dt = spec["rates"]["control_dt"]
    steps = int(round(seconds / dt))
    vx, survived = [], 0
    obs = controller.observe(robot)
    start = robot.base()[0]
    for _ in range(steps):
        actions, targets = controller.act(obs)
        robot.step(targets.astype(np.float64))
        controller.advance(actions)
        obs = controller.observe(robot)
        _, quat, lin_world, _ = robot.base()
        vx.append(float(quat_rotate_inverse(quat, lin_world)[0]))  # base-frame forward velocity
        if fell(spec, robot):
            break
        survived += 1
    end = robot.base()[0]
    return {
        "terrain": terrain,
        "command": [float(c) for c in command],
        "seconds": seconds,
        "survival": survived / max(steps, 1),
        "survived_seconds": survived * dt,
        "vx_mean": float(np.mean(vx)) if vx else 0.0,
        "distance_x": float(end[0] - start[0]),
        "lateral_drift": float(end[1] - start[1]),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Walk this folder's robot with its ONNX controller in MuJoCo."
    )
    parser.add_argument(
        "--seconds", type=float, default=10.0, help="simulated seconds (default 10)"
    )
    parser.add_argument(
        "--vx", type=float, default=0.5, help="forward velocity command, m/s (default 0.5)"
    )
    parser.add_argument("--vy", type=float, default=0.0, help="lateral velocity command, m/s")
    parser.add_argument("--yaw", type=float, default=0.0, help="yaw-rate command, rad/s")
    parser.add_argument(
        "--terrain",
        choices=("flat", "slope"),
        default=None,
        help="ground (default: the one the policy was trained on; flat for the random terrain)",
    )
    parser.add_argument(
        "--phase", type=float, default=0.0, help="initial gait clock phase in [0, 1)"
    )
    parser.add_argument("--json", action="store_true", help="print the result as one JSON line")
    args = parser.parse_args(argv)
    if not (args.seconds > 0 and 0.0 <= args.phase < 1.0):
        print("error: --seconds must be > 0 and --phase in [0, 1)", file=sys.stderr)
        return 2
    spec = json.loads((HERE / "policy.json").read_text())
    reference = check_reference(spec, HERE)
    difference, rows = reference if reference is not None else (None, 0)
    tolerance = spec["onnx"]["tolerance"]
    result = walk(HERE, args.seconds, [args.vx, args.vy, args.yaw], args.terrain, args.phase)
    result["onnx_vs_torch_max_abs_action_difference"] = difference
    if args.json:
        print(json.dumps(result))
    else:
        if difference is not None:
            print(
                f"ONNX vs torch on {rows} recorded observations (reference.npz): "
                f"max |action difference| {difference:.2e} (tolerance {tolerance:g})"
            )
        print(
            f"{spec['robot']} {spec['design_text']} on {result['terrain']} ground, command vx "
            f"{args.vx:g} m/s "
            f"vy {args.vy:g} m/s yaw {args.yaw:g} rad/s for {args.seconds:g} s: survival "
            f"{result['survival']:.2f} "
            f"({result['survived_seconds']:.2f} s), mean forward speed {result['vx_mean']:.3f} "
            "m/s, "
            f"distance {result['distance_x']:.2f} m, lateral drift {result['lateral_drift']:+.2f} m"
        )
    if difference is not None and difference > tolerance:
        print(
            f"error: the ONNX controller differs from the torch policy by {difference:.2e} > "
            f"{tolerance:g}",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
