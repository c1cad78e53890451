"""PyBullet's armature correction on a floating base (issue 49). MuJoCo adds each joint's
armature to the mass matrix; the PyBullet engine takes the torque it would absorb off the
motor torque, predicting the accelerations from Bullet's mass matrix over all of the body's
generalized velocities (the floating base's six first) and the last step's other forces.
Predicted from the joints' block alone, the base's reaction to a joint's acceleration lagged
one step, and Qilin (a 0.01 kg m^2 armature on light legs) fell over at its first step:
survival 0.00 with its shipped policy. Every robot is checked, enumerated from the registry."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pybullet")

import pybullet as p
from coadapt_plugins.simulators.pybullet.armature import (
    FOLD_RATIO,
    base_velocity,
    folded_joints,
    foot_joints,
)
from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator
from coadapt_plugins.simulators.pybullet.spec import EnvSpec, mjcf_joint_dynamics

from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.plugins import get_registry

ROBOTS = get_registry().names("robot")  # a robot added later (a spec robot) is checked too


def _robot(name: str):
    return get_registry().create("robot", name)


def _kinetic_energy(client: int, body: int) -> float:
    """Sum over the base and every link of 1/2 m v^2 + 1/2 w' I w, from Bullet's link states."""
    energy = 0.0
    _, orn = p.getBasePositionAndOrientation(body, physicsClientId=client)
    linear, angular = p.getBaseVelocity(body, physicsClientId=client)
    frames = [(-1, orn, linear, angular)]
    for link in range(p.getNumJoints(body, physicsClientId=client)):
        state = p.getLinkState(body, link, computeLinkVelocity=1, physicsClientId=client)
        frames.append((link, state[1], state[6], state[7]))
    for link, quat, v, w in frames:
        mass, _, moments = p.getDynamicsInfo(body, link, physicsClientId=client)[:3]
        rotation = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        inertia = rotation @ np.diag(moments) @ rotation.T
        energy += 0.5 * mass * np.dot(v, v) + 0.5 * np.asarray(w) @ inertia @ np.asarray(w)
    return float(energy)


@pytest.mark.parametrize("name", ROBOTS)
def test_generalized_velocities_are_the_ones_of_bullets_mass_matrix(name, tmp_path):
    """1/2 u'Mu with u = (base angular, base linear in the base's inertial frame, joints)
    is the body's kinetic energy at a tilted, moving pose: the order the correction
    assumes (`armature.base_velocity`)."""
    robot = _robot(name)
    model = robot.build(robot.nominal_design())
    if "urdf" not in model.formats:
        pytest.skip(f"{name} writes no URDF, which PyBullet reads")
    path = tmp_path / "robot.urdf"
    path.write_text(model.text("urdf"))
    client = p.connect(p.DIRECT)
    try:
        tilt = p.getQuaternionFromEuler([0.3, -0.5, 1.1])
        body = p.loadURDF(
            str(path), [0.1, 0.2, 1.0], tilt, flags=p.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=client,
        )  # fmt: skip
        movable = [
            i
            for i in range(p.getNumJoints(body, physicsClientId=client))
            if p.getJointInfo(body, i, physicsClientId=client)[2] != p.JOINT_FIXED
        ]
        rng = np.random.default_rng(0)
        q, dq = rng.normal(0.0, 0.5, len(movable)), rng.normal(0.0, 1.0, len(movable))
        for joint, position, speed in zip(movable, q, dq, strict=True):
            p.resetJointState(body, joint, position, speed, physicsClientId=client)
        p.resetBaseVelocity(body, [0.4, -0.3, 0.2], [1.0, -2.0, 0.5], physicsClientId=client)
        u = np.concatenate([base_velocity(client, body), dq])
        mass = np.array(p.calculateMassMatrix(body, q.tolist(), physicsClientId=client))
        energy = _kinetic_energy(client, body)
    finally:
        p.disconnect(physicsClientId=client)
    assert energy > 1.0
    assert 0.5 * u @ mass @ u == pytest.approx(energy, rel=1e-9)


def test_the_last_actuated_joint_above_each_foot_is_folded():
    """The "foot_link" mode folds the armature of the joint that turns each foot: Kuafu's ankles
    (the foot is their child link), Qilin's knees (the foot sphere is fixed to the calf)."""
    folded = {
        name: foot_joints(EnvSpec.from_model(_robot(name).build(_robot(name).nominal_design())))
        for name in ("kuafu", "qilin")
    }
    assert folded == {
        "kuafu": ["left_ankle", "right_ankle"],
        "qilin": ["FL_knee", "FR_knee", "RL_knee", "RR_knee"],
    }


