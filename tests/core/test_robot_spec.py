"""Robot specs: what a spec builds (links scaled along their vectors, the mass rule, motor
types, full-precision model text) and every bad input refused in one line naming the field."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from coadapt_plugins.robots.specs.robot import spec_robot_class

from coadapt_core.errors import UserError

NEZHA = Path(__file__).resolve().parents[2] / "plugins" / "robots" / "specs" / "nezha"


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """A copy of nezha's folder, renamed 'probe', for a test to edit."""
    target = tmp_path / "probe"
    shutil.copytree(NEZHA, target, ignore=shutil.ignore_patterns("policies", "README.md"))
    edit(target, lambda d: d.update(name="probe"))
    return target


def edit(folder: Path, change) -> None:
    path = folder / "robot.yaml"
    data = yaml.safe_load(path.read_text())
    change(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))


def build(folder: Path, design=None):
    robot = spec_robot_class(folder)()
    return robot, robot.build(robot.nominal_design() if design is None else np.array(design))


def test_a_scale_moves_the_child_along_its_vector_and_stretches_the_geoms(folder):
    _, nominal = build(folder)
    _, long = build(folder, [1.3, 0.7])
    a = mujoco.MjModel.from_xml_string(nominal.text("mjcf"))
    b = mujoco.MjModel.from_xml_string(long.text("mjcf"))
    knee = a.body("left_knee_link").id
    np.testing.assert_allclose(b.body_pos[knee], 1.3 * a.body_pos[knee], atol=1e-12)
    ankle = a.body("left_ankle_pitch_link").id
    np.testing.assert_allclose(b.body_pos[ankle], 0.7 * a.body_pos[ankle], atol=1e-12)
    thigh = a.geom("left_thigh").id  # a capsule along the link: its half-length scales
    assert b.geom_size[thigh, 1] == pytest.approx(1.3 * a.geom_size[thigh, 1], rel=1e-12)
    assert b.geom_size[thigh, 0] == pytest.approx(a.geom_size[thigh, 0], rel=1e-12)
    # a body's other children do not move (the pelvis's hips)
    hip = a.body("left_hip_pitch_link").id
    np.testing.assert_array_equal(b.body_pos[hip], a.body_pos[hip])


def test_the_stretch_rule_scales_the_stretching_share_of_the_mass(folder):
    _, nominal = build(folder)
    _, long = build(folder, [1.3, 1.0])
    a = mujoco.MjModel.from_xml_string(nominal.text("mjcf"))
    b = mujoco.MjModel.from_xml_string(long.text("mjcf"))
    body = a.body("left_hip_yaw_link").id
    # nezha's thigh: stretch_share 0.53 of 1.702 kg grows by 30 %
    assert b.body_mass[body] == pytest.approx(a.body_mass[body] * (1 + 0.3 * 0.53), rel=1e-12)
    # the stretching part carries all of the first moment about the origin; stretched with
    # its density kept (mass x s, positions x s) it grows by s^2 along the link
    first = a.body_mass[body] * a.body_ipos[body, 2]
    assert b.body_mass[body] * b.body_ipos[body, 2] == pytest.approx(1.3**2 * first, rel=1e-12)
    assert long.total_mass - nominal.total_mass == pytest.approx(2 * 0.3 * 0.53 * 1.702, rel=1e-9)
    assert "0.53 of the body's mass stretches" in long.info["mass_rules"]["thigh_scale"]


def test_motor_types_set_limits_and_add_their_mass_difference(folder):
    robot, nominal = build(folder)
    _, heavy = build(folder, [1.0, 1.0, 2, 2])  # hip pitch motors type 2 instead of 1
    k = nominal.joint_names.index("left_hip_pitch")
    assert (nominal.torque_limit[k], heavy.torque_limit[k]) == (88.0, 139.0)
    assert (nominal.speed_limit[k], heavy.speed_limit[k]) == (32.0, 20.0)
    assert heavy.total_mass - nominal.total_mass == pytest.approx(2 * (1.4 - 0.9), abs=1e-12)
    assert robot.design_space(True).names == [
        "thigh_scale",
        "shank_scale",
        "hip_motor",
        "knee_motor",
    ]


def test_model_text_keeps_full_precision(folder):
    _, model = build(folder, [1.2345678901, 0.9876543219])
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    knee = compiled.body("left_knee_link").id
    assert compiled.body_pos[knee, 2] == pytest.approx(-0.19 * 1.234568, abs=1e-15)
    assert compiled.body_subtreemass[1] == pytest.approx(model.total_mass, rel=1e-14)


def _refused(folder: Path, field: str, change=None, design=None) -> str:
    if change is not None:
        edit(folder, change)
    with pytest.raises(UserError) as info:
        build(folder, design)
    message = str(info.value)
    assert info.value.field == field, message
    assert "\n" not in message and field in message
    return message


def test_unknown_body_in_a_link(folder):
    message = _refused(
        folder, "design[0].links[0]", lambda d: d["design"][0]["links"][0].__setitem__(0, "nope")
    )
    assert "no body 'nope'" in message


