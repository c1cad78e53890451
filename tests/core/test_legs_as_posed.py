"""Legs as a model file poses them (issue 58): `robot new` locks the slide joints between the
base and the legs (motors hung on sprung brackets, PyBullet's minitaur_rainbow_dash_v1) at 0
inside their range, at the nearest limit where 0 lies outside it, or at the keyframe's value,
writes them under `locked_joints` with a comment and says so; it takes alike leg chains posed
straight out (PyBullet's microtaur at its zero pose) as the legs and solves each foot under its
hip. Small MJCF models written here; a slide a motor drives stays one line, exit 2."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from coadapt_plugins.robots.specs.new import starting_spec, write_robot
from coadapt_plugins.robots.specs.robot import spec_robot_class

from coadapt_core.errors import UserError

CORNERS = [("fl", 0.15, 0.1), ("fr", 0.15, -0.1), ("rl", -0.15, 0.1), ("rr", -0.15, -0.1)]


def bracket_quad(slide_range: str = "-0.02 0.02", key: str = "", driven: bool = False) -> str:
    """A 12 kg quadruped whose legs (hip and knee hinges, 0.2 m thigh and shin) each hang
    on a bracket on a slide joint (axis z) below the trunk; `key` a "home" keyframe's qpos."""
    legs, motors = [], []
    for name, x, y in CORNERS:
        legs.append(f"""
      <body name="{name}_bracket" pos="{x} {y} -0.03">
        <joint name="{name}_slide" type="slide" axis="0 0 1" range="{slide_range}"/>
        <geom type="box" size="0.02 0.02 0.01" mass="0.1"/>
        <body name="{name}_thigh">
          <joint name="{name}_hip" axis="0 1 0" range="-1.5 1.5" armature="0.01" damping="0.1"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.02" mass="0.5"/>
          <body name="{name}_shin" pos="0 0 -0.2">
            <joint name="{name}_knee" axis="0 1 0" range="-2.5 0" armature="0.01" damping="0.1"/>
            <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.015" mass="0.3"/>
            <body name="{name}_foot" pos="0 0 -0.2">
              <geom type="sphere" size="0.02" mass="0.05"/>
            </body>
          </body>
        </body>
      </body>""")
        motors += [
            f'<motor name="{name}_{j}" joint="{name}_{j}" ctrlrange="-40 40"/>'
            for j in ("hip", "knee")
        ]
        if driven:
            motors.append(f'<motor name="{name}_lift" joint="{name}_slide" ctrlrange="-9 9"/>')
    keyframe = f'<keyframe><key name="home" qpos="{key}"/></keyframe>' if key else ""
    return f"""<mujoco model="bracket_quad">
  <compiler angle="radian"/>
  <worldbody>
    <body name="trunk" pos="0 0 0.4">
      <freejoint/>
      <geom type="box" size="0.2 0.12 0.04" mass="9"/>{"".join(legs)}
    </body>
  </worldbody>
  <actuator>{"".join(motors)}</actuator>{keyframe}
</mujoco>"""


