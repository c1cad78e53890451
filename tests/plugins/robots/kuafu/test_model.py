"""The generated Kuafu model: the paper's nominal figures, Table 8 motors, the conventions
the simulators rely on, and build speed."""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from coadapt_plugins.robots.kuafu import constants as C
from coadapt_plugins.robots.kuafu.generator import KuafuDesign, leg_joint_inertias
from coadapt_plugins.robots.kuafu.validation import pinocchio_model

from .helpers import standing_data

TABLE_8 = {1: (119.7, 99.0, 0.62), 2: (120.3, 340.0, 0.62), 3: (135.1, 310.0, 0.67)}
RPM = 2.0 * np.pi / 60.0


def measured_height(model) -> tuple[float, float]:
    """(top of the head, bottom of the soles) in MuJoCo at the default pose, base at
    `standing_base_height`."""
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = standing_data(model, mj)
    head = mj.geom("head").id
    top = data.geom_xpos[head, 2] + mj.geom_size[head, 0]
    bottoms = []
    for side in C.SIDES:
        sole = mj.geom(f"{side}_sole").id
        corners = (
            data.geom_xpos[sole]
            + (
                data.geom_xmat[sole].reshape(3, 3)
                @ (
                    np.array([[sx, sy, -1.0] for sx in (-1, 1) for sy in (-1, 1)])
                    * mj.geom_size[sole]
                ).T
            ).T
        )
        bottoms.append(corners[:, 2].min())
    return float(top), float(min(bottoms))


def test_nominal_mass_height_and_lengths(kuafu):
    model = kuafu.build(kuafu.nominal_design())
    assert model.total_mass == pytest.approx(42.0, abs=0.5)
    top, bottom = measured_height(model)
    assert bottom == pytest.approx(0.0, abs=1e-9)  # standing_base_height puts the soles on z = 0
    assert top - bottom == pytest.approx(1.6, abs=0.03)
    assert model.info["standing_height"] == pytest.approx(top - bottom, abs=1e-9)
    assert model.info["thigh_length"] == pytest.approx(0.35)
    assert model.info["shank_length"] == pytest.approx(0.35)


def test_standing_height_follows_the_legs(kuafu):
    short = kuafu.build(np.array([0.5, 0.5]))
    tall = kuafu.build(np.array([1.5, 1.5]))
    # 0.94 of the leg-length change shows up in the height (bent knees at the default pose)
    assert measured_height(tall)[0] - measured_height(short)[0] == pytest.approx(
        0.94 * 0.35 * 2.0, abs=1e-9
    )


def test_urdf_in_pinocchio_has_8_revolute_joints_with_table_8_limits(kuafu):
    model = kuafu.build(np.array([1.0, 1.0]))
    pmodel = pinocchio_model(model)
    assert (pmodel.nq, pmodel.nv) == (15, 14)  # free flyer (7 / 6) + 8 actuated joints
    kinds = {pmodel.names[i]: pmodel.joints[i].shortname() for i in range(2, pmodel.njoints)}
    assert sorted(kinds) == sorted(C.JOINT_NAMES)
    for name, kind in kinds.items():
        assert kind == ("JointModelRX" if "roll" in name else "JointModelRY"), name
        j = pmodel.joints[pmodel.getJointId(name)]
        assert pmodel.effortLimit[j.idx_v] == pytest.approx(119.7)
        assert pmodel.velocityLimit[j.idx_v] == pytest.approx(99.0 * RPM)
    fixed = [
        f.name
        for f in pmodel.frames
        if f.type == pin.FrameType.FIXED_JOINT and f.name != "universe"
    ]
    assert sorted(fixed) == ["left_shoulder", "right_shoulder"]


@pytest.mark.parametrize("hip, knee", [(1, 1), (2, 3), (3, 2)])
def test_motor_types_set_limits_in_every_description(kuafu, hip, knee):
    model = kuafu.build(np.array([1.1, 0.9, hip, knee]))
    expected_type = [hip, hip, knee, 1] * 2  # the ankle always uses a type-1 motor
    assert model.info["motor_types"] == expected_type
    np.testing.assert_allclose(model.torque_limit, [TABLE_8[t][0] for t in expected_type])
    np.testing.assert_allclose(model.speed_limit, [TABLE_8[t][1] * RPM for t in expected_type])
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    pmodel = pinocchio_model(model)
    for k, name in enumerate(model.joint_names):
        act = mj.actuator(name)
        assert mj.actuator_trnid[act.id, 0] == mj.joint(name).id
        assert mj.actuator_gear[act.id, 0] == 1.0
        np.testing.assert_allclose(
            mj.actuator_ctrlrange[act.id], [-model.torque_limit[k], model.torque_limit[k]]
        )
        idx = pmodel.joints[pmodel.getJointId(name)].idx_v
        assert pmodel.effortLimit[idx] == pytest.approx(model.torque_limit[k])
        assert pmodel.velocityLimit[idx] == pytest.approx(model.speed_limit[k])


def test_motor_mass_enters_the_model(kuafu):
    base = kuafu.build(np.array([1.0, 1.0, 1, 1])).total_mass
    # type 3 is 0.05 kg heavier: 2 knee actuators; 4 hip actuators (roll and pitch)
    assert kuafu.build(np.array([1.0, 1.0, 1, 3])).total_mass - base == pytest.approx(
        0.10, abs=1e-9
    )
    assert kuafu.build(np.array([1.0, 1.0, 3, 1])).total_mass - base == pytest.approx(
        0.20, abs=1e-9
    )
    # a 2-vector design is motor types (1, 1)
    assert kuafu.build(np.array([1.0, 1.0])).text("mjcf") == kuafu.build(
        np.array([1.0, 1.0, 1, 1])
    ).text("mjcf")


