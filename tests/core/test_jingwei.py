"""jingwei, the reverse-knee bird biped of issue 59's study (plugins/robots/specs/jingwei):
its spec is what `coadapt robot new` writes from its model file, unedited; it validates with
the nominal design and the four corners standing under joint PD; it has a mirror map."""

from __future__ import annotations

from pathlib import Path

import pytest
from coadapt_plugins.robots.specs.new import write_robot

from coadapt_core.plugins import get_registry

FOLDER = Path(__file__).resolve().parents[2] / "plugins" / "robots" / "specs" / "jingwei"


@pytest.fixture(scope="module")
def jingwei():
    return get_registry().create("robot", "jingwei")


@pytest.mark.slow
def test_its_spec_is_robot_news_unedited(tmp_path) -> None:
    """The keyframe stands at the nominal design but leaves a corner falling, so robot new
    solves it again at each design (`standing_pose.solve`) and every corner stands."""
    folder, notes, copied = write_robot("jingwei", FOLDER / "model.xml", tmp_path)
    assert copied == ["model.xml"]
    assert (folder / "robot.yaml").read_text() == (FOLDER / "robot.yaml").read_text()
    assert any(
        n.startswith("keyframe 'stand' solved at each design (solve: 0.9087)") for n in notes
    )


def test_it_validates_and_every_corner_stands(jingwei) -> None:
    report = jingwei.validate(jingwei.nominal_design())
    assert report.feasible, report.reasons
    stand = next(f for f in report.findings if f.check == "stand.hold")
    assert stand.ok and stand.message.startswith("the nominal design and 4 corners stand")
    model = jingwei.build(jingwei.nominal_design())
    assert model.num_joints == 8 and abs(model.total_mass - 14.5) < 1e-6
    # the knee bends backwards: thigh down and back (hip pitch > 0), shin down and forward
    knees = [
        model.default_joint_pos[model.joint_names.index(f"{s}_knee")] for s in ("left", "right")
    ]
    assert all(k < -1.0 for k in knees)


def test_its_mirror_map_flips_the_hip_roll_only(jingwei) -> None:
    mirror = jingwei.mirror()
    assert mirror.joints == (4, 5, 6, 7, 0, 1, 2, 3) and mirror.legs == (1, 0)
    # hip roll, hip pitch, knee, ankle: only the roll joint changes sign
    assert mirror.joint_signs == (-1, 1, 1, 1) * 2


def test_no_design_of_it_needs_the_level_search(jingwei) -> None:
    """Its pose solved per design is the leg IK's answer at 0.9087 of the leg's length at
    every design (each joint inside its range, the soles level): the search that a design
    clipping a joint gets (`level.level_targets`) leaves jingwei's standing poses as they
    were, bit for bit."""
    import numpy as np
    import torch

    space = jingwei.design_space()
    corners = np.array([[x, y] for x in (space.lower[0], space.upper[0])
                        for y in (space.lower[1], space.upper[1])])  # fmt: skip
    designs = torch.as_tensor(np.vstack([space.sample(64, rng=3), corners]), dtype=torch.float64)
    built = jingwei._built
    assert torch.equal(built.stand_targets(designs), built.stand_targets(designs, level=False))
