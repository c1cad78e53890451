"""A model loaded from where it lives, fixed in the spec, stood up (issue 58 items 1, 3, 5, 6):
`robot new` on the models written for these tests (tests/core/robot_files/: a Menagerie-style
MJCF with meshdir and nested includes; a vendor-style URDF with a `package://` mesh, knees
without limits, inertias MuJoCo refuses and no keyframe), the files it copies, the spec lines
it assumes, the standing pose it solves, the stand test, and each bad input in one line,
exit 2, nothing created. tests/core/test_robot_corpus.py takes the same models on to a
co-design run."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch
import yaml
from coadapt_plugins.robots.specs.new import write_robot
from coadapt_plugins.robots.specs.robot import spec_robot_class

from coadapt_core.errors import UserError

HERE = Path(__file__).resolve().parent / "robot_files"
MENAGERIE = HERE / "menagerie" / "quad.xml"
ROS = HERE / "ros"
URDF = ROS / "quad_description" / "urdf" / "quad.urdf"


def coadapt(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, COADAPT_ROBOT_PATH=str(cwd / "robots"))
    return subprocess.run(
        [sys.executable, "-m", "coadapt_core", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_a_menagerie_layout_is_read_where_it_lives_and_copied_whole(tmp_path):
    """meshdir="assets" and nested includes: the model loads from its folder, and the robot's
    folder gets every file it needs in the same layout (the bug: the copy lacked them, and
    MuJoCo said "Error opening file 'assets/...'"); the robot's version covers them."""
    folder, _, copied = write_robot("mquad", MENAGERIE, tmp_path / "robots")
    assert copied == ["quad.xml", "legs/front.xml", "legs/rear.xml", "assets/trunk.obj"]
    for rel in copied:
        assert (folder / rel).read_bytes() == (MENAGERIE.parent / rel).read_bytes()
    robot = spec_robot_class(folder)()
    model = robot.build(robot.nominal_design())
    assert "<mesh" in model.text("mjcf") and len(model.joint_names) == 12
    assert [leg.name for leg in robot.legs()] == ["FL", "FR", "RL", "RR"]
    assert robot.spec.standing_pose == "home"
    assert "menagerie_quad: 4 legs (FL, FR, RL, RR), 12 hinge joints" in robot.spec.description
    # the version is the files': another mesh in the robot's folder is another robot
    before = spec_robot_class(folder).plugin_version
    (folder / "assets" / "trunk.obj").write_text(
        (folder / "assets" / "trunk.obj").read_text().replace("0.18", "0.19")
    )
    assert spec_robot_class(folder).plugin_version != before


def test_a_vendor_urdf_gets_its_fixes_in_the_spec_and_a_solved_standing_pose(tmp_path):
    """package:// found upward from the file; knees without limits, hip inertias MuJoCo
    refuses and missing armature and damping: each an assumed spec line with a comment, the
    user's file unchanged; no keyframe: each foot under its hip at 0.75 of its leg."""
    before = URDF.read_bytes()
    folder, notes, copied = write_robot("rquad", URDF, tmp_path / "robots")
    assert URDF.read_bytes() == before
    assert copied == ["quad.urdf", "quad_description/meshes/trunk.obj"]
    text = (folder / "robot.yaml").read_text()
    spec = yaml.safe_load(text)
    assert spec["balanceinertia"] is True
    assert "# balanceinertia: assumed: MuJoCo refuses an inertia" in text
    assert spec["joints"]["FL_calf_joint"]["range"] == [-3.141593, 3.141593]
    assert spec["joints"]["FL_hip_joint"] == {"armature": 0.006, "damping": 0.06}  # 30 N m
    line = next(x for x in text.splitlines() if x.startswith('  "FL_calf_joint"'))
    assert line.endswith("# assumed: no range in the model, no armature, no damping")
    assert spec["limits"]["speed"] == {  # each URDF joint's <limit velocity>
        f"{leg}_{j}_joint": 20.0 if j == "calf" else 25.0
        for leg in ("FL", "FR", "RL", "RR")
        for j in ("hip", "thigh", "calf")
    }
    assert ".*" not in spec["limits"]["speed"]
    assert [leg["name"] for leg in spec["legs"]] == ["FL", "FR", "RL", "RR"]
    assert any(line.startswith("balanceinertia: true (MuJoCo refused") for line in notes)
    assert any("joints without a range (FL_calf_joint" in line for line in notes)
    assert any("standing pose solved with 4 of 4 feet" in line for line in notes)
    robot = spec_robot_class(folder)()
    model = robot.build(robot.nominal_design())
    j = model.joint_names.index("FL_calf_joint")
    assert (model.joint_lower[j], model.joint_upper[j]) == (-3.141593, 3.141593)
    assert model.info["armature"][model.joint_names.index("FL_hip_joint")] == 0.006
    feet = robot.default_foot_positions(torch.tensor(robot.nominal_design()[None]))[0].numpy()
    np.testing.assert_allclose(feet[:, 0], 0.0, atol=1e-6)  # under the hips
    np.testing.assert_allclose(feet[:, 2], -0.75 * 0.4, atol=1e-6)  # 0.75 of 0.2 + 0.2 m
    knees = np.array(model.default_joint_pos)[
        [model.joint_names.index(f"{g}_calf_joint") for g in ("FL", "RR")]
    ]
    assert np.all(knees < 0)  # bent backwards, as a quadruped's


