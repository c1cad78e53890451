"""Spec robots of every hinge layout MuJoCo accepts and with meshes in the links a design
scales: stacked hinges (a hip of three hinges in one body, an ankle of two at different
anchors) go through the build, `robot validate` (Pinocchio joint by joint), the URDF writer
(intermediate links) and both simulators; visual meshes stretch with their link, collision
meshes stretch when aligned with it, are fitted on request or refused in one line."""

from __future__ import annotations

import os
import re
import struct
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from coadapt_plugins.robots.specs.robot import spec_robot_class

from coadapt_core.errors import UserError

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


def with_refs(model: str) -> str:
    """The left knee and ankle roll given a `ref` (the angle at which MuJoCo leaves them
    unturned): 20 and -10 deg."""
    return model.replace(
        'name="left_knee" axis="0 1 0"', 'name="left_knee" axis="0 1 0" ref="20"'
    ).replace('name="left_ankle_x" axis="1 0 0.5"', 'name="left_ankle_x" axis="1 0 0.5" ref="-10"')


@pytest.fixture(params=["plain", "refs"])
def stacks(tmp_path: Path, request) -> Path:
    """The stacked-hinge biped as written, and with hinges that have a `ref`."""
    model = stacked_model() if request.param == "plain" else with_refs(stacked_model())
    return write_robot_folder(tmp_path / "stack", model)


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


def test_stacked_hinges_write_a_urdf_whose_frames_are_mujocos(stacks):
    """The URDF's bodies sit where MuJoCo puts them at any joint angles: each stacked hinge
    turns an intermediate link at its anchor, and the body's own link is fixed below."""
    import pinocchio as pin

    robot = spec_robot_class(stacks)()
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


def test_the_leg_ik_turns_each_stacked_hinge(stacks):
    """Each stacked hinge is a joint of the leg's chain: feet land where MuJoCo's kinematics
    of the design's own model puts them, off-origin anchors included."""
    import torch

    robot = spec_robot_class(stacks)()
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


# -- meshes in scaled links -------------------------------------------------------------------