def _corners(robot) -> list[np.ndarray]:
    space = robot.design_space()
    lo, hi = space.lower, space.upper
    return [robot.nominal_design()] + [
        np.where([(k >> i) & 1 for i in range(space.dim)], hi, lo) for k in range(2**space.dim)
    ]


def test_a_joint_whose_armature_outweighs_what_it_turns_is_folded_too():
    """nezha's ankle pitch turns a 0.074 kg link and the foot (0.003 kg m^2 about its axis)
    under a 0.01 kg m^2 armature: folded beside the ankle roll. Left in joint space, the
    shipped policy's PyBullet survival was 0.78 against 0.98 folded (docs/sim-to-sim.md).
    Kuafu's and Qilin's sets stay their foot joints at the nominal design and every corner,
    so their physics is unchanged."""
    for name in ("kuafu", "qilin"):
        robot = _robot(name)
        for design in _corners(robot):
            spec = EnvSpec.from_model(robot.build(design))
            assert folded_joints(spec) == foot_joints(spec), (name, design)
    nezha = _robot("nezha")
    for design in _corners(nezha):
        spec = EnvSpec.from_model(nezha.build(design))
        assert folded_joints(spec) == [
            "left_ankle_pitch",
            "left_ankle_roll",
            "right_ankle_pitch",
            "right_ankle_roll",
        ], design
        ratio = spec.joint_armature / spec.joint_inertia
        pitch = spec.joint_names.index("left_ankle_pitch")
        assert ratio[pitch] == pytest.approx(3.3, abs=0.1)
        assert (
            np.delete(ratio, np.flatnonzero(np.isin(spec.joint_names, folded_joints(spec)))).max()
            < FOLD_RATIO
        )


def test_the_turned_inertia_is_the_subtree_about_the_joint_axis():
    """A 1 kg sphere (radius 0.1 m) on a hinge with a 0.3 kg m^2 armature, a 2 kg one 0.5 m
    out, a second hinge between them at 0.25 m: the first turns 0.004 + 2 (0.004 + 0.25) =
    0.512 kg m^2 with the second straight, the second 2 (0.004 + 0.0625) = 0.133; bent 90
    degrees, the first turns 0.004 + 2 (0.004 + 0.25^2 + 0.25^2) = 0.262. Armature is not
    counted."""
    mjcf = """<mujoco><worldbody><body><joint name="a" type="hinge" axis="0 0 1" armature="0.3"/>
      <geom type="sphere" size="0.1" mass="1"/>
      <body pos="0.25 0 0"><joint name="b" type="hinge" axis="0 0 1" armature="0.3"/>
        <geom type="sphere" size="0.1" mass="2" pos="0.25 0 0"/></body>
    </body></worldbody></mujoco>"""
    _, armature, _, inertia = mjcf_joint_dynamics(mjcf, ["a", "b"])
    assert armature.tolist() == [0.3, 0.3]
    assert inertia == pytest.approx([0.512, 0.133], rel=1e-9)
    bent = mjcf_joint_dynamics(mjcf, ["a", "b"], np.array([0.0, np.pi / 2]))[3]
    assert bent == pytest.approx([0.262, 0.133], rel=1e-9)


def _step_response(sim_cls, robot, joint: int, **kwargs) -> np.ndarray:
    """[25, J] joint angles over 0.5 s after a 0.2 rad step of one joint's target, the robot
    standing on flat ground (no randomization)."""
    with sim_cls(
        robot, robot.nominal_design()[None], randomization=RandomizationConfig.off(), **kwargs
    ) as sim:
        sim.reset()
        targets = sim.default_joint_pos.clone()
        targets[:, joint] += 0.2
        return np.array([sim.step(targets).joint_pos[0].numpy() for _ in range(25)])