def test_a_link_whose_child_is_not_the_parents_child(folder):
    def change(d):
        d["design"][0]["links"][0] = ["left_hip_yaw_link", "left_ankle_pitch_link"]

    assert "is not a child of" in _refused(folder, "design[0].links[0]", change)


@pytest.mark.parametrize("bounds", [[1.3, 0.7], [0.0, 1.3], [-0.5, 1.0]])
def test_reversed_or_non_positive_bounds(folder, bounds):
    assert "0 < low < high" in _refused(
        folder, "design[0].bounds", lambda d: d["design"][0].__setitem__("bounds", bounds)
    )


def test_a_nominal_value_outside_its_bounds(folder):
    assert "outside the bounds" in _refused(
        folder, "design[1].nominal", lambda d: d["design"][1].__setitem__("nominal", 1.5)
    )


def test_a_foot_that_does_not_end_a_leg_chain(folder):
    def change(d):
        d["legs"][0]["foot"] = "left_knee_link"

    assert "a foot ends a leg chain" in _refused(folder, "legs[0].foot", change)


def test_a_missing_standing_pose(folder):
    assert "missing" in _refused(folder, "standing_pose", lambda d: d.pop("standing_pose"))


def test_an_unknown_joint_in_the_standing_pose(folder):
    def change(d):
        d["standing_pose"] = {"joints": {"left_elbow": 0.3}}

    _refused(folder, "standing_pose.joints.left_elbow", change)


def test_a_joint_no_gain_pattern_matches(folder):
    def change(d):
        d["gains"].pop(".*_knee")

    assert "left_knee" in _refused(folder, "gains", change)


def test_a_model_that_does_not_compile_says_mujocos_line(folder):
    text = (
        (folder / "model.xml")
        .read_text()
        .replace('name="left_knee_link"', 'name="left_knee_link" bogus="1"')
    )
    (folder / "model.xml").write_text(text)
    message = _refused(folder, "model")
    assert "does not load in MuJoCo" in message and "bogus" in message


def test_a_collision_mesh_off_its_link_is_refused_unless_fitted(folder):
    text = (folder / "model.xml").read_text()
    text = text.replace(
        "<worldbody>",
        '<asset><mesh name="lump" vertex="0 0 0 0.05 0 0 0 0.05 0 0 0 0.05"/></asset>\n'
        "  <worldbody>",
    ).replace(
        '<geom name="left_thigh"',
        '<geom name="left_lump" type="mesh" mesh="lump"/><geom name="left_thigh"',
    )
    (folder / "model.xml").write_text(text)
    with pytest.raises(UserError) as info:  # any design: it cannot stretch along the link
        spec_robot_class(folder)().build(np.array([1.0, 1.0]))
    assert info.value.field == "design[0].links[0]" and "mesh 'left_lump'" in str(info.value)
    assert "`collision: fit`" in str(info.value)
    edit(folder, lambda d: d.update(collision="fit"))
    _, model = build(folder, [1.2, 1.0])
    assert "collision mesh 'left_lump' of body 'left_hip_yaw_link'" in model.info["collision_fit"]


