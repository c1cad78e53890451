"""The MuJoCo simulator's model tools (`Simulator.model_tools`; the contract is in
`coadapt_core.physics.model_tools`): a robot's MJCF compiled and posed, nothing simulated,
for the handoff's design sheet and the robot conformance suite, plus the handoff folder's
standalone check (`handoff_check.py`, copied as check.py) and its README's usage sketch."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

#: the robot model format these tools read (`RobotModel.formats` key)
MODEL_FORMAT = "mjcf"
#: walks a handoff folder's model with its ONNX controller (numpy, mujoco, onnxruntime only)
HANDOFF_CHECK = Path(__file__).with_name("handoff_check.py")


def _compiled(model: Any) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(model.text(MODEL_FORMAT))


def _pose(
    mj: mujoco.MjModel, model: Any, joint_pos: np.ndarray, base_height: float | None = None
) -> mujoco.MjData:
    """Data with the actuated joints at `joint_pos` (the base at its reference placement, or
    upright at `base_height` when it has a free joint), kinematics computed."""
    data = mujoco.MjData(mj)
    base = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, model.base_body)
    if (
        base_height is not None
        and base >= 0
        and mj.body_jntnum[base] > 0
        and mj.jnt_type[mj.body_jntadr[base]] == mujoco.mjtJoint.mjJNT_FREE
    ):
        adr = mj.jnt_qposadr[mj.body_jntadr[base]]
        data.qpos[adr : adr + 7] = [0.0, 0.0, base_height, 1.0, 0.0, 0.0, 0.0]
    for name, q in zip(model.joint_names, joint_pos, strict=True):
        data.qpos[mj.jnt_qposadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)]] = q
    mujoco.mj_kinematics(mj, data)
    return data


def link_facts(model: Any) -> dict[str, Any]:
    """Bodies, total mass and height of a `RobotModel` at its default pose, the base upright
    at its standing height."""
    mj = _compiled(model)
    data = _pose(mj, model, model.default_joint_pos, base_height=model.standing_base_height)
    links = []
    for b in range(1, mj.nbody):
        parent = int(mj.body_parentid[b])
        joints = [
            mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, j)
            for j in range(mj.body_jntadr[b], mj.body_jntadr[b] + mj.body_jntnum[b])
        ]
        links.append(
            {
                "name": mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}",
                "parent": (mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, parent) or "world")
                if parent
                else "world",
                "joints": [j for j in joints if j],
                "offset_from_parent": float(np.linalg.norm(mj.body_pos[b])) if parent else None,
                "mass": float(mj.body_mass[b]),
                "com": [float(x) for x in mj.body_ipos[b]],
                "principal_inertia": [float(x) for x in mj.body_inertia[b]],
            }
        )
    # height: the geoms' bounding boxes at the default pose, the base at its standing height
    low, high = math.inf, -math.inf
    for g in range(mj.ngeom):
        if mj.geom_bodyid[g] == 0:
            continue
        centre, half = mj.geom_aabb[g, :3], mj.geom_aabb[g, 3:]
        corners = (
            np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
            + centre
        )
        z = data.geom_xpos[g, 2] + corners @ data.geom_xmat[g].reshape(3, 3)[2]
        low, high = min(low, float(z.min())), max(high, float(z.max()))
    return {
        "links": links,
        "total_mass": float(mj.body_subtreemass[0]),
        "height": high - low if math.isfinite(high) else None,
        "lowest_point": low if math.isfinite(low) else None,
    }


def foot_positions(model: Any, joint_pos: np.ndarray) -> np.ndarray:
    """[F, 3] each foot body's origin in the base frame, the joints at `joint_pos`."""
    mj = _compiled(model)
    data = _pose(mj, model, np.asarray(joint_pos, dtype=float))
    base = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, model.base_body)
    feet = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, f) for f in model.foot_bodies]
    rot = data.xmat[base].reshape(3, 3)
    return np.stack([rot.T @ (data.xpos[f] - data.xpos[base]) for f in feet])


def actuated_joints(model: Any) -> list[str | None]:
    """The joint each actuator drives, in actuator order (None: it drives no joint)."""
    mj = _compiled(model)
    return [
        mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, int(mj.actuator_trnid[a, 0]))
        if mj.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
        else None
        for a in range(mj.nu)
    ]


def handoff_usage(rates: dict[str, Any], model_file: str) -> str:
    """The handoff README's section: load the model and run the controller in a few lines."""
    return f"""## Load the model and run the controller (numpy, mujoco, onnxruntime)

The policy was trained with the robot on a ground plane at a physics step of
{rates["physics_dt"]:g} s and a policy period of {rates["control_dt"]:g} s
({rates["decimation"]} physics steps per action, {rates["control_hz"]:g} Hz). `check.py` is
the full version of this (clock, falls, speed):

```python
import json, math, mujoco, numpy as np, onnxruntime as ort
p = json.load(open("policy.json")); J = p["action"]["joint_order"]; g = np.array([0.0, 0.0, -1.0])
spec = mujoco.MjSpec.from_file("{model_file}"); spec.option.timestep = p["rates"]["physics_dt"]
spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=0, conaffinity=1)
for a in spec.actuators: a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
m = spec.compile(); d = mujoco.MjData(m); policy = ort.InferenceSession("policy.onnx")
qa = m.jnt_qposadr[[m.joint(n).id for n in J]]; va = m.jnt_dofadr[[m.joint(n).id for n in J]]
q0 = np.array(p["action"]["default_joint_pos"])
kp, kd = np.array(p["joints"]["kp"]), np.array(p["joints"]["kd"])
d.qpos[:7] = [0, 0, p["simulation"]["standing_base_height"] + 0.002, 1, 0, 0, 0]
d.qpos[qa] = q0; mujoco.mj_forward(m, d)
def rot(q, v):  # world -> base
    return v * (2 * q[0] ** 2 - 1) - np.cross(q[1:], v) * 2 * q[0] + q[1:] * 2 * q[1:] @ v
hist, phase, cmd = np.zeros((p["observation"]["history"], len(J))), 0.0, np.array([0.5, 0.0, 0.0])
for step in range(round(10 / p["rates"]["control_dt"])):  # 10 s
    clock = [math.sin(2 * math.pi * phase), math.cos(2 * math.pi * phase)]
    obs = np.concatenate([rot(d.qpos[3:7], d.qvel[:3]), d.qvel[3:6], rot(d.qpos[3:7], g), cmd,
                          d.qpos[qa] - q0, d.qvel[va], hist.ravel(), clock])
    action, target = policy.run(None, {{"obs": obs[None].astype(np.float32)}})
    for _ in range(p["rates"]["decimation"]):  # PD at the physics rate (check.py: motor limits too)
        d.ctrl[:] = kp * (target[0] - d.qpos[qa]) - kd * d.qvel[va]; mujoco.mj_step(m, d)
    hist = np.roll(hist, 1, axis=0); hist[0] = action[0]
    phase = (phase + p["rates"]["control_dt"] * p["gait"]["frequency"]) % 1
print("base x after 10 s:", d.qpos[0])
```

(This sketch assumes the free joint is the model's first joint and one actuator per joint in
joint order, as the robot's MJCF has them; `check.py` looks both up by name.)
"""
