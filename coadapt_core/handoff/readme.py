"""The handoff folder's README: the files, how to load the model and run the controller in
a few lines, the observation layout, and how to check it."""

from __future__ import annotations

from typing import Any

from coadapt_core import __version__


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