def test_validate_runs_the_stand_test_at_the_nominal_design_and_the_corners(tmp_path):
    folder, _, _ = write_robot("rquad", URDF, tmp_path / "robots")
    robot = spec_robot_class(folder)()
    stand = next(
        f for f in robot.validate(robot.nominal_design()).findings if f.check == "stand.hold"
    )
    assert stand.ok and "the nominal design and 4 corners stand" in stand.message
    assert "base above 75% of its standing height, tilt below 20 deg, 3 s" in stand.message
    corner = robot.validate(np.array([0.7, 1.3]))
    found = next(f for f in corner.findings if f.check == "stand.hold")
    assert found.ok and found.message.startswith("the design stands")  # that design alone
    # gains far too weak: the quadruped sags, and validation says so
    data = yaml.safe_load((folder / "robot.yaml").read_text())
    data["gains"] = {"default": {"kp": 2.0, "kd": 0.05}}
    (folder / "robot.yaml").write_text(yaml.safe_dump(data))
    weak = spec_robot_class(folder)()
    report = weak.validate(weak.nominal_design())
    assert not report.feasible
    assert any(r.startswith("stand.hold: falls: design (1,1): lowest") for r in report.reasons)


def test_a_humanoids_arms_are_not_legs_and_its_legs_are_named_left_and_right():
    import pybullet_data
    from coadapt_plugins.robots.specs.new import starting_spec

    data, _, _ = starting_spec("hum", Path(pybullet_data.getDataPath()) / "mjcf" / "humanoid.xml")
    assert [(leg["name"], leg["foot"]) for leg in data["legs"]] == [
        ("left", "left_foot"),
        ("right", "right_foot"),
    ]


