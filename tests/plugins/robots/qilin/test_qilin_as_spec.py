"""Qilin expressed as a robot spec over the MJCF its generator writes at the nominal design,
compared with the generator's models at the nominal design and the four corners (and with
motor types): what agrees within 1e-9 and the two named differences (docs/your-robot.md)."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch
from coadapt_plugins.robots.qilin.robot import Qilin
from coadapt_plugins.robots.specs.robot import spec_robot_class

HERE = Path(__file__).resolve().parent
DESIGNS = [[1.0, 1.0], [0.7, 0.7], [0.7, 1.3], [1.3, 0.7], [1.3, 1.3], [1.3, 0.7, 2, 1]]


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("qilin") / "qilin-spec"
    shutil.copytree(HERE / "spec", folder)
    generator = Qilin()
    (folder / "model.xml").write_text(generator.build(generator.nominal_design()).text("mjcf"))
    return generator, spec_robot_class(folder)()


@pytest.mark.parametrize("design", DESIGNS)
def test_the_spec_builds_the_generators_model(pair, design):
    generator, spec = pair
    a, b = generator.build(np.array(design)), spec.build(np.array(design))
    ma = mujoco.MjModel.from_xml_string(a.text("mjcf"))
    mb = mujoco.MjModel.from_xml_string(b.text("mjcf"))
    ids = [mb.body(ma.body(i).name).id for i in range(ma.nbody)]  # same bodies, by name
    assert np.abs(ma.body_pos - mb.body_pos[ids]).max() < 1e-9
    assert np.abs(ma.body_mass - mb.body_mass[ids]).max() < 1e-9
    assert np.abs(ma.body_ipos - mb.body_ipos[ids]).max() < 1e-9
    assert abs(a.total_mass - b.total_mass) < 1e-9
    joints = [mb.joint(ma.joint(j).name).id for j in range(ma.njnt)]
    assert np.abs(ma.jnt_axis - mb.jnt_axis[joints]).max() < 1e-12
    assert np.abs(ma.jnt_range - mb.jnt_range[joints]).max() < 1e-12
    assert a.joint_names == b.joint_names and a.foot_bodies == b.foot_bodies
    for name in ("torque_limit", "speed_limit", "kp", "kd", "joint_lower", "joint_upper"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-12, atol=1e-12)
    assert abs(a.standing_base_height - b.standing_base_height) < 1e-9
    np.testing.assert_allclose(b.foot_contact_points, a.foot_contact_points, atol=1e-12)
    # named difference 1: the inertias, the thigh's motor treated as a point mass (the
    # generator's is a 0.6 kg cylinder); nothing but the thighs differs
    gap = np.abs(ma.body_inertia - mb.body_inertia[ids]).max(axis=1)
    thighs = [ma.body(f"{leg}_thigh").id for leg in ("FL", "FR", "RL", "RR")]
    assert np.all(np.delete(gap, thighs) < 1e-9)
    if design[0] == 1.0:  # an unscaled thigh is the generator's own
        assert gap[thighs].max() < 1e-9
    else:
        assert 1e-5 < gap[thighs].max() < 7.2e-4
    # named difference 2: the standing pose, fixed angles against the generator's solved
    # pose; equal where thigh and calf scale alike
    pose_gap = np.abs(a.default_joint_pos - b.default_joint_pos).max()
    if design[0] == design[1]:
        assert pose_gap < 1e-9
    else:
        assert 0.3 < pose_gap < 0.5


def test_the_spec_ik_equals_qilins_analytic_ik(pair):
    generator, spec = pair
    designs = torch.tensor([[1.0, 1.0], [0.7, 0.7], [1.3, 1.3]], dtype=torch.float64)
    offsets = torch.tensor([0.04, -0.02, 0.03], dtype=torch.float64)
    feet = generator.default_foot_positions(designs) + offsets
    assert (
        float(
            (spec.default_foot_positions(designs) - generator.default_foot_positions(designs))
            .abs()
            .max()
        )
        < 1e-12
    )
    q = spec.leg_inverse_kinematics(designs, feet)
    assert float((q - generator.leg_inverse_kinematics(designs, feet)).abs().max()) < 1e-6
