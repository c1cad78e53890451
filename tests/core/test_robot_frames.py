"""Models whose frames and inertias are their own (issue 58): a y-up URDF whose bodies have a
mass but zero inertia and whose legs end in a knee (pybullet_data's laikago.urdf) gets
`base_orientation`, `inertia_from_shape` and `tips` written by `robot new`, the file left as
it is (four-bar legs the file leaves open: tests/core/test_four_bar.py); each new spec
field's bad value is one line naming it. tests/core/test_robot_corpus.py takes laikago
on to a co-design run."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from coadapt_plugins.robots.specs.new import starting_spec
from coadapt_plugins.robots.specs.orient import TIP_RADIUS, up_rotation
from coadapt_plugins.robots.specs.spec import parse_spec

from coadapt_core.errors import UserError

pytest.importorskip("pybullet_data")
import pybullet_data

DATA = Path(pybullet_data.getDataPath())
NEZHA = Path(__file__).resolve().parents[2] / "plugins" / "robots" / "specs" / "nezha"


def test_a_y_up_urdf_with_zero_inertias_and_knee_ended_legs_gets_its_fixes_in_the_spec():
    source = DATA / "laikago" / "laikago.urdf"
    before = source.read_bytes()
    data, notes, comments = starting_spec("laikago-yup", source)
    assert source.read_bytes() == before
    # y up, +z forward (the legs named F are at +z): x -> y, y -> z, z -> x
    assert data["base_orientation"] == [0.5, 0.5, 0.5, 0.5]
    assert data["inertia_from_shape"] is True
    assert sorted(data["tips"]) == ["FL_lower_leg", "FR_lower_leg", "RL_lower_leg", "RR_lower_leg"]
    tip = np.array(data["tips"]["FL_lower_leg"])
    assert 0.25 < np.linalg.norm(tip) + TIP_RADIUS < 0.3  # the shank's far end, 0.28 m
    assert [leg["foot"] for leg in data["legs"]] == [
        f"{g}_lower_leg_tip" for g in ("FL", "FR", "RL", "RR")
    ]
    assert data["standing_pose"]["solve"] == 0.75  # every foot placed
    assert [p["links"][0] for p in data["design"]] == [
        ["FL_upper_leg", "FL_lower_leg"],
        ["FL_lower_leg", "FL_lower_leg_tip"],
    ]
    assert "base_orientation" in comments and "tips" in comments
    assert any("the model is not z-up" in n for n in notes)
    assert any(n.startswith("bodies with a mass and zero inertia (chassis") for n in notes)


def test_the_turned_base_stands_its_feet_below_it_and_keeps_the_models_masses(tmp_path):
    from coadapt_plugins.robots.specs.model import load_mjspec
    from coadapt_plugins.robots.specs.orient import reorient

    source = DATA / "laikago" / "laikago.urdf"
    with pytest.raises(UserError, match="mass and inertia of moving bodies"):
        load_mjspec(source)
    spec = load_mjspec(source, shape_inertia=True)
    reorient(spec.body("chassis"), [0.5, 0.5, 0.5, 0.5])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    assert model.body("chassis").mass[0] == pytest.approx(13.715)
    assert np.all(model.body_inertia[1:] > 0)
    # the box bounding the chassis's collision mesh: within 5 % of the moments the authors of
    # laikago_toes_zup.urdf (the same robot, z-up) wrote, 0.22, 0.431, 0.565 kg m^2
    moments = np.sort(model.body_inertia[model.body("chassis").id])
    np.testing.assert_allclose(moments, [0.22, 0.431, 0.565], rtol=0.05)
    front, rear = data.xpos[model.body("FL_hip_motor").id], data.xpos[model.body("RL_hip_motor").id]
    assert front[0] > 0.2 and rear[0] < -0.15 and front[1] > 0  # x forward, y left
    assert np.all(data.xpos[[model.body(f"{g}_lower_leg").id for g in ("FL", "RR")], 2] < -0.1)
    assert up_rotation(model, data, model.body("chassis").id) is None  # upright now


def test_z_up_models_and_an_ant_at_rest_are_left_as_they_are():
    for source in (DATA / "a1" / "a1.urdf", DATA / "mjcf" / "ant.xml", NEZHA / "model.xml"):
        data, _, _ = starting_spec("probe", source)
        assert "base_orientation" not in data and "tips" not in data, source.name


def _spec(**extra) -> dict:
    data = yaml.safe_load((NEZHA / "robot.yaml").read_text())
    data.update(extra)
    return data


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"base_orientation": [1, 0, 0]}, "'base_orientation': needs a quaternion"),
        ({"base_orientation": [2, 0, 0, 0]}, "'base_orientation': needs a unit quaternion"),
        ({"tips": {"left_foot": [0, 0]}}, "'tips.left_foot': needs a point [x, y, z]"),
        ({"inertia_from_shape": "yes"}, "'inertia_from_shape': needs true or false"),
    ],
)
def test_a_bad_frame_or_inertia_field_is_one_line_naming_it(extra, message):
    with pytest.raises(UserError) as found:
        parse_spec(_spec(**extra), NEZHA)
    assert message in str(found.value) and "\n" not in str(found.value)


def test_a_tip_on_a_body_that_does_not_exist_is_one_line(tmp_path):
    import shutil

    from coadapt_plugins.robots.specs.robot import spec_robot_class

    folder = tmp_path / "probe"
    shutil.copytree(NEZHA, folder, ignore=shutil.ignore_patterns("policies"))
    data = _spec(name="probe", tips={"no_such_shin": [0.0, 0.0, -0.2]})
    (folder / "robot.yaml").write_text(yaml.safe_dump(data))
    robot = spec_robot_class(folder)()
    with pytest.raises(UserError, match=r"'tips.no_such_shin': no body 'no_such_shin' in the"):
        robot.build(robot.nominal_design())


def test_a_humanoids_feet_are_placed_under_its_hips_its_second_ankle_hinge_held():
    """The waist's joints are locked (both legs' chains hold them), so each leg is measured
    from its thigh, the first body that turns; the ankle's second hinge (ankle_x) stays at
    its reference and the first (ankle_y) keeps the foot flat: each foot ends under its hip
    at 0.75 of the leg's length (0.403 + 0.39 m), solved again at each design."""
    source = DATA / "mjcf" / "humanoid.xml"
    data, notes, _ = starting_spec("hum", source)
    assert [leg.get("hip") for leg in data["legs"]] == ["left_thigh", "right_thigh"]
    pose = data["standing_pose"]
    assert pose["solve"] == 0.75
    assert any("standing pose solved with 2 of 2 feet" in n for n in notes)
    assert not {"left_ankle_x", "right_ankle_x"} & set(pose["joints"])  # held at 0
    model = mujoco.MjModel.from_xml_path(str(source))
    d = mujoco.MjData(model)
    for joint, angle in pose["joints"].items():
        d.qpos[model.jnt_qposadr[model.joint(joint).id]] = angle
    mujoco.mj_kinematics(model, d)
    for side in ("left", "right"):
        foot, hip = d.xpos[model.body(f"{side}_foot").id], d.xpos[model.body(f"{side}_thigh").id]
        torso = d.xmat[model.body("torso").id].reshape(3, 3)
        rel = torso.T @ (foot - hip)
        assert abs(rel[0]) < 1e-3 and rel[2] == pytest.approx(-0.75 * (0.403 + 0.39), abs=1e-3)
        sole = d.xmat[model.body(f"{side}_foot").id].reshape(3, 3)[:, 2] @ torso[:, 2]
        assert sole > np.cos(np.radians(2.0))  # the foot flat within 2 deg, as in the file