def box_triangles(half: tuple[float, float, float]) -> np.ndarray:
    """[12, 3, 3] the outward triangles of a box of half-sizes `half` about the origin."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return np.array(
        [corners[[a, b, c]] for a, b, c, d in faces for a, b, c in ((a, b, c), (a, c, d))]
    )


def write_stl(path: Path, triangles: np.ndarray) -> None:
    """A binary STL (what vendors ship)."""
    out = [b"coadapt test mesh".ljust(80), struct.pack("<I", len(triangles))]
    for tri in triangles:
        normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        out.append(struct.pack("<12fH", *normal, *tri.ravel(), 0))
    path.write_bytes(b"".join(out))


def write_obj(path: Path, triangles: np.ndarray) -> None:
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in triangles.reshape(-1, 3)]
    lines += [f"f {3 * k + 1} {3 * k + 2} {3 * k + 3}" for k in range(len(triangles))]
    path.write_text("\n".join(lines) + "\n")


#: a visual skin on each thigh, turned 30 deg about x (its vertices stretch, not its axes), an
#: aligned collision shell on each shin (an STL), and a collision guard on the left thigh
#: turned `{guard}` deg off the link (0: aligned, so it stretches)
MESHES = """<asset>
    <mesh name="skin" file="skin.obj"/>
    <mesh name="shell" file="shell.stl"/>
    <mesh name="guard" file="guard.stl"/>
  </asset>
  <worldbody>"""
THIGH = """<geom name="{s}_thigh" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.04"/>
        <geom name="{s}_skin" type="mesh" mesh="skin" pos="0 0 -0.15" euler="30 0 0"
              contype="0" conaffinity="0" group="2"/>"""
GUARD = (
    """<geom name="left_guard" type="mesh" mesh="guard" pos="0.05 0 -0.15" euler="0 {guard} 0"/>"""
)
SHIN = """<geom name="{s}_shin" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.035"/>
          <geom name="{s}_shell" type="mesh" mesh="shell" pos="0 0 -0.17"/>"""


def meshy_folder(folder: Path, guard: float | None = None, collision: str | None = None) -> Path:
    text = stacked_model().replace("<worldbody>", MESHES, 1)
    for side in ("left", "right"):
        thigh = THIGH.format(s=side)
        if side == "left" and guard is not None:
            thigh += "\n        " + GUARD.format(guard=guard)
        text = text.replace(
            f'<geom name="{side}_thigh" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.04"/>', thigh
        ).replace(
            f'<geom name="{side}_shin" type="capsule" fromto="0 0 0 0 0 -0.3" size="0.035"/>',
            SHIN.format(s=side),
        )
    spec = {**SPEC, "name": folder.name}
    if collision:
        spec["collision"] = collision
    write_robot_folder(folder, text, spec)
    write_obj(folder / "skin.obj", box_triangles((0.05, 0.03, 0.12)))
    write_stl(folder / "shell.stl", box_triangles((0.03, 0.03, 0.12)))
    write_stl(folder / "guard.stl", box_triangles((0.01, 0.02, 0.1)))
    return folder


def body_vertices(model, geom: str) -> np.ndarray:
    """[V, 3] a mesh geom's vertices in its body's frame, as MuJoCo compiled them."""
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    g = mj.geom(geom).id
    mesh = mj.geom_dataid[g]
    v0, nv = mj.mesh_vertadr[mesh], mj.mesh_vertnum[mesh]
    return mj.geom_pos[g] + mj.mesh_vert[v0 : v0 + nv] @ _mat(mj.geom_quat[g]).T


def _mat(quat) -> np.ndarray:
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=float))
    return out.reshape(3, 3)


def _sorted(points: np.ndarray) -> np.ndarray:
    return points[np.lexsort(np.round(points, 9).T[::-1])]


@pytest.mark.parametrize("geom", ["left_skin", "right_shell", "left_guard"])
def test_meshes_stretch_with_their_link(tmp_path, geom):
    """A design stretches each mesh's vertices along its link (x -> x + (s - 1)(x.u)u in
    the body frame): the visual skin turned 30 deg off the link, the aligned collision shell
    and guard; the nominal design keeps the file's shape exactly."""
    folder = meshy_folder(tmp_path / "meshy", guard=0.0)
    robot = spec_robot_class(folder)()
    nominal = body_vertices(robot.build(np.array([1.0, 1.0])), geom)
    scale = {"left_skin": 1.3, "right_shell": 0.7, "left_guard": 1.3}[geom]
    stretched = body_vertices(robot.build(np.array([1.3, 0.7])), geom)
    u = np.array([0.0, 0.0, -1.0])  # the thigh's and the shin's link vectors point down
    expected = nominal + (scale - 1.0) * np.outer(nominal @ u, u)
    # MuJoCo keeps mesh vertices in float32
    np.testing.assert_allclose(_sorted(stretched), _sorted(expected), atol=1e-7)
    # the file's own box, placed by the geom: 2 x half-size long along the link
    length = {"left_skin": None, "right_shell": 0.24, "left_guard": 0.2}[geom]
    if length is not None:
        assert np.ptp(nominal[:, 2]) == pytest.approx(length, abs=1e-7)


def test_a_collision_mesh_off_its_link_is_refused_naming_collision_fit(tmp_path):
    folder = meshy_folder(tmp_path / "robots" / "meshy", guard=40.0)
    with pytest.raises(UserError) as info:
        spec_robot_class(folder)().build(np.array([1.0, 1.0]))  # any design: it cannot scale
    assert info.value.field == "design[0].links[0]"
    done = _cli(["robot", "validate", "meshy"], tmp_path / "robots", tmp_path)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = (done.stdout + done.stderr).strip().splitlines()
    assert len(lines) == 1 and "'left_guard'" in lines[0] and "40 deg" in lines[0], lines
    assert "`collision: fit`" in lines[0]