@pytest.mark.parametrize("joint", [0, 2])
def test_a_standing_quadrupeds_step_response_follows_mujoco(joint):
    """Qilin standing, one leg's abduction (0) or knee (2) target stepped by 0.2 rad: the
    joints follow MuJoCo's to 0.05 rad RMS (measured 0.020 and 0.023; before the base's
    rows counted, the correction diverged: 0.92 and 0.83 rad)."""
    robot = _robot("qilin")
    mujoco = get_registry().get("simulator", "mujoco")
    reference = _step_response(mujoco, robot, joint)
    for mode in ("foot_link", "joint_space"):
        moved = _step_response(PyBulletSimulator, robot, joint, armature=mode)
        rms = float(np.sqrt(np.mean((moved - reference) ** 2)))
        assert rms < 0.05, (mode, rms)


@pytest.mark.parametrize("name", ["kuafu", "qilin", "nezha"])
def test_the_correction_predicts_the_step_bullet_takes(name):
    """In the air, without gravity and at rest, a first step's other forces h are nil, so the
    accelerations the "foot_link" correction predicts are exact: they are Bullet's step,
    the base's six included, to 1e-4 of the largest (measured 6e-7 for Kuafu, 4e-5 Qilin,
    2e-5 nezha). Predicted with MuJoCo's base rows where Bullet's carry the folded inertia
    (before issue 58's fix) they were 4e-3, 0.15 and 0.08 off, and 0.92 for pybullet_data's
    ant (its 1 kg m^2 folded into every leg link), whose correction then diverged."""
    from coadapt_plugins.simulators.pybullet.engine import Engine

    robot = _robot(name)
    spec = EnvSpec.from_model(robot.build(robot.nominal_design()))
    engine = Engine(
        [spec], terrain="flat", terrain_seed=0, physics_dt=0.005, decimation=1,
        fixed_base=False, max_delay_steps=0,
    )  # fmt: skip
    try:
        assert engine.folded[0].size  # the case the base's rows matter for
        p.setGravity(0.0, 0.0, 0.0, physicsClientId=engine.clients[0])
        engine._place_base(0, np.array([0.0, 0.0, 3.0]))
        targets = spec.default_joint_pos + 0.2 * np.cos(np.arange(len(spec.joint_names)))
        engine.step(targets[None])
        taken = (engine._velocities(0, None) - engine.prev_u[0]) / engine.physics_dt
        predicted = engine.predicted[0]
    finally:
        engine.close()
    assert np.abs(taken).max() > 1.0
    assert np.abs(predicted - taken).max() < 1e-4 * np.abs(taken).max()


#: a 1 kg sphere of radius 0.1 m (0.004 kg m^2 about any axis) on a vertical hinge with
#: armature 0.0006 and damping 1 N m s/rad, in MJCF and URDF; gravity does not turn it
WHEEL_MJCF = """<mujoco><option timestep="0.005"/><worldbody><body name="base">
  <geom type="box" size="0.05 0.05 0.05" mass="1" contype="0" conaffinity="0"/>
  <body name="wheel"><joint name="spin" type="hinge" axis="0 0 1" armature="0.0006" damping="1"/>
    <geom type="sphere" size="0.1" mass="1" contype="0" conaffinity="0"/></body>
</body></worldbody><actuator><motor name="spin" joint="spin"/></actuator></mujoco>"""
WHEEL_URDF = """<robot name="wheel"><link name="base"><inertial><mass value="1"/>
  <inertia ixx="0.00167" ixy="0" ixz="0" iyy="0.00167" iyz="0" izz="0.00167"/></inertial></link>
<link name="wheel"><inertial><mass value="1"/>
  <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.004"/></inertial></link>
<joint name="spin" type="revolute"><parent link="base"/><child link="wheel"/>
  <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1000" velocity="100"/></joint></robot>"""


