"""Four-bar legs a model file leaves open, closed by the robot (issue 58, spec `loops`):
pybullet_data's minitaur.urdf as it is, with a spec written here, builds with its knees
passive (no motor, not policy joints) and its loops closed at the standing pose; joint PD
holds it standing in MuJoCo (a `<connect>` per leg) and in PyBullet (a point-to-point
constraint per leg, as PyBullet's own minitaur environment adds) with each toe's two ends
together; the statics count the pins' forces; the leg IK moves both halves of a leg; bad
loops are one line naming the field. `robot new` finds the four-bars and writes the loops
itself (tests/core/test_robot_corpus.py takes three minitaur files on to a co-design run);
coaxial halves whose ends do not meet are refused in one line."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from coadapt_plugins.robots.specs.new import starting_spec

from coadapt_core.errors import UserError

pytest.importorskip("pybullet_data")
import pybullet_data

SOURCE = Path(pybullet_data.getDataPath()) / "quadruped" / "minitaur.urdf"
LEGS = ("front_left", "front_right", "back_left", "back_right")


def minitaur_spec(**change) -> dict:
    """A spec for minitaur.urdf as the file is: each leg's two lower legs' ends pinned
    together, the knees passive, the motors at pi/2 (upper legs level, the leg a diamond)."""
    pose = {}
    for leg in LEGS:
        for side in "LR":
            pose[f"motor_{leg}{side}_joint"] = math.pi / 2
            pose[f"knee_{leg}{side}_link"] = -2.1834  # PyBullet's minitaur's knee angle
    halves = [(leg, side) for leg in LEGS for side in "LR"]
    spec = {
        "name": "minitaur-test",
        "model": "minitaur.urdf",
        "base": "base_chassis_link",
        "tips": {f"lower_leg_{g}{s}_link": [0.0, 0.0, 0.2] for g, s in halves},
        "loops": [
            {
                "bodies": [f"lower_leg_{g}L_link_tip", f"lower_leg_{g}R_link_tip"],
                "passive": [f"knee_{g}L_link", f"knee_{g}R_link"],
            }
            for g in LEGS
        ],
        "design": [
            {
                "name": "upper_scale",
                "bounds": [0.8, 1.2],
                "mass": "fixed",
                "links": [[f"upper_leg_{g}{s}_link", f"lower_leg_{g}{s}_link"] for g, s in halves],
            },
            {
                "name": "lower_scale",
                "bounds": [0.8, 1.2],
                "mass": "fixed",
                "links": [
                    [f"lower_leg_{g}{s}_link", f"lower_leg_{g}{s}_link_tip"] for g, s in halves
                ],
            },
        ],
        "limits": {"torque": {"motor_.*": 10.0}, "speed": {"motor_.*": 50.0}},
        "joints": {"motor_.*": {"range": [-3.2, 3.2]}},
        "legs": [
            {"name": g, "foot": f"lower_leg_{g}L_link_tip", "hip": f"motor_{g}L_link", "phase": ph}
            for g, ph in zip(LEGS, (0.0, 0.5, 0.5, 0.0), strict=True)
        ],
        "standing_pose": {"joints": pose},
        "gains": {"default": {"kp": 100.0, "kd": 2.5}},
    }
    spec.update(change)
    return spec


def robot_in(folder: Path, **change):
    from coadapt_plugins.robots.specs.robot import spec_robot_class

    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(SOURCE, folder / SOURCE.name)
    (folder / "robot.yaml").write_text(yaml.safe_dump(minitaur_spec(**change)))
    return spec_robot_class(folder)()


def pin_gaps(model, data) -> np.ndarray:
    """[K] the distance between each loop's two sites."""
    return np.array(
        [
            np.linalg.norm(data.site_xpos[model.eq_obj1id[e]] - data.site_xpos[model.eq_obj2id[e]])
            for e in range(model.neq)
        ]
    )