def test_a_bad_collision_rule_is_refused(tmp_path):
    folder = meshy_folder(tmp_path / "meshy", collision="shrink")
    with pytest.raises(UserError) as info:
        spec_robot_class(folder)()
    assert info.value.field == "collision" and "stretch, fit" in str(info.value)


def test_collision_fit_replaces_collision_meshes_by_primitives_and_says_how_well(tmp_path):
    folder = meshy_folder(tmp_path / "meshy", guard=40.0, collision="fit")
    robot = spec_robot_class(folder)()
    model = robot.build(np.array([1.3, 0.7]))
    fits = model.info["collision_fit"].split("; ")
    assert len(fits) == 3  # the left guard and both shells; the visual skins stay meshes
    assert (
        fits[0]
        == "collision mesh 'left_guard' of body 'left_thigh': a box, its volume +0.0% of the mesh's"
    )
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    guard = mj.geom("left_guard").id
    assert mj.geom_type[guard] == mujoco.mjtGeom.mjGEOM_BOX
    # the fitted box is the file's box (half-sizes 0.01, 0.02, 0.1), moved with the link
    np.testing.assert_allclose(np.sort(mj.geom_size[guard]), [0.01, 0.02, 0.1], atol=1e-6)
    assert mj.geom_type[mj.geom("left_skin").id] == mujoco.mjtGeom.mjGEOM_MESH
    # no collision mesh left: the URDF's one mesh file is the skins' (both alike), a visual
    files = [k.split(":", 1)[1] for k in model.formats if k.startswith("urdf:")]
    urdf = model.text("urdf")
    assert len(files) == 1 and urdf.count(f'<mesh filename="{files[0]}"/>') == 2
    assert not re.search(r"<collision>[^/]*<geometry><mesh", urdf)


def prism_triangles(radius: float, half: float, sides: int = 24) -> np.ndarray:
    """[4 sides, 3, 3] a closed prism of `sides` sides about z (a vendor's cylinder mesh)."""
    a = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    ring = radius * np.stack([np.cos(a), np.sin(a)], axis=1)
    out = []
    for i in range(sides):
        j = (i + 1) % sides
        b0, b1 = [*ring[i], -half], [*ring[j], -half]
        t0, t1 = [*ring[i], half], [*ring[j], half]
        out += [[b0, b1, t1], [b0, t1, t0], [[0, 0, half], t0, t1], [[0, 0, -half], b1, b0]]
    return np.array(out)


def test_collision_fit_picks_the_primitive_closest_in_volume(tmp_path):
    """A 24-sided prism shell becomes a cylinder (fitted to its bounding box: radius 3 cm,
    1.2 % more volume than the prism, pi / (12 sin 15 deg)), not the inertia box MuJoCo fits
    by default."""
    folder = meshy_folder(tmp_path / "meshy", collision="fit")
    write_stl(folder / "shell.stl", prism_triangles(0.03, 0.12))
    model = spec_robot_class(folder)().build(np.array([1.0, 1.0]))
    fits = model.info["collision_fit"].split("; ")
    assert fits[0] == (
        "collision mesh 'left_shell' of body 'left_shin': a cylinder, its volume +1.2% of the "
        "mesh's"
    )
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    np.testing.assert_allclose(mj.geom_size[mj.geom("left_shell").id, :2], [0.03, 0.12], atol=1e-6)


def test_robot_new_writes_collision_fit_for_a_collision_mesh_off_its_link(tmp_path):
    from coadapt_plugins.robots.specs.new import write_robot

    source = meshy_folder(tmp_path / "source", guard=40.0)
    folder, notes, _ = write_robot("meshy", source / "model.xml", tmp_path / "robots")
    assert yaml.safe_load((folder / "robot.yaml").read_text())["collision"] == "fit"
    assert any("'left_guard' (40 deg off its link)" in line for line in notes), notes
    assert any(line.startswith("fitted: collision mesh 'left_guard'") for line in notes), notes


