"""Shared test helpers: a floor scene and a PD standing rollout in real MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import torch

from coadapt_core.physics.actuation import pd_torque
from coadapt_core.robot import RobotModel


def with_floor(model: RobotModel) -> mujoco.MjModel:
    """The robot's MJCF plus a ground plane that collides with it (the simulators add
    terrain the same way, through MjSpec)."""
    spec = mujoco.MjSpec.from_string(model.text("mjcf"))
    floor = spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1]
    )
    floor.contype, floor.conaffinity = 1, 1
    return spec.compile()


def standing_data(model: RobotModel, mj: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(mj)
    data.qpos[2] = model.standing_base_height
    data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
    data.qpos[7:15] = model.default_joint_pos
    mujoco.mj_forward(mj, data)
    return data


def stand_under_pd(
    model: RobotModel,
    seconds: float,
    push: tuple[float, float] = (0.0, 0.0),
    gain_factor: float = 1.0,
) -> dict[str, float]:
    """Hold the default pose with the shared PD law for `seconds` on flat ground, adding a
    base velocity `push` (vx, vy) after 1 s. Returns the final base tilt (rad), the base's
    drop below its standing height (m) and the largest joint error (rad)."""
    mj = with_floor(model)
    data = standing_data(model, mj)
    target = model.default_joint_pos[None]  # [1, 8]
    for k in range(int(round(seconds / mj.opt.timestep))):
        state = (
            target,
            data.qpos[None, 7:15],
            data.qvel[None, 6:14],
            model.kp,
            model.kd,
            model.torque_limit,
            model.speed_limit,
        )
        data.ctrl[:] = pd_torque(
            *(torch.tensor(a, dtype=torch.float64) for a in state),
            pd_factor=gain_factor,
            motor_strength=gain_factor,
        )[0].numpy()
        if k == int(round(1.0 / mj.opt.timestep)):
            data.qvel[0] += push[0]
            data.qvel[1] += push[1]
        mujoco.mj_step(mj, data)
    tilt = 2.0 * float(np.arccos(min(1.0, abs(data.qpos[3]))))
    return {
        "tilt": tilt,
        "drop": model.standing_base_height - float(data.qpos[2]),
        "joint_error": float(np.abs(data.qpos[7:15] - model.default_joint_pos).max()),
    }