def test_the_knees_are_passive_and_every_loop_is_closed_at_the_standing_pose(tmp_path):
    before = SOURCE.read_bytes()
    robot = robot_in(tmp_path / "mt")
    rm = robot.build(robot.nominal_design())
    assert SOURCE.read_bytes() == before  # the user's file is theirs
    assert sorted(rm.joint_names) == sorted(f"motor_{g}{s}_joint" for g in LEGS for s in "LR")
    model = mujoco.MjModel.from_xml_string(rm.text("mjcf"))
    assert model.nu == 8 and model.neq == 4  # a motor per motor joint, a pin per leg
    data = mujoco.MjData(model)
    for name, angle in zip(rm.joint_names, rm.default_joint_pos, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    mujoco.mj_kinematics(model, data)  # the knees at 0: the standing pose's angles
    assert pin_gaps(model, data).max() < 1e-9
    knee = data.xpos[model.body("lower_leg_front_leftL_link").id]
    toe = data.xpos[model.body("lower_leg_front_leftL_link_tip").id]
    assert toe[2] < knee[2] - 0.1  # a diamond: the toe below the knees
    assert 0.14 < rm.standing_base_height < 0.2
    urdf = rm.text("urdf")
    assert 'name="knee_front_leftL_link" type="continuous"' in urdf
    # another design closes its loops too (its knees solved again)
    longer = robot.build(np.array([1.2, 0.8]))
    model = mujoco.MjModel.from_xml_string(longer.text("mjcf"))
    data = mujoco.MjData(model)
    for name, angle in zip(longer.joint_names, longer.default_joint_pos, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    mujoco.mj_kinematics(model, data)
    assert pin_gaps(model, data).max() < 1e-9


@pytest.mark.slow
def test_joint_pd_holds_it_standing_in_mujoco_and_pybullet_with_the_toes_pinned(tmp_path):
    from coadapt_plugins.robots.specs.validation import stand_test

    robot = robot_in(tmp_path / "mt")
    rm = robot.build(robot.nominal_design())
    stand = stand_test(rm)
    assert stand.ok and stand.lowest > 0.8, stand.text()
    # the pins hold in MuJoCo, stepped as the stand test steps it, for 6 s (the file's
    # links have inertias of 1 kg m^2: the legs settle slowly)
    spec = mujoco.MjSpec.from_string(rm.text("mjcf"))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], conaffinity=1)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:7] = [0, 0, rm.standing_base_height, 1, 0, 0, 0]
    qadr = [model.jnt_qposadr[model.joint(j).id] for j in rm.joint_names]
    vadr = [model.jnt_dofadr[model.joint(j).id] for j in rm.joint_names]
    data.qpos[qadr] = rm.default_joint_pos
    for _ in range(3000):
        torque = rm.kp * (rm.default_joint_pos - data.qpos[qadr]) - rm.kd * data.qvel[vadr]
        data.ctrl[:] = np.clip(torque, -rm.torque_limit, rm.torque_limit)
        mujoco.mj_step(model, data)
    assert pin_gaps(model, data).max() < 2e-3
    assert data.qpos[2] > 0.8 * rm.standing_base_height
    # the statics count the pins: its largest motor torque is what PD holds at rest
    report = robot.validate(robot.nominal_design())
    statics = next(f for f in report.findings if f.check == "statics.standing_torque")
    held = float(np.max(np.abs(data.ctrl) / rm.torque_limit))
    assert statics.ok and abs(statics.value - held) < 0.05 * held, (statics.value, held)
    assert all(f.ok for f in report.findings), [f.message for f in report.findings if not f.ok]
    # PyBullet: the URDF is a tree, the engine pins the toes as PyBullet's minitaur does
    gaps, height, bent = _pybullet_hold(robot, rm)
    assert max(gaps) < 2e-3 and height > 0.5 * rm.standing_base_height, (max(gaps), height)
    assert abs(bent) > 0.05  # the knees, free, follow the motors (0.1 rad)