def _obj_vertices(text: str) -> np.ndarray:
    return np.array(
        [[float(x) for x in line.split()[1:]] for line in text.splitlines() if line[:2] == "v "]
    )


def test_the_urdf_carries_visual_meshes_stretched_as_the_mjcfs_and_pybullet_shows_them(tmp_path):
    """A visual mesh (the thighs' skins, 30 deg off their link) is a `<visual>` of the URDF
    only, in MuJoCo's colour: at a stretched design its vertices, placed by the visual's
    origin, are the MJCF's within 1e-6 m, and PyBullet loads it as the thigh's visual."""
    import re

    from coadapt_plugins.robots.specs.robot import spec_robot_class
    from coadapt_plugins.robots.specs.urdf import mesh_files

    from tests.core.test_spec_shapes import _mat, body_vertices, meshy_folder

    folder = meshy_folder(tmp_path / "meshy", guard=40.0, collision="fit")
    model = spec_robot_class(folder)().build(np.array([1.3, 0.7]))
    urdf = model.text("urdf")
    link = re.search(r'<link name="left_thigh">.*?</link>', urdf, flags=re.S).group(0)
    visual = re.search(
        r'<visual><origin xyz="([^"]*)" rpy="([^"]*)"/><geometry><mesh filename="([^"]*)"/>'
        r'</geometry><material name="[^"]*"><color rgba="([^"]*)"/></material></visual>',
        link,
    )
    assert visual and "<collision><origin" in link  # the capsule still collides
    xyz, rpy = (np.array([float(x) for x in g.split()]) for g in visual.group(1, 2))
    roll, pitch, yaw = rpy
    rot = (
        _mat([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)])
        @ _mat([np.cos(pitch / 2), 0, np.sin(pitch / 2), 0])
        @ _mat([np.cos(roll / 2), np.sin(roll / 2), 0, 0])
    )
    placed = xyz + _obj_vertices(mesh_files(model.formats)[visual.group(3)]) @ rot.T
    mjcf = body_vertices(model, "left_skin")
    np.testing.assert_allclose(np.sort(placed, axis=0), np.sort(mjcf, axis=0), atol=1e-6)
    pybullet = pytest.importorskip("pybullet")
    out = tmp_path / "urdf"
    out.mkdir()
    (out / "m.urdf").write_text(urdf)
    for name, text in mesh_files(model.formats).items():
        (out / name).write_text(text)
    client = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(out / "m.urdf"), physicsClientId=client)
        shapes = pybullet.getVisualShapeData(body, physicsClientId=client)
        files = {s[4].decode() for s in shapes if s[2] == pybullet.GEOM_MESH}
    finally:
        pybullet.disconnect(client)
    assert any(f.endswith(visual.group(3)) for f in files), files
