"""The generic leg IK (`coadapt_plugins.robots.specs.kinematics`): it agrees with Kuafu's and
Qilin's analytic IKs, places every robot's feet within 1 mm of reachable targets (checked by
MuJoCo's forward kinematics, not its own), and keeps a six-joint leg's sole as it stands."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import torch
from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain

from coadapt_core.plugins import get_registry

REGISTRY = get_registry()


def _generic_for(name: str, design: np.ndarray) -> tuple[object, object, LegKinematics]:
    """(robot, its model at `design`, the generic IK of that model's legs)."""
    robot = REGISTRY.create("robot", name)
    model = robot.build(design)
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    # each analytic IK measures feet from the body holding the hip-pitch joint
    hips = [
        compiled.body(compiled.jnt_bodyid[compiled.joint(j).id]).name
        for j in model.joint_names
        if j.endswith(("hip_pitch", "_hip"))
    ]
    legs = list(zip(model.foot_bodies, hips, strict=True))
    chain = build_chain(
        compiled, model.base_body, model.joint_names, legs, [], model.default_joint_pos, np.zeros(0)
    )
    return robot, model, LegKinematics(chain)


def _targets(kinematics: LegKinematics, designs: torch.Tensor, spread: float, seed: int):
    """[n, L, 3] reachable foot targets relative to the hips: the feet of the standing pose
    with every leg joint turned by up to `spread` rad (forward kinematics)."""
    g = torch.Generator().manual_seed(seed)
    standing = kinematics.chain.standing.expand(designs.shape[0], -1)
    x = kinematics.leg_angles(standing)
    x = x + spread * (2 * torch.rand(x.shape, generator=g, dtype=torch.float64) - 1)
    feet, _, _, _, _ = kinematics.forward(kinematics.scales(designs), x)
    return feet - kinematics.standing(designs)[2]


def _mujoco_feet(model, q: np.ndarray) -> np.ndarray:
    """[L, 3] foot body origins relative to the base, by MuJoCo, for joint angles q."""
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    data = mujoco.MjData(compiled)
    data.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
    for name, angle in zip(model.joint_names, q, strict=True):
        data.qpos[compiled.jnt_qposadr[compiled.joint(name).id]] = angle
    mujoco.mj_kinematics(compiled, data)
    return np.array([data.xpos[compiled.body(f).id] for f in model.foot_bodies])


@pytest.mark.parametrize(
    ("name", "design"),
    [("kuafu", [1.0, 1.0]), ("kuafu", [1.4, 0.6]), ("qilin", [1.0, 1.0]), ("qilin", [0.75, 1.25])],
)
def test_generic_ik_agrees_with_the_analytic_ik(name, design):
    robot, _, generic = _generic_for(name, np.array(design))
    n = 256
    designs = torch.tensor(design, dtype=torch.float64).expand(n, -1).clone()
    targets = _targets(generic, designs, 0.15, seed=len(name))
    analytic = robot.leg_inverse_kinematics(designs, targets)
    numeric = generic.inverse(designs, targets)
    assert float((analytic - numeric).abs().max()) < 1e-6


@pytest.mark.parametrize("name", ["kuafu", "qilin", "nezha"])
def test_generic_ik_places_feet_within_a_millimetre(name):
    robot = REGISTRY.create("robot", name)
    design = robot.nominal_design()
    _, model, generic = _generic_for(name, design) if name != "nezha" else (None, None, None)
    model = robot.build(design)
    kinematics = generic or robot._built.kinematics
    designs = torch.tensor(design, dtype=torch.float64)[None].expand(8, -1).clone()
    targets = _targets(kinematics, designs, 0.2, seed=3)
    q = kinematics.inverse(designs, targets)
    _, _, hips = kinematics.standing(designs)
    for i in range(8):
        feet = _mujoco_feet(model, q[i].numpy()) - hips[i].numpy()
        error = np.linalg.norm(feet - targets[i].numpy(), axis=1).max()
        assert error < 1e-3, f"{name}: foot {error * 1000:.3f} mm from its target"


def test_a_six_joint_leg_keeps_its_sole_as_it_stands():
    robot = REGISTRY.create("robot", "nezha")
    kinematics = robot._built.kinematics
    designs = torch.tensor([[1.2, 0.8]], dtype=torch.float64).expand(16, -1).clone()
    _, standing_rot, _ = kinematics.standing(designs)
    targets = _targets(kinematics, designs, 0.15, seed=5)
    q = robot.leg_inverse_kinematics(designs, targets)
    x = kinematics.leg_angles(q)
    _, rot, _, _, _ = kinematics.forward(kinematics.scales(designs), x)
    assert float((rot - standing_rot).abs().max()) < 1e-6


def test_the_spec_robots_ik_follows_the_design():
    """A spec robot's IK scales its chain with the design: feet land where MuJoCo's
    kinematics of that design's own model puts them."""
    robot = REGISTRY.create("robot", "nezha")
    for design in ([0.7, 1.3], [1.3, 0.7]):
        model = robot.build(np.array(design))
        designs = torch.tensor(design, dtype=torch.float64)[None]
        default = robot.default_foot_positions(designs)
        targets = default + torch.tensor([0.03, 0.01, 0.02], dtype=torch.float64)
        q = robot.leg_inverse_kinematics(designs, targets)[0].numpy()
        _, _, hips = robot._built.kinematics.standing(designs)
        feet = _mujoco_feet(model, q) - hips[0].numpy()
        assert np.abs(feet - targets[0].numpy()).max() < 1e-6
        standing = _mujoco_feet(model, model.default_joint_pos) - hips[0].numpy()
        np.testing.assert_allclose(standing, default[0].numpy(), atol=1e-9)


def test_a_design_solves_as_it_would_alone():
    """Each design stops iterating once its own legs have settled: a batch where one target is
    out of reach (every iteration) gives every design, bit for bit, what it gets alone."""
    robot = REGISTRY.create("robot", "nezha")
    kinematics = robot._built.kinematics
    g = torch.Generator().manual_seed(7)
    designs = 0.7 + 0.6 * torch.rand(12, 2, generator=g, dtype=torch.float64)
    targets = _targets(kinematics, designs, 0.2, seed=11)
    targets[4] = 1.8 * targets[4]  # out of reach: this design takes every iteration
    batch = kinematics.inverse(designs, targets)
    for i in range(designs.shape[0]):
        alone = kinematics.inverse(designs[i : i + 1], targets[i : i + 1])
        assert torch.equal(batch[i : i + 1], alone), f"design {i}"