@pytest.mark.slow
@pytest.mark.parametrize("collision", ["stretch", "fit"])
def test_robots_with_meshes_in_scaled_links_pass_every_step(tmp_path, collision):
    """Visual and collision meshes in the links a design scales: `robot validate` at the
    nominal design and two corners, a URDF export (its collision meshes as files beside it),
    and a 1 s PyBullet and MuJoCo stand at a corner where both stand alike."""
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.plugins import get_registry

    guard = 0.0 if collision == "stretch" else 40.0
    folder = meshy_folder(tmp_path / "robots" / "meshy", guard=guard, collision=collision)
    simulator = get_registry().get("simulator", "mujoco")
    off = RandomizationConfig.off()
    two = np.array([[1.0, 1.0], [1.3, 0.7]])
    if collision == "stretch":  # one MuJoCo batch shares mesh shapes: refused in one line
        with pytest.raises(UserError, match=r"collision mesh 'left_guard'.*collision: fit"):
            simulator(spec_robot_class(folder)(), two, randomization=off, num_threads=1)
    else:  # only visual meshes differ: the batch takes both designs
        simulator(spec_robot_class(folder)(), two, randomization=off, num_threads=1).close()
    robot = spec_robot_class(folder)()
    for design in ([1.0, 1.0], [0.7, 0.7], [1.3, 1.3]):
        report = robot.validate(np.array(design))
        assert report.feasible, (design, report.reasons)
    out = tmp_path / "export" / "meshy.urdf"
    out.parent.mkdir()
    done = _cli(
        ["robot", "export", "meshy", "--design", "1.3,0.7", "--format", "urdf", "-o", str(out)],
        tmp_path / "robots",
        tmp_path,
    )
    assert done.returncode == 0, done.stderr
    meshes = sorted(p.name for p in out.parent.glob("*.obj"))
    # the two thighs' visual skins, alike, in one file; the guard and the two shins' shells,
    # alike, in one more when they stay meshes
    assert len(meshes) == (3 if collision == "stretch" else 1)
    for name in meshes:
        assert f'filename="{name}"' in out.read_text()
    if meshes:  # standard output cannot carry the mesh files: one line, exit 2
        done = _cli(["robot", "export", "meshy", "--format", "urdf"], tmp_path / "robots", tmp_path)
        lines = (done.stdout + done.stderr).strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and "give -o FILE" in lines[0], lines
    pytest.importorskip("pybullet")
    design = np.array([[1.1, 0.9]])  # stretched meshes, and a design that stands
    model = robot.build(design[0])
    heights = {}
    for name in ("mujoco", "pybullet"):
        options = {"processes": 0} if name == "pybullet" else {}
        sim = get_registry().get("simulator", name)(
            robot, design, randomization=off, seed=0, num_threads=1, **options
        )
        sim.reset()
        targets = sim.default_joint_pos.clone()
        heights[name] = np.array([float(sim.step(targets).base_pos[0, 2]) for _ in range(50)])
        sim.close()
        assert np.abs(heights[name] - model.standing_base_height).max() < 0.02, name
    assert np.abs(heights["mujoco"] - heights["pybullet"]).max() < 0.002


def test_robot_new_on_stacked_hinges_writes_a_spec_that_validates(tmp_path):
    """`robot new` on the stacked-hinge biped as the file is: both legs found through their
    stacked hips and ankles, and the spec it writes validates at the nominal design and the
    corners, Pinocchio agreeing hinge by hinge."""
    from coadapt_plugins.robots.specs.new import write_robot

    source = write_robot_folder(tmp_path / "source", stacked_model())
    folder, _, _ = write_robot("stacked", source / "model.xml", tmp_path / "robots")
    robot = spec_robot_class(folder)()
    assert [leg.name for leg in robot.legs()] == ["left", "right"]
    assert len(robot.build(robot.nominal_design()).joint_names) == 12
    for design in ([1.0, 1.0], [0.7, 0.7], [1.3, 1.3]):
        report = robot.validate(np.array(design))
        assert report.feasible, (design, report.reasons)