def _pybullet_hold(robot, rm) -> tuple[list[float], float]:
    """(each loop's gap, the base height, how far a knee turned) on PyBullet after 1 s of
    joint PD toward the standing pose with every motor 0.2 rad on."""
    import pybullet as p
    from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator
    from coadapt_plugins.simulators.pybullet.spec import EnvSpec

    from coadapt_core.physics.randomization import RandomizationConfig

    loops = EnvSpec.from_model(rm).loops
    assert len(loops) == 4
    with PyBulletSimulator(
        robot, robot.nominal_design()[None], randomization=RandomizationConfig.off()
    ) as sim:
        sim.reset()
        engine = sim._engine  # one environment: in this process
        client, body = engine.clients[0], engine.bodies[0]
        names = {
            p.getJointInfo(body, i, physicsClientId=client)[12].decode(): i
            for i in range(p.getNumJoints(body, physicsClientId=client))
        }
        knee = names["lower_leg_front_leftL_link"]  # a joint's index is its child link's
        start = p.getJointState(body, knee, physicsClientId=client)[0]
        # every motor turned 0.2 rad on: each leg shortens, its knees bend with it
        targets = sim.default_joint_pos.clone() + 0.2
        for _ in range(50):
            state = sim.step(targets)
        bent = p.getJointState(body, knee, physicsClientId=client)[0] - start
        gaps = []
        for a, pa, b, pb in loops:
            ends = []
            for link, point in ((a, pa), (b, pb)):
                frame = p.getLinkState(body, names[link], physicsClientId=client)
                rot = np.array(p.getMatrixFromQuaternion(frame[5])).reshape(3, 3)
                ends.append(np.array(frame[4]) + rot @ np.array(point))
            gaps.append(float(np.linalg.norm(ends[0] - ends[1])))
    return gaps, float(state.base_pos[0, 2]), bent


@pytest.mark.parametrize(
    ("change", "field", "says"),
    [
        ({"loops": [{"bodies": ["nowhere", "lower_leg_front_leftR_link_tip"]}]},
         "loops[0].bodies", "no body 'nowhere'"),
        ({"loops": [{"bodies": ["lower_leg_front_leftL_link_tip", "lower_leg_front_leftR_link_tip"],
                     "passive": ["knee_nowhere"]}]},
         "loops[0].passive", "'knee_nowhere' is not a hinge"),
        ({"loops": [{**loop, "bodies": [loop["bodies"][0], "lower_leg_back_rightR_link_tip"]}
                    if k == 0 else loop for k, loop in enumerate(minitaur_spec()["loops"])]},
         "loops[0]", "the loop does not close"),
        ({"loops": [{"bodies": ["a"]}]}, "loops[0].bodies", "needs two bodies"),
    ],
)  # fmt: skip
def test_a_bad_loop_is_one_line_naming_it(change, field, says, tmp_path):
    with pytest.raises(UserError) as caught:
        robot_in(tmp_path / "mt", **change).build(np.array([1.0, 1.0]))
    message = str(caught.value)
    assert "\n" not in message and f"'{field}'" in message and says in message, message


@pytest.mark.parametrize(
    ("pins", "field", "says"),
    [
        ({"nowhere": [0.0, 0.0, 0.1]}, "pins.nowhere",
         "no body 'nowhere' in the model; pins takes a body of the model and a point [x, y, z]"),
        ({"lower_leg_front_leftL_link": [0.0, 0.2]}, "pins.lower_leg_front_leftL_link",
         "needs a point [x, y, z] in the body's frame, got [0.0, 0.2]"),
        ({"lower_leg_front_leftL_link": [0.0, 0.0, 0.1, 0.0]}, "pins.lower_leg_front_leftL_link",
         "needs a point [x, y, z]"),
        ([[0.0, 0.0, 0.1]], "pins", "needs a mapping"),
    ],
)  # fmt: skip
def test_a_bad_pin_is_one_line_naming_it(pins, field, says, tmp_path):
    with pytest.raises(UserError) as caught:
        robot_in(tmp_path / "mt", pins=pins).build(np.array([1.0, 1.0]))
    message = str(caught.value)
    assert "\n" not in message and f"'{field}'" in message and says in message, message


def test_the_command_line_refuses_a_bad_pin_in_one_line_exit_2(tmp_path):
    import os
    import subprocess
    import sys

    robot_in(tmp_path / "robots" / "mt", pins={"nowhere": [0.0, 0.0, 0.1]})
    done = subprocess.run(
        [sys.executable, "-m", "coadapt_core", "robot", "show", "minitaur-test", "--no-validate"],
        capture_output=True, text=True, timeout=300,
        env=dict(os.environ, COADAPT_ROBOT_PATH=str(tmp_path / "robots")),
    )  # fmt: skip
    lines = (done.stdout + done.stderr).strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "'pins.nowhere'" in lines[0], lines