def test_package_path_finds_a_package_elsewhere(tmp_path):
    alone = tmp_path / "elsewhere" / "quad.urdf"
    alone.parent.mkdir()
    shutil.copy(URDF, alone)
    done = coadapt(
        ["robot", "new", "rq", "--from", str(alone), "--package-path", str(ROS)], tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert "copied 2 files the model needs into it:" in done.stdout
    assert (tmp_path / "robots" / "rq" / "quad_description" / "meshes" / "trunk.obj").is_file()


def _refused(done: subprocess.CompletedProcess, tmp_path: Path, *parts: str) -> str:
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "Traceback" not in done.stderr
    for part in parts:
        assert part in lines[0], lines[0]
    robots = tmp_path / "robots"
    assert not robots.exists() or not any(robots.iterdir())  # nothing created
    return lines[0]


def test_a_package_found_nowhere_is_one_line(tmp_path):
    alone = tmp_path / "elsewhere" / "quad.urdf"
    alone.parent.mkdir()
    shutil.copy(URDF, alone)
    done = coadapt(["robot", "new", "rq", "--from", str(alone)], tmp_path)
    _refused(
        done,
        tmp_path,
        "package 'quad_description' (package://quad_description/...) is in none of the folders",
        str(alone.parent),
        "--package-path",
    )


def test_a_model_that_does_not_load_with_its_assets_resolved_is_one_line(tmp_path):
    copy = tmp_path / "model"
    shutil.copytree(MENAGERIE.parent, copy, ignore=shutil.ignore_patterns("assets"))
    done = coadapt(["robot", "new", "mq", "--from", str(copy / "quad.xml")], tmp_path)
    _refused(done, tmp_path, "'quad.xml' does not load in MuJoCo", "trunk.obj")


def test_a_quadruped_no_gain_stands_is_one_line_naming_the_joint(tmp_path):
    weak = tmp_path / "model"
    shutil.copytree(MENAGERIE.parent, weak)
    text = (weak / "quad.xml").read_text().replace('ctrlrange="-30 30"', 'ctrlrange="-0.5 0.5"')
    (weak / "quad.xml").write_text(text)
    done = coadapt(["robot", "new", "mq", "--from", str(weak / "quad.xml")], tmp_path)
    line = _refused(done, tmp_path, "the stand test fails with gains up to 8 x", "at its peak")
    assert "_joint' at its peak" in line


def test_a_range_for_a_joint_that_does_not_exist_is_one_line(tmp_path):
    folder, _, _ = write_robot("mquad", MENAGERIE, tmp_path / "robots")
    data = yaml.safe_load((folder / "robot.yaml").read_text())
    data["joints"] = {"FL_knee": {"range": [-2.0, 0.0]}}
    (folder / "robot.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(UserError, match=r"robot spec field 'joints.FL_knee': matches no hinge"):
        spec_robot_class(folder)().build(np.array([1.0, 1.0]))
    done = coadapt(["robot", "validate", "mquad"], tmp_path)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "joints.FL_knee" in done.stderr and "Traceback" not in done.stderr


def test_a_file_named_by_an_absolute_path_is_copied_and_mapped_in_the_spec(tmp_path):
    """A mesh named by an absolute path: copied to the robot's `assets/`, the spec's `assets`
    maps the path to it, and the robot builds once the original is gone."""
    model = tmp_path / "model"
    shutil.copytree(MENAGERIE.parent, model, ignore=shutil.ignore_patterns("assets"))
    elsewhere = tmp_path / "meshes" / "trunk.obj"
    elsewhere.parent.mkdir()
    shutil.copy(MENAGERIE.parent / "assets" / "trunk.obj", elsewhere)
    text = (model / "quad.xml").read_text().replace(' meshdir="assets"', "")
    (model / "quad.xml").write_text(text.replace('file="trunk.obj"', f'file="{elsewhere}"'))
    folder, _, copied = write_robot("aquad", model / "quad.xml", tmp_path / "robots")
    assert "assets/trunk.obj" in copied
    assert yaml.safe_load((folder / "robot.yaml").read_text())["assets"] == {
        str(elsewhere): "assets/trunk.obj"
    }
    shutil.rmtree(elsewhere.parent)
    robot = spec_robot_class(folder)()
    assert "<mesh" in robot.build(robot.nominal_design()).text("mjcf")


def test_a_mesh_above_the_models_folder_keeps_its_layout_in_the_copy(tmp_path):
    """A URDF in `urdf/` naming `../meshes/trunk.obj`: the robot's folder holds both below
    their lowest common folder, and the spec's model is the path inside it."""
    tree = tmp_path / "desc"
    shutil.copytree(ROS / "quad_description", tree)
    text = (tree / "urdf" / "quad.urdf").read_text()
    (tree / "urdf" / "quad.urdf").write_text(
        text.replace("package://quad_description/meshes/trunk.obj", "../meshes/trunk.obj")
    )
    folder, _, copied = write_robot("lquad", tree / "urdf" / "quad.urdf", tmp_path / "robots")
    assert copied == ["urdf/quad.urdf", "meshes/trunk.obj"]
    assert yaml.safe_load((folder / "robot.yaml").read_text())["model"] == "urdf/quad.urdf"
    shutil.rmtree(tree)
    robot = spec_robot_class(folder)()
    assert "<mesh" in robot.build(robot.nominal_design()).text("mjcf")


def test_a_solved_standing_pose_follows_the_design(tmp_path):
    """`standing_pose.solve`: at every design each foot stands under its hip at 0.75 of its
    leg's length (MuJoCo's forward kinematics of the built model), so a corner stands as the
    nominal design does; the gait's default foot positions are those targets."""
    folder, _, _ = write_robot("rquad", URDF, tmp_path / "robots")
    assert yaml.safe_load((folder / "robot.yaml").read_text())["standing_pose"]["solve"] == 0.75
    robot = spec_robot_class(folder)()
    for design in ([1.0, 1.0], [0.7, 1.3], [1.3, 0.7]):
        model = robot.build(np.array(design))
        m = mujoco.MjModel.from_xml_string(model.text("mjcf"))
        d = mujoco.MjData(m)
        for joint, angle in zip(model.joint_names, model.default_joint_pos, strict=True):
            d.qpos[m.jnt_qposadr[m.joint(joint).id]] = angle
        mujoco.mj_kinematics(m, d)
        for leg in ("FL", "RR"):
            rel = d.xpos[m.body(f"{leg}_foot").id] - d.xpos[m.body(f"{leg}_hip").id]
            assert rel[0] == pytest.approx(0.0, abs=1e-6)
            assert rel[2] == pytest.approx(-0.75 * 0.2 * sum(design), abs=1e-6)
        feet = robot.default_foot_positions(torch.tensor([design], dtype=torch.float64))[0]
        np.testing.assert_allclose(feet[:, 2].numpy(), -0.75 * 0.2 * sum(design), atol=1e-9)


@pytest.mark.parametrize(
    ("pose", "message"),
    [
        ({"joints": {}, "solve": 1.5}, "standing_pose.solve': needs a share of the leg's length"),
        ({"keyframe": "home", "solve": 0.75}, "standing_pose.solve': goes with joints"),
    ],
)
def test_a_bad_solve_is_one_line_naming_it(tmp_path, pose, message):
    folder, _, _ = write_robot("mquad", MENAGERIE, tmp_path / "robots")
    data = yaml.safe_load((folder / "robot.yaml").read_text())
    data["standing_pose"] = pose
    (folder / "robot.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(UserError, match=message):
        spec_robot_class(folder)
