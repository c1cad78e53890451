"""Spec robots of every hinge layout MuJoCo accepts and with meshes in the links a design
scales: stacked hinges (a hip of three hinges in one body, an ankle of two at different
anchors) go through the build, `robot validate` (Pinocchio joint by joint), the URDF writer
(intermediate links) and both simulators; visual meshes stretch with their link, collision
meshes stretch when aligned with it, are fitted on request or refused in one line."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from coadapt_plugins.robots.specs.robot import spec_robot_class

#: a biped whose hips are three stacked hinges (the last off the body's origin on the left)
#: and whose ankles are two hinges at different anchors, as in MuJoCo's classic humanoid
STACKED = """<mujoco model="stack">
  <compiler angle="degree"/>
  <default>
    <joint damping="0.5" armature="0.01" limited="true"/>
    <geom contype="1" conaffinity="1" density="800"/>
  </default>
  <worldbody>
    <body name="pelvis" pos="0 0 0.8">
      <freejoint/>
      <geom name="pelvis" type="box" size="0.08 0.14 0.05"/>
      {legs}
    </body>
  </worldbody>
  <actuator>{motors}</actuator>
  <keyframe>
    <key name="stand" qpos="0 0 0.8 1 0 0 0 {stand}"/>
  </keyframe>
</mujoco>
"""
LEG = """<body name="{s}_thigh" pos="0 {y} -0.06">
        <joint name="{s}_hip_x" axis="1 0 0" range="-30 30"/>
        <joint name="{s}_hip_z" axis="0 0 1" range="-40 40"/>
        <joint name="{s}_hip_y" axis="0 1 0" range="-100 30" pos="0 0 {hy}"/>
        <geom name="{s}_thigh" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.04"/>
        <body name="{s}_shin" pos="0 0 -0.34">
          <joint name="{s}_knee" axis="0 1 0" range="0 140" pos="0 0 0.02"/>
          <geom name="{s}_shin" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.035"/>
          <body name="{s}_foot" pos="0 0 -0.34">
            <joint name="{s}_ankle_y" axis="0 1 0" range="-50 50" pos="0 0 0.04"/>
            <joint name="{s}_ankle_x" axis="1 0 0.5" range="-30 30" pos="0 0 0.02"/>
            <geom name="{s}_foot" type="box" pos="0.03 0 -0.01" size="0.09 0.04 0.015"/>
          </body>
        </body>
      </body>"""
JOINTS = ["hip_x", "hip_z", "hip_y", "knee", "ankle_y", "ankle_x"]
STAND = [0.0, 0.0, -0.3, 0.6, -0.3, 0.0]

SPEC = {
    "name": "stack",
    "description": "a biped with stacked hinges at the hips and ankles",
    "model": "model.xml",
    "base": "pelvis",
    "design": [
        {
            "name": "thigh_scale",
            "bounds": [0.7, 1.3],
            "nominal": 1.0,
            "links": [["left_thigh", "left_shin"], ["right_thigh", "right_shin"]],
        },
        {
            "name": "shin_scale",
            "bounds": [0.7, 1.3],
            "nominal": 1.0,
            "links": [["left_shin", "left_foot"], ["right_shin", "right_foot"]],
        },
    ],
    "limits": {"torque": {".*": 80.0}, "speed": {".*": 20.0}},
    "legs": [
        {"name": "left", "foot": "left_foot", "phase": 0.0, "hip": "left_thigh"},
        {"name": "right", "foot": "right_foot", "phase": 0.5, "hip": "right_thigh"},
    ],
    "standing_pose": {"keyframe": "stand"},
    "gains": {".*": {"kp": 80.0, "kd": 2.0}},
}


def stacked_model(legs_extra: str = "") -> str:
    legs, motors = [], []
    for side, y, hy in (("left", 0.09, 0.01), ("right", -0.09, 0.0)):
        legs.append(LEG.format(s=side, y=y, hy=hy))
        motors += [f'<motor joint="{side}_{j}" gear="1"/>' for j in JOINTS]
    stand = " ".join(str(a) for a in STAND * 2)
    text = STACKED.format(legs="\n      ".join(legs), motors="".join(motors), stand=stand)
    return text.replace("<!--extra-->", legs_extra)


def write_robot_folder(folder: Path, model: str, spec: dict | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.xml").write_text(model)
    (folder / "robot.yaml").write_text(yaml.safe_dump(spec or SPEC, sort_keys=False))
    return folder


@pytest.fixture
def stack(tmp_path: Path) -> Path:
    return write_robot_folder(tmp_path / "stack", stacked_model())


def _cli(args: list[str], robot_path: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, COADAPT_ROBOT_PATH=str(robot_path))
    return subprocess.run(
        [sys.executable, "-m", "coadapt_core", *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=300,
    )


# -- stacked hinges ---------------------------------------------------------------------------


def test_stacked_hinges_write_a_urdf_whose_frames_are_mujocos(stack):
    """The URDF's bodies sit where MuJoCo puts them at any joint angles: each stacked hinge
    turns an intermediate link at its anchor, and the body's own link is fixed below."""
    import pinocchio as pin

    robot = spec_robot_class(stack)()
    model = robot.build(np.array([1.2, 0.8]))
    urdf = model.text("urdf")
    assert urdf.count('type="revolute"') == 12
    assert 'link name="left_thigh__left_hip_x"' in urdf
    assert 'joint name="left_thigh_fixed"' in urdf  # left hip_y sits 1 cm off the origin
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = mujoco.MjData(mj)
    import re

    text = re.sub(r"<(visual|collision)>.*?</\1>", "", urdf, flags=re.S)
    pm = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
    pd = pm.createData()
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = pin.neutral(pm)
        q[:3] = [0.1, -0.2, 0.9]
        data.qpos[:7] = [0.1, -0.2, 0.9, 1, 0, 0, 0]
        for name in model.joint_names:
            angle = rng.uniform(-0.5, 0.5)
            q[pm.joints[pm.getJointId(name)].idx_q] = angle
            data.qpos[mj.jnt_qposadr[mj.joint(name).id]] = angle
        mujoco.mj_kinematics(mj, data)
        pin.forwardKinematics(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        for body in ("left_thigh", "left_shin", "left_foot", "right_foot"):
            frame = pd.oMf[pm.getFrameId(body)]
            np.testing.assert_allclose(frame.translation, data.xpos[mj.body(body).id], atol=1e-9)
            np.testing.assert_allclose(
                frame.rotation, data.xmat[mj.body(body).id].reshape(3, 3), atol=1e-9
            )


@pytest.mark.parametrize("design", [[1.0, 1.0], [0.7, 1.3], [1.3, 0.7]])
def test_stacked_hinges_validate_joint_by_joint(stack, design):
    robot = spec_robot_class(stack)()
    report = robot.validate(np.array(design))
    assert report.feasible, report.reasons
    found = {f.check: f for f in report.findings}
    assert found["consistency.pinocchio"].value <= 1e-9
    # left: hip 3 (its last hinge off the origin), knee 1, ankle 2; right: hip 2, knee 1, ankle 2
    assert "11 intermediate links" in found["consistency.pinocchio"].message


def test_pinocchio_composite_joints_are_read_through_their_coordinates(stack):
    """Without a URDF Pinocchio reads the MJCF, merging each body's hinges into one joint
    with nq > 1: the comparison indexes its coordinates and agrees as closely."""
    import dataclasses

    from coadapt_plugins.robots.specs.validation import validate_spec_model

    robot = spec_robot_class(stack)()
    model = robot.build(np.array([1.1, 0.9]))
    mjcf_only = dataclasses.replace(model, formats={"mjcf": model.text("mjcf")})
    report = validate_spec_model(robot, mjcf_only)
    found = {f.check: f for f in report.findings}
    assert "MJCF" in found["consistency.pinocchio"].message
    assert found["consistency.pinocchio"].value <= 1e-9, found["consistency.pinocchio"].message


def test_the_leg_ik_turns_each_stacked_hinge(stack):
    """Each stacked hinge is a joint of the leg's chain: feet land where MuJoCo's kinematics
    of the design's own model puts them, off-origin anchors included."""
    import torch

    robot = spec_robot_class(stack)()
    kin = robot._built.kinematics
    assert kin.chain.joint_index.shape == (2, 6)  # six hinges per leg, each its own slot
    for design in ([1.0, 1.0], [1.3, 0.7]):
        model = robot.build(np.array(design))
        designs = torch.tensor(design, dtype=torch.float64)[None]
        default = robot.default_foot_positions(designs)
        targets = default + torch.tensor([0.05, 0.03, 0.04], dtype=torch.float64)
        q = robot.leg_inverse_kinematics(designs, targets)[0].numpy()
        hips = kin.standing(designs)[2][0].numpy()
        feet = _mujoco_feet(model, q) - hips
        assert np.abs(feet - targets[0].numpy()).max() < 1e-6
        standing = _mujoco_feet(model, model.default_joint_pos) - hips
        np.testing.assert_allclose(standing, default[0].numpy(), atol=1e-9)
        # the hip's roll hinge took part (the target is 3 cm to the side)
        left_hip_x = model.joint_names.index("left_hip_x")
        assert abs(q[left_hip_x] - model.default_joint_pos[left_hip_x]) > 1e-3


def _mujoco_feet(model, q: np.ndarray) -> np.ndarray:
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = mujoco.MjData(compiled)
    data.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
    for name, angle in zip(model.joint_names, q, strict=True):
        data.qpos[compiled.jnt_qposadr[compiled.joint(name).id]] = angle
    mujoco.mj_kinematics(compiled, data)
    return np.array([data.xpos[compiled.body(f).id] for f in model.foot_bodies])


@pytest.mark.slow
def test_stacked_hinges_stand_alike_in_mujoco_and_pybullet(stack):
    """Both simulators hold the nominal design's standing pose with PD for 2 s (100 control
    steps): the base stays within 2 cm of its standing height and the two agree within
    2 mm (PyBullet through the URDF's intermediate links)."""
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.plugins import get_registry

    pytest.importorskip("pybullet")
    robot = spec_robot_class(stack)()
    model = robot.build(robot.nominal_design())
    heights = {}
    for name in ("mujoco", "pybullet"):
        options = {"processes": 0} if name == "pybullet" else {}
        sim = get_registry().get("simulator", name)(
            robot, robot.nominal_design()[None], randomization=RandomizationConfig.off(),
            seed=0, num_threads=1, **options,
        )  # fmt: skip
        sim.reset()
        targets = sim.default_joint_pos.clone()
        trace = [float(sim.step(targets).base_pos[0, 2]) for _ in range(100)]
        sim.close()
        heights[name] = np.array(trace)
        assert np.all(np.isfinite(trace))
        assert np.abs(heights[name] - model.standing_base_height).max() < 0.02, name
    assert np.abs(heights["mujoco"] - heights["pybullet"]).max() < 0.002