def test_robot_new_finds_the_four_bars_and_writes_them_as_loops():
    data, notes, comments = starting_spec("probe", SOURCE)
    assert [leg["name"] for leg in data["legs"]] == list(LEGS)
    # each leg's outer half first: its motor the hip, its end the toe
    outer = {"front_left": "L", "front_right": "R", "back_left": "L", "back_right": "R"}
    assert [leg["hip"] for leg in data["legs"]] == [f"motor_{g}{outer[g]}_link" for g in LEGS]
    assert data["loops"][0] == {
        "bodies": ["lower_leg_front_leftL_link_tip", "lower_leg_front_leftR_link_tip"],
        "passive": ["knee_front_leftL_link", "knee_front_leftR_link"],
    }
    assert len(data["loops"]) == 4 and "loops" in comments
    assert "base_orientation" not in data  # its legs point up at zero: the file's z is up
    assert sorted(data["limits"]["torque"]) == sorted(
        f"motor_{g}{s}_joint" for g in LEGS for s in "LR"
    )  # the knees get no motor
    assert abs(data["tips"]["lower_leg_front_leftR_link"][2] - 0.19) < 1e-9  # 0.2 less 1 cm
    assert any(n.startswith("four-bar legs (4, each two chains") for n in notes)
    # each half's standing angles written, the knees apart (upper legs out on either side)
    pose = data["standing_pose"]["joints"]
    assert len(pose) == 16 and 0.85 < data["standing_pose"]["solve"] < 0.95  # solved per design


def test_robot_new_pins_a_longer_lower_leg_where_the_other_meets_it():
    """minitaur_derpy.urdf: each leg's lower legs reach 0.24 and 0.216 m; the shorter one's
    end meets the longer 0.206 m along it, and the longer one's end is the toe."""
    data, _, comments = starting_spec("probe", SOURCE.parent / "minitaur_derpy.urdf")
    assert data["pins"]["lower_leg_front_leftL_link"] == [0.0, 0.0, 0.206]
    assert data["loops"][0]["bodies"] == [
        "lower_leg_front_leftL_link_pin",
        "lower_leg_front_leftR_link_tip",
    ]
    assert data["legs"][0]["foot"] == "lower_leg_front_leftL_link_tip"  # the longer's end
    assert abs(data["tips"]["lower_leg_front_leftL_link"][2] - 0.23) < 1e-9
    assert "pins" in comments
    # the pin moves with the lower leg's scale, as its tip does
    lower = next(p for p in data["design"] if p["name"] == "lower_leg_scale")
    assert ["lower_leg_front_leftL_link", "lower_leg_front_leftL_link_pin"] in lower["links"]


def test_the_leg_ik_moves_both_halves_and_keeps_the_toes_together(tmp_path):
    import torch
    from coadapt_plugins.robots.specs.loops import solve_passive

    robot = robot_in(tmp_path / "mt")
    design = torch.tensor([[1.2, 0.8]], dtype=torch.float64)
    rm = robot.build(design[0].numpy())
    toes = robot.default_foot_positions(design)  # [1, 4, 3] from the hips, closed
    model = mujoco.MjModel.from_xml_string(rm.text("mjcf"))
    data = mujoco.MjData(model)
    data.qpos[3:7] = [1, 0, 0, 0]

    def toe_at(motors) -> np.ndarray:
        passive = [model.joint(j).name for j in range(1, model.njnt)]
        passive = [j for j in passive if j not in rm.joint_names]
        loops = [(f"lower_leg_{g}L_link_tip", f"lower_leg_{g}R_link_tip", ()) for g in LEGS]
        knees, _ = solve_passive(
            model, loops, rm.joint_names, motors, passive, np.zeros(len(passive))
        )
        pairs = [*zip(rm.joint_names, motors, strict=True), *zip(passive, knees, strict=True)]
        for name, angle in pairs:
            data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
        mujoco.mj_kinematics(model, data)
        leg = robot.spec.legs[0]
        return data.xpos[model.body(leg.foot).id] - data.xpos[model.body(leg.hip).id]

    assert np.abs(toe_at(rm.default_joint_pos) - toes[0, 0].numpy()).max() < 1e-6
    target = toes.clone()
    target[..., 0] += 0.03  # 3 cm forward, 2 cm up
    target[..., 2] += 0.02
    motors = robot.leg_inverse_kinematics(design, target)[0].numpy()
    assert np.abs(motors - rm.default_joint_pos).max() > 0.1
    reached = toe_at(motors)
    assert abs(reached[0] - target[0, 0, 0]) < 1e-3 and abs(reached[2] - target[0, 0, 2]) < 1e-3