def _wheel_spec(implicit: bool) -> EnvSpec:
    from coadapt_plugins.simulators.pybullet.spec import compiled_dynamics

    damping, armature, frictionloss, inertia, implicit_damping = compiled_dynamics(
        WHEEL_MJCF, ["spin"]
    )
    assert implicit_damping and inertia == pytest.approx([0.004])
    one = np.ones(1)
    return EnvSpec(
        design=np.zeros(1), urdf=WHEEL_URDF, base_body="base", joint_names=["spin"],
        foot_bodies=["wheel"], default_joint_pos=np.zeros(1), kp=100 * one, kd=2 * one,
        torque_limit=1000 * one, speed_limit=100 * one, standing_base_height=0.5,
        foot_radius=0.1, joint_damping=damping, joint_armature=armature,
        joint_frictionloss=frictionloss, joint_inertia=inertia, implicit_damping=implicit,
    )  # fmt: skip


def test_mujocos_implicit_joint_damping_is_carried_like_armature():
    """MuJoCo's Euler step solves (M + A + h D) dv = h f: with h = 5 ms and damping 1 the
    wheel's 0.0046 kg m^2 (inertia and armature) gains 0.005, and explicit PD with kd = 2
    N m s/rad is stable in MuJoCo (kd h / I = 1.04) and not without that term (2.17, above
    the bound 2). PyBullet (damping applied explicitly, as torque) carries h D as armature
    (folded into the wheel's inertia) and follows MuJoCo's step response to 1e-4 rad; without
    it, it swings from limit to limit. Kuafu, Qilin and nezha have damping 0.1: 0.0005 kg m^2
    beside their armature's 0.01-0.03. (The "joint_space" mode diverges here with or without
    the term: its h, Bullet's damping torque in it, lags one step, which is unstable once
    d h / I = 1.25 exceeds 1; the default mode folds such a light joint, `folded_joints`.)"""
    import mujoco as mj
    from coadapt_plugins.simulators.pybullet.engine import Engine

    model = mj.MjModel.from_xml_string(WHEEL_MJCF)
    data = mj.MjData(model)
    reference = []
    for _ in range(100):
        data.ctrl[0] = 100 * (0.2 - data.qpos[0]) - 2 * data.qvel[0]
        mj.mj_step(model, data)
        reference.append(data.qpos[0])
    assert abs(reference[-1] - 0.2) < 1e-3  # MuJoCo settles on the target
    options = dict(
        terrain="flat", terrain_seed=0, physics_dt=0.005, decimation=1, fixed_base=True,
        max_delay_steps=0,
    )  # fmt: skip
    for implicit, mode in ((True, "foot_link"), (True, "link_inertia"), (False, "foot_link")):
        engine = Engine([_wheel_spec(implicit)], armature=mode, **options)
        moved = [engine.step(np.array([[0.2]]))["joint_pos"][0, 0] for _ in range(100)]
        engine.close()
        error = np.abs(np.array(moved) - np.array(reference))
        if implicit:
            assert error.max() < 1e-4, (mode, error.max())
        else:  # the explicit PD on 0.0046 kg m^2 alone grows until the joint's limits
            assert error.max() > 2.0, error.max()


def test_which_mujoco_integrators_damp_implicitly():
    """Euler (unless eulerdamp is disabled), implicit and implicitfast take joint damping
    into the velocity update; RK4 does not; the carried armature follows."""
    import mujoco as mj
    from coadapt_plugins.simulators.pybullet.armature import carried_armature
    from coadapt_plugins.simulators.pybullet.spec import damps_implicitly

    def compiled(option: str):
        return mj.MjModel.from_xml_string(WHEEL_MJCF.replace('<option timestep="0.005"/>', option))

    assert damps_implicitly(compiled("<option/>"))
    assert not damps_implicitly(compiled('<option><flag eulerdamp="disable"/></option>'))
    assert damps_implicitly(compiled('<option integrator="implicitfast"/>'))
    assert damps_implicitly(compiled('<option integrator="implicit"/>'))
    assert not damps_implicitly(compiled('<option integrator="RK4"/>'))
    assert carried_armature(_wheel_spec(True), 0.005) == pytest.approx([0.0056])
    assert carried_armature(_wheel_spec(False), 0.005) == pytest.approx([0.0006])
