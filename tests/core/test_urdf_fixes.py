"""`urdf_fixes` (issue 58): URDF forms MuJoCo refuses are read as PyBullet reads them, the
model file unchanged. PyBullet makes of each fixed text exactly the joint frames and axes it
makes of the file as it is (its microtaur: an `rpy` of four numbers; spirit40newer: a joint
with two `<axis>`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pybullet")
import pybullet
import pybullet_data
from coadapt_plugins.robots.specs.model import load_mjspec
from coadapt_plugins.robots.specs.spec import parse_spec
from coadapt_plugins.robots.specs.urdffix import fixed_xml, needed

from coadapt_core.errors import UserError

DATA = Path(pybullet_data.getDataPath())


def joint_frames(path: Path) -> np.ndarray:
    """Each joint's axis, parent frame position and orientation and its link's world pose,
    as PyBullet loads `path` (fixed base, every joint at 0)."""
    client = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(path), useFixedBase=True, physicsClientId=client)
        rows = []
        for j in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, j, physicsClientId=client)
            link = pybullet.getLinkState(
                body, j, computeForwardKinematics=1, physicsClientId=client
            )
            rows.append(np.concatenate([*info[13:16], link[4], link[5]]))
        return np.array(rows)
    finally:
        pybullet.disconnect(client)


@pytest.mark.parametrize(
    ("model", "fix", "where"),
    [
        ("quadruped/microtaur/microtaur.urdf", "rpy_three", 8),
        ("quadruped/spirit40newer.urdf", "first_axis", 1),
    ],
)
def test_a_fixed_urdf_is_what_pybullet_makes_of_the_file(model, fix, where, tmp_path):
    source = DATA / model
    before = source.read_bytes()
    found = needed(source)
    assert list(found) == [fix] and len(found[fix]) == where
    with pytest.raises(UserError, match="does not load in MuJoCo"):
        load_mjspec(source)
    text = fixed_xml(source, (fix,))
    (tmp_path / "fixed.urdf").write_text(text)
    original, fixed = joint_frames(source), joint_frames(tmp_path / "fixed.urdf")
    assert original.shape == fixed.shape and len(original) >= 12
    assert np.abs(original - fixed).max() < 1e-12
    assert load_mjspec(source, urdf_fixes=(fix,)).compile().njnt == 12
    assert source.read_bytes() == before


def test_a_urdf_fix_coadapt_does_not_make_is_refused_in_one_line(tmp_path):
    data = {"model": "m.urdf", "legs": [{"name": "a", "foot": "f", "phase": 0}]}
    data |= {"design": [{"name": "s", "bounds": [0.5, 1.5], "links": [["a", "b"]]}]}
    data |= {"standing_pose": {"joints": {}}, "gains": {}, "urdf_fixes": ["last_axis"]}
    with pytest.raises(UserError, match=r"'urdf_fixes\[0\]': 'last_axis' is not one of: "):
        parse_spec(data, tmp_path, fallback_name="probe")