def _edited(text: str, start: str, old: str, new: str) -> str:
    """`text` with `old` replaced by `new` in the element that starts with `start`."""
    begin = text.index(start)
    end = text.index(f"</{start.split()[0][1:]}>", begin)
    return text[:begin] + text[begin:end].replace(old, new) + text[end:]


@pytest.mark.parametrize(
    ("edits", "says"),
    [
        # one lower leg hung 5 cm further out along the axis: the ends do not meet
        ([('<joint name="knee_front_leftR_link"', 'xyz="0.0 0.01 .055"', 'xyz="0.0 0.06 .055"')],
         "two halves of a four-bar leg, but their ends are"),
    ],
)  # fmt: skip
def test_coaxial_halves_whose_ends_do_not_meet_are_refused_in_one_line(edits, says, tmp_path):
    """(One lower leg shorter than the other meets it short of its end: a `pins` body there,
    as minitaur_derpy's, test_robot_new_pins_a_longer_lower_leg_where_the_other_meets_it.)"""
    text = SOURCE.read_text()
    for start, old, new in edits:
        changed = _edited(text, start, old, new)
        assert changed != text
        text = changed
    model = tmp_path / "edited.urdf"  # a model written for the test: the user's file as it is
    model.write_text(text)
    with pytest.raises(UserError) as found:
        starting_spec("probe", model)
    message = str(found.value)
    assert "\n" not in message and says in message, message


def test_the_mirror_pairs_each_four_bars_outer_motor_with_the_mirror_legs_outer_one(tmp_path):
    """quadruped.urdf's halves sit 0.125 m (outer, R) and 0.06 m (inner, L) from the base's
    x-z plane on either side: the mirror pairs R with R. Its pose solved per design differs
    between mirror legs by up to 6.6e-5 rad (its motors turned by rpy 1.57075, not pi/2, the
    same way on both sides): within the map's 1e-3 rad, it gets a map. minitaur.urdf's
    differs by up to 0.025 rad (its outer lower legs differ by 1 mm): refused in one line.
    minitaur_derpy's (1.4e-7 rad) gets a map: its longer, pinned halves outer on both sides,
    paired."""
    from coadapt_plugins.robots.specs.new import write_robot
    from coadapt_plugins.robots.specs.robot import spec_robot_class

    folder, _, _ = write_robot("quadruped", SOURCE.parent / "quadruped.urdf", tmp_path)
    robot = spec_robot_class(folder)()
    mirror, joints = robot.mirror(), robot._built.prepared.joints
    pairs = {joints[k]: joints[m] for k, m in enumerate(mirror.joints)}
    assert all(pairs[j][-7] == j[-7] for j in joints), pairs  # outer with outer (R with R)
    assert pairs["motor_front_rightR_joint"] == "motor_front_leftR_joint"
    assert mirror.joint_signs == (1.0,) * 8 and mirror.legs == (1, 0, 3, 2)
    pose = robot.build(robot.nominal_design()).default_joint_pos
    gap = max(abs(pose[k] - mirror.joint_signs[k] * pose[m]) for k, m in enumerate(mirror.joints))
    assert 1e-5 < gap < 1e-4, gap  # the rounded rpy's trace, inside the map's tolerance
    folder, _, _ = write_robot("minitaur", SOURCE, tmp_path)
    with pytest.raises(UserError) as found:
        spec_robot_class(folder)().mirror()
    message = str(found.value)
    assert "the standing pose is not its own mirror image" in message and "\n" not in message
    pair = re.findall(r"'(motor_\w+)' (-?[0-9.]+)", message)
    assert abs(abs(float(pair[0][1])) - abs(float(pair[1][1]))) > 1e-3, pair
    folder, _, _ = write_robot("derpy", SOURCE.parent / "minitaur_derpy.urdf", tmp_path)
    robot = spec_robot_class(folder)()
    mirror, joints = robot.mirror(), robot._built.prepared.joints
    pairs = {joints[k]: joints[m] for k, m in enumerate(mirror.joints)}
    assert pairs["motor_front_leftL_joint"] == "motor_front_rightR_joint"  # the pinned halves
    assert pairs["motor_back_leftR_joint"] == "motor_back_rightL_joint"
    assert mirror.legs == (1, 0, 3, 2)