def written(tmp_path: Path, text: str, name: str = "quad.xml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_slide_between_base_and_leg_is_locked_at_0_said_and_gone_from_the_robot(tmp_path):
    model = written(tmp_path, bracket_quad())
    before = model.read_bytes()
    folder, notes, _ = write_robot("bq", model, tmp_path / "robots")
    assert model.read_bytes() == before
    text = (folder / "robot.yaml").read_text()
    spec = yaml.safe_load(text)
    assert spec["locked_joints"] == [f"{n}_slide" for n, _, _ in CORNERS]  # at 0: names alone
    assert "# locked_joints: assumed: slide joints between the base and the legs held rigid" in text
    said = next(line for line in notes if line.startswith("slide joints between the base"))
    assert "fl_slide at 0 m" in said and "locked (locked_joints)" in said
    assert len(spec["legs"]) == 4 and spec["standing_pose"]["solve"] == 0.75
    robot = spec_robot_class(folder)()
    built = robot.build(robot.nominal_design())
    assert len(built.joint_names) == 8 and not any("slide" in j for j in built.joint_names)
    compiled = mujoco.MjModel.from_xml_string(built.text("mjcf"))
    assert not any(compiled.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE)
    np.testing.assert_allclose(compiled.body("fl_bracket").pos, [0.15, 0.1, -0.03], atol=1e-9)


def test_a_slide_whose_range_leaves_out_0_is_locked_at_its_nearest_limit(tmp_path):
    data, notes, comments = starting_spec("bq", written(tmp_path, bracket_quad("0.01 0.03")))
    assert data["locked_joints"] == [{f"{n}_slide": 0.01} for n, _, _ in CORNERS]
    said = next(line for line in notes if line.startswith("slide joints between the base"))
    assert "fl_slide at 0.01 m (0 lies outside its range [0.01, 0.03]: its nearest limit)" in said
    assert "where 0 lies outside a joint's range: its nearest limit" in comments["locked_joints"]


def test_a_keyframes_slide_value_is_where_it_is_locked_and_the_keyframe_still_loads(tmp_path):
    legs = " ".join("0.015 0.4 -0.8" for _ in CORNERS)  # slide, hip, knee per leg
    path = written(tmp_path, bracket_quad(key=f"0 0 0.36 1 0 0 0 {legs}"))
    folder, notes, _ = write_robot("bq", path, tmp_path / "robots")
    spec = yaml.safe_load((folder / "robot.yaml").read_text())
    assert spec["locked_joints"] == [{f"{n}_slide": 0.015} for n, _, _ in CORNERS]
    assert spec["standing_pose"] == {"keyframe": "home"}
    assert any("fl_slide at 0.015 m;" in line for line in notes)
    text = (folder / "robot.yaml").read_text()
    assert "slide joints between the base and the legs held rigid at keyframe 'home'" in text
    robot = spec_robot_class(folder)()
    built = robot.build(robot.nominal_design())
    np.testing.assert_allclose(built.default_joint_pos, [0.4, -0.8] * 4, atol=1e-12)
    compiled = mujoco.MjModel.from_xml_string(built.text("mjcf"))  # moved up by 0.015 m
    np.testing.assert_allclose(compiled.body("rr_bracket").pos, [-0.15, -0.1, -0.015], atol=1e-9)


def test_locked_joints_takes_a_value_and_refuses_a_bad_one_in_one_line(tmp_path):
    folder, _, _ = write_robot("bq", written(tmp_path, bracket_quad()), tmp_path / "robots")
    data = yaml.safe_load((folder / "robot.yaml").read_text())
    data["locked_joints"] = [{"fl_slide": -0.02}, "fr_slide", "rl_slide", {"rr_slide": 0.0}]
    (folder / "robot.yaml").write_text(yaml.safe_dump(data))
    compiled = mujoco.MjModel.from_xml_string(
        spec_robot_class(folder)().build(np.ones(2)).text("mjcf")
    )
    np.testing.assert_allclose(compiled.body("fl_bracket").pos, [0.15, 0.1, -0.05], atol=1e-9)
    for bad, message in [
        ({"fl_slide": "low"}, "'locked_joints[0].fl_slide': needs a finite number"),
        ({"fl_slide": 0.0, "fr_slide": 0.0}, "'locked_joints[0]': needs one NAME: VALUE"),
        ("no_such_joint", "'locked_joints': no joint 'no_such_joint' in the model"),
    ]:
        data["locked_joints"] = [bad]
        (folder / "robot.yaml").write_text(yaml.safe_dump(data))
        with pytest.raises(UserError, match=re.escape(message)):
            spec_robot_class(folder)().build(np.ones(2))


def test_a_slide_a_motor_drives_is_not_locked_and_robot_new_says_so_in_one_line(tmp_path):
    model = written(tmp_path, bracket_quad(driven=True))
    env = dict(os.environ, COADAPT_ROBOT_PATH=str(tmp_path / "robots"))
    done = subprocess.run(
        [sys.executable, "-m", "coadapt_core", "robot", "new", "bq", "--from", str(model)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 2, done.stdout + done.stderr
    assert done.stderr.startswith("error: ") and done.stderr.strip().count("\n") == 0
    assert "joint 'fl_slide' is not a hinge" in done.stderr
    assert not (tmp_path / "robots" / "bq").exists()


def sideways_quad(down: bool = False, rr_shin: float = 0.2) -> str:
    """A quadruped whose legs (abduction about x at the trunk's side, then pitch and knee
    hinges about the trunk's z at 0) lie straight out sideways at the zero pose, as
    PyBullet's microtaur's; `down`: the rear right abduction's range [1.4, 1.7] rad leaves
    out 0, so that leg alone hangs (near) down at the pose; `rr_shin` its shin's length."""
    legs = []
    for name, x, y in CORNERS:
        s = 1.0 if y > 0 else -1.0
        length = rr_shin if name == "rr" else 0.2
        shin = f"0 {s * length} 0"
        limits = ' range="1.4 1.7"' if down and name == "rr" else ""
        legs.append(f"""
      <body name="{name}_hip" pos="{x} {y} 0">
        <joint name="{name}_abduct" axis="1 0 0"{limits}/>
        <geom type="box" size="0.03 0.03 0.03" mass="0.3"/>
        <body name="{name}_thigh" pos="0 {s * 0.05} 0">
          <joint name="{name}_pitch" axis="0 0 1"/>
          <geom type="capsule" fromto="0 0 0 0 {s * 0.2} 0" size="0.02" mass="0.5"/>
          <body name="{name}_shin" pos="0 {s * 0.2} 0">
            <joint name="{name}_knee" axis="0 0 1"/>
            <geom type="capsule" fromto="0 0 0 {shin}" size="0.015" mass="0.3"/>
            <body name="{name}_foot" pos="{shin}">
              <geom type="sphere" size="0.02" mass="0.05"/>
            </body>
          </body>
        </body>
      </body>""")
    return f"""<mujoco model="sideways_quad">
  <compiler angle="radian"/>
  <worldbody>
    <body name="trunk" pos="0 0 0.4">
      <freejoint/>
      <geom type="box" size="0.2 0.1 0.04" mass="9"/>{"".join(legs)}
    </body>
  </worldbody>
</mujoco>"""


@pytest.mark.parametrize("down", [False, True], ids=["all-out", "one-down"])
def test_alike_legs_posed_out_sideways_are_the_legs_feet_solved_under_hips(down, tmp_path):
    data, notes, _ = starting_spec("sq", written(tmp_path, sideways_quad(down)))
    assert [leg["foot"] for leg in data["legs"]] == [f"{n}_foot" for n, _, _ in CORNERS]
    assert any(
        "its 4 alike chains of 3 hinges taken as the legs, each foot solved under its hip" in line
        for line in notes
    )
    pose = data["standing_pose"]["joints"]
    assert abs(abs(pose["fl_abduct"]) - np.pi / 2) < 0.1  # the leg turned down
    if not down:  # (the rear right leg, hung near down at its limit, may stay as it hangs)
        assert any("standing pose solved with 4 of 4 feet" in line for line in notes)


def test_one_foot_down_of_legs_not_alike_is_still_refused_in_one_line(tmp_path):
    """The rear right shin 0.3 m, the others 0.2 m: not one kind of leg, so the one foot
    near the ground is all robot new sees, as before."""
    with pytest.raises(UserError, match="found one leg standing") as info:
        starting_spec("sq", written(tmp_path, sideways_quad(down=True, rr_shin=0.3)))
    assert "\n" not in str(info.value)


def test_a_joint_welded_at_a_value_puts_its_body_where_that_value_does():
    """`locks.lock_joints` on a hinge off its body's origin, about a slanted axis, with a
    reference angle, and on a slide: every body lies where the free model puts it with the
    joints at those values."""
    from coadapt_plugins.robots.specs.locks import lock_joints

    xml = """<mujoco><compiler angle="radian"/><worldbody><body name="a" pos="0 0 1">
      <freejoint/><geom size="0.1"/>
      <body name="b" pos="0.1 0.2 0" euler="0.3 0.1 0.2">
        <joint name="h" pos="0.05 0 0.02" axis="0 1 1" ref="0.2"/><geom size="0.05"/>
        <body name="c" pos="0 0 -0.3" euler="0 0.4 0">
          <joint name="s" type="slide" axis="1 0 1"/><geom size="0.05"/>
          <body name="d" pos="0.1 0 -0.2"><geom size="0.02"/></body>
        </body>
      </body></body></worldbody></mujoco>"""
    free = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(free)
    data.qpos[:7] = free.qpos0[:7]
    data.qpos[7:] = [0.9, 0.03]  # the hinge at 0.9 rad (0.7 from its reference), the slide
    mujoco.mj_kinematics(free, data)
    spec = mujoco.MjSpec.from_string(xml)
    lock_joints(spec, ["h", "s"], {"h": 0.9, "s": 0.03})
    welded = spec.compile()
    assert welded.njnt == 1
    weld = mujoco.MjData(welded)
    mujoco.mj_kinematics(welded, weld)
    for body in ("b", "c", "d"):
        np.testing.assert_allclose(weld.body(body).xpos, data.body(body).xpos, atol=1e-12)
        np.testing.assert_allclose(weld.body(body).xmat, data.body(body).xmat, atol=1e-12)