def test_mjcf_conventions(kuafu):
    model = kuafu.build(np.array([0.8, 1.3]))
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    assert mj.opt.timestep == pytest.approx(0.005)
    assert mj.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE and mj.joint(0).name == "root"
    assert mj.body(mj.jnt_bodyid[0]).name == "base"
    assert [mj.joint(i).name for i in range(1, mj.njnt)] == C.JOINT_NAMES
    assert all(mj.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE for i in range(1, mj.njnt))
    np.testing.assert_allclose(mj.jnt_axis[1:5], [[1, 0, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0]])
    assert [mj.actuator(i).name for i in range(mj.nu)] == C.JOINT_NAMES
    # arms hang on fixed shoulders: bodies without joints
    for side in C.SIDES:
        assert mj.body_jntnum[mj.body(f"{side}_arm").id] == 0
    # robot only: no geom on the world body; collision geoms collide with terrain, not each other
    assert not np.any(mj.geom_bodyid == 0)
    collision = mj.geom_contype == 1
    assert np.all(mj.geom_conaffinity == 0)
    assert np.all((mj.geom_contype == 0) | (mj.geom_contype == 1))
    for side in C.SIDES:
        sole = mj.geom(f"{side}_sole").id
        assert collision[sole] and mj.geom_type[sole] == mujoco.mjtGeom.mjGEOM_BOX
        assert mj.body(mj.geom_bodyid[sole]).name == f"{side}_foot"
    np.testing.assert_allclose(mj.dof_armature[6:], C.ARMATURE)
    np.testing.assert_allclose(mj.dof_damping[6:], C.JOINT_DAMPING)


def test_foot_contact_points_are_the_sole_corners(kuafu):
    model = kuafu.build(np.array([1.2, 0.7]))
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    sole = mj.geom("left_sole").id
    centre, half = mj.geom_pos[sole], mj.geom_size[sole]
    corners = {
        tuple(np.round(centre + half * [sx, sy, -1.0], 9)) for sx in (-1, 1) for sy in (-1, 1)
    }
    assert {tuple(np.round(p, 9)) for p in model.foot_contact_points} == corners
    # the URDF collision box of each foot is the same box
    root = ET.fromstring(model.text("urdf"))
    for side in C.SIDES:
        link = root.find(f"link[@name='{side}_foot']")
        box = link.find("collision/geometry/box")
        origin = link.find("collision/origin")
        np.testing.assert_allclose([float(x) for x in box.get("size").split()], 2 * half)
        np.testing.assert_allclose([float(x) for x in origin.get("xyz").split()], centre)


def test_default_pose_knees_bent_soles_flat_feet_under_hips(kuafu):
    for design in ([1.0, 1.0], [0.5, 1.5], [1.5, 0.5]):
        model = kuafu.build(np.array(design))
        mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
        data = standing_data(model, mj)
        q = model.default_joint_pos
        assert q[0] == 0.0 and q[4] == 0.0
        assert 0.4 < q[2] < 1.0  # knee bent 23-57 degrees
        for side in C.SIDES:
            foot = mj.body(f"{side}_foot").id
            hip = mj.body(f"{side}_hip_roll_link").id
            np.testing.assert_allclose(
                data.xmat[foot].reshape(3, 3), np.eye(3), atol=1e-12
            )  # sole flat
            np.testing.assert_allclose(data.xpos[foot][:2], data.xpos[hip][:2], atol=1e-12)


def test_pd_gains_follow_the_scaling_rule(kuafu):
    joints = ("hip_roll", "hip_pitch", "knee", "ankle")
    nominal = kuafu.build(np.array([1.0, 1.0]))
    assert list(nominal.kp[:4]) == [C.NOMINAL_KP[j] for j in joints]
    assert list(nominal.kd[:4]) == [C.NOMINAL_KD[j] for j in joints]
    i_nom = leg_joint_inertias(KuafuDesign(1.0, 1.0))
    for design in ([0.5, 0.5], [1.5, 1.5], [1.5, 0.5]):
        model = kuafu.build(np.array(design))
        inertia = leg_joint_inertias(KuafuDesign(*design))
        load = np.array([inertia["load"][j] / i_nom["load"][j] for j in joints] * 2)
        swing = np.array(
            [(inertia["swing"][j] + C.ARMATURE) / (i_nom["swing"][j] + C.ARMATURE) for j in joints]
            * 2
        )
        np.testing.assert_allclose(model.kp / nominal.kp, load, rtol=1e-12)
        np.testing.assert_allclose(model.kd / nominal.kd, np.sqrt(load * swing), rtol=1e-12)
    short, tall = kuafu.build(np.array([0.5, 0.5])), kuafu.build(np.array([1.5, 1.5]))
    assert np.all(tall.kp > nominal.kp) and np.all(nominal.kp > short.kp)
    # the load inertia counts the upper body; the swing inertia at the ankle is the foot alone
    assert i_nom["load"]["ankle"] > 20.0 and i_nom["swing"]["ankle"] < 0.01


def test_build_is_cached_fast_and_read_only(kuafu):
    designs = np.random.default_rng(123).uniform(0.5, 1.5, size=(50, 2))
    start = time.perf_counter()
    for d in designs:
        kuafu.build(d)
    per_design = (time.perf_counter() - start) / len(designs)
    assert per_design < 0.010, f"{per_design * 1e3:.2f} ms per new design"
    assert kuafu.build(designs[0]) is kuafu.build(designs[0] + 1e-9)
    with pytest.raises(ValueError):
        kuafu.build(designs[0]).kp[0] = 1.0