def _cli(args: list[str], robot_path: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, COADAPT_ROBOT_PATH=str(robot_path))
    return subprocess.run(
        [sys.executable, "-m", "coadapt_core", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )


def test_the_command_line_refuses_a_bad_spec_in_one_line(folder):
    edit(folder, lambda d: d["design"][0].__setitem__("bounds", [1.3, 0.7]))
    done = _cli(["robot", "show", "probe"], folder.parent)
    assert done.returncode == 2, done.stderr
    lines = (done.stdout + done.stderr).strip().splitlines()
    assert len(lines) == 1 and "design[0].bounds" in lines[0], lines
    assert "Traceback" not in done.stderr


def test_a_spec_with_a_python_tag_is_refused_and_its_payload_does_not_run(folder, tmp_path):
    """robot.yaml is read with the safe loader: a tag that would build an object or call a
    function is refused in one line, and the call never happens."""
    marker = tmp_path / "ran"
    text = (folder / "robot.yaml").read_text()
    payload = f"!!python/object/apply:os.mkdir ['{marker}']"
    (folder / "robot.yaml").write_text(text.replace("name: probe", f"name: {payload}", 1))
    with pytest.raises(UserError, match="not readable YAML") as refused:
        spec_robot_class(folder)
    assert refused.value.field == "robot"
    done = _cli(["robot", "show", "probe"], folder.parent)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert not marker.exists()


def test_robot_new_on_a_broken_model_creates_nothing(tmp_path):
    model = tmp_path / "broken.xml"
    model.write_text(
        "<mujoco><worldbody><body name='a'><joint type='hinge' bogus='1'/></body>"
        "</worldbody></mujoco>"
    )
    done = _cli(
        ["robot", "new", "broken", "--from", str(model), "--into", str(tmp_path / "robots")],
        tmp_path,
    )
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and "does not load in MuJoCo" in done.stderr
    assert not (tmp_path / "robots" / "broken").exists()


def test_the_registry_keeps_a_plugins_robot_over_a_users_spec_of_its_name(folder, monkeypatch):
    from coadapt_core.plugins import load_registry

    edit(folder, lambda d: d.update(name="qilin"))
    monkeypatch.setenv("COADAPT_ROBOT_PATH", str(folder.parent))
    registry = load_registry()
    assert registry.get("robot", "qilin").__name__ == "Qilin"
    lines = [b.line() for b in registry.broken]
    assert any("robot name 'qilin' is taken" in line for line in lines), lines


def test_a_users_spec_is_versioned_by_its_files(folder, monkeypatch):
    from coadapt_core.plugins import load_registry

    monkeypatch.setenv("COADAPT_ROBOT_PATH", str(folder.parent))
    before = {i.name: i.version for i in load_registry().all() if i.kind == "robot"}["probe"]
    text = (folder / "model.xml").read_text().replace('damping="0.1"', 'damping="0.2"')
    (folder / "model.xml").write_text(text)
    after = {i.name: i.version for i in load_registry().all() if i.kind == "robot"}["probe"]
    assert len(before) == 12 and before != after


def test_a_spec_that_does_not_read_is_named_by_its_folder(folder, monkeypatch):
    from coadapt_core.errors import UnknownPluginError
    from coadapt_core.plugins import load_registry

    edit(folder, lambda d: d["design"][0].__setitem__("nominal", 2.0))
    monkeypatch.setenv("COADAPT_ROBOT_PATH", str(folder.parent))
    registry = load_registry()
    assert "probe" not in registry.names("robot") and "kuafu" in registry.names("robot")
    with pytest.raises(UnknownPluginError) as info:
        registry.get("robot", "probe")
    assert "design[0].nominal" in str(info.value) and "unknown robot" not in str(info.value)


def test_a_urdf_model_file_makes_a_spec_robot_too(tmp_path):
    """MuJoCo reads URDF: `robot new` on Qilin's URDF keeps its fixed feet and root link
    (no static bodies fused) and builds Qilin's masses and feet."""
    from coadapt_plugins.robots.specs.new import write_robot

    from coadapt_core.plugins import get_registry

    qilin = get_registry().create("robot", "qilin").build(np.array([1.0, 1.0]))
    (tmp_path / "qilin.urdf").write_text(qilin.text("urdf"))
    folder, _, _ = write_robot("qurdf", tmp_path / "qilin.urdf", tmp_path / "robots")
    robot = spec_robot_class(folder)()
    model = robot.build(robot.nominal_design())
    assert model.foot_bodies == qilin.foot_bodies and model.base_body == "base"
    assert model.total_mass == pytest.approx(qilin.total_mass, rel=1e-12)
    assert robot.validate(robot.nominal_design()).feasible


def test_the_design_sheet_lists_a_spec_robots_mass_rules(folder):
    """`coadapt handoff`'s design sheet prints a spec robot's info, text entries included."""
    from coadapt_core.handoff.sheet import _info_rows

    _, model = build(folder)
    rows = "\n".join(_info_rows(dict(model.info)))
    assert "| mass rules | thigh_scale 0.53 of the body's mass stretches" in rows
    assert "| thigh scale link length | 0.19 | m |" in rows


def test_a_closed_chain_is_refused(folder):
    text = (
        (folder / "model.xml")
        .read_text()
        .replace(
            "</mujoco>",
            '<equality><connect body1="left_foot" body2="right_foot" anchor="0 0 0"/></equality>'
            "\n</mujoco>",
        )
    )
    (folder / "model.xml").write_text(text)
    assert "closed chains" in _refused(folder, "model")


def test_a_spec_robot_ships_its_policy_in_its_own_folder():
    from coadapt_core.learning.checkpoints import read_checkpoint
    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", "nezha")
    path = robot.shipped_policy("flat", False)
    assert path == NEZHA / "policies" / "flat.pt"
    state = read_checkpoint(path)
    assert state["robot"] == "nezha" and int(state["dims"]["num_design"]) == 2
    assert robot.shipped_policy("flat", True) is None and robot.shipped_policy("slope") is None


@pytest.mark.parametrize("source", ["qilin", "nezha"])
def test_robot_new_on_qilins_and_nezhas_model_files_writes_specs_that_validate(tmp_path, source):
    from coadapt_plugins.robots.specs.new import write_robot

    from coadapt_core.plugins import get_registry

    if source == "qilin":
        qilin = get_registry().create("robot", "qilin")
        model_file = tmp_path / "qilin.xml"
        model_file.write_text(qilin.build(qilin.nominal_design()).text("mjcf"))
    else:
        model_file = NEZHA / "model.xml"
    folder, notes, _ = write_robot(f"{source}-new", model_file, tmp_path / "robots")
    robot = spec_robot_class(folder)()
    assert len(robot.legs()) == (4 if source == "qilin" else 2)
    assert robot.design_space().names == (
        ["thigh_scale", "calf_scale"] if source == "qilin" else ["hip_yaw_scale", "knee_scale"]
    )
    for design in ([1.0, 1.0], [0.7, 0.7], [1.3, 1.3]):
        report = robot.validate(np.array(design))
        assert report.feasible, report.reasons
    assert any("no-load joint speeds" in line for line in notes)
