"""Engine-robustness randomization (issue 17): contact softness, extra joint damping and
armature scale, drawn per environment and written into each environment's MuJoCo model;
off by default without disturbing Table 2's random stream."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

from coadapt_core.errors import UserError
from coadapt_core.physics.randomization import RandomizationConfig, sample_env_params


def test_default_keeps_table_2_and_its_random_stream() -> None:
    drawn = sample_env_params(RandomizationConfig(), 64, np.random.default_rng(7))
    default = SimpleNamespace(**drawn.numpy())
    assert np.all(default.contact_timeconst == 0.02) and np.all(default.joint_damping == 0.0)
    assert np.all(default.armature == 1.0)
    # the same draws as Table 2 alone: friction, restitution, CoM shift, PD, strength, delay
    rng = np.random.default_rng(7)
    for name, shape in (
        ("friction", (64,)),
        ("restitution", (64,)),
        ("com_shift", (64, 3)),
        ("pd_factor", (64,)),
        ("motor_strength", (64,)),
        ("delay", (64,)),
    ):
        lo, hi = getattr(RandomizationConfig(), name)
        np.testing.assert_array_equal(getattr(default, name), rng.uniform(lo, hi, size=shape))
    assert drawn.privileged().shape == (64, 8)  # the critic input keeps its size


def test_presets_and_bad_ranges() -> None:
    robust = RandomizationConfig.preset("engine")
    assert robust.contact_timeconst == (0.01, 0.04) and robust.joint_damping == (0.0, 1.0)
    assert robust.armature == (0.75, 1.25) and robust.delay == (0.0, 0.025)
    assert robust.friction == RandomizationConfig().friction  # Table 2 kept
    assert not RandomizationConfig.preset("off").enabled
    with pytest.raises(UserError, match="not one of: table2, engine, off"):
        RandomizationConfig.preset("bullet")
    with pytest.raises(UserError, match="contact_timeconst"):
        RandomizationConfig(contact_timeconst=(0.0, 0.02))
    with pytest.raises(UserError, match="joint_damping"):
        RandomizationConfig(joint_damping=(-0.1, 0.5))


def test_engine_parameters_are_drawn_in_range_and_written_into_each_model(kuafu) -> None:
    rand = RandomizationConfig.engine_robust()
    designs = kuafu.design_space().sample(24, rng=3)
    with MujocoSimulator(kuafu, designs, randomization=rand, seed=5) as sim:
        sim.reset()
        params = SimpleNamespace(**sim.env_params.numpy())
        for name in ("contact_timeconst", "joint_damping", "armature"):
            lo, hi = getattr(rand, name)
            values = getattr(params, name)
            assert values.min() >= lo and values.max() <= hi, name
            assert np.ptp(values) > 0.6 * (hi - lo), name  # spread over the range
        dofs = sim._ref.dof_adr
        for env in (0, 11, 23):
            model = sim.env_model(env)
            own = mujoco.MjModel.from_xml_string(kuafu.build(sim.designs[env]).text("mjcf"))
            np.testing.assert_allclose(model.geom_solref[:, 0], params.contact_timeconst[env])
            np.testing.assert_allclose(
                model.dof_damping[dofs], own.dof_damping[dofs] + params.joint_damping[env]
            )
            np.testing.assert_allclose(
                model.dof_armature[dofs], own.dof_armature[dofs] * params.armature[env]
            )
            np.testing.assert_array_equal(
                model.dof_damping[:6], own.dof_damping[:6]
            )  # the free joint untouched
        # two environments really differ
        assert abs(params.joint_damping[0] - params.joint_damping[1]) > 1e-3


def _fixed(**overrides) -> RandomizationConfig:
    values = {k: (v, v) for k, v in RandomizationConfig.NOMINAL.items()}
    values.update({k: (v, v) for k, v in overrides.items()})
    return RandomizationConfig(**values)


def _run(
    kuafu, rand: RandomizationConfig, steps: int, fixed_base: bool = False, offset: float = 0.0
) -> tuple:
    design = np.tile(kuafu.nominal_design(), (1, 1))
    with MujocoSimulator(kuafu, design, randomization=rand, seed=0, fixed_base=fixed_base) as sim:
        state = sim.reset()
        target = state.joint_pos.clone() + offset
        heights, joints = [], []
        for _ in range(steps):
            state = sim.step(target)
            heights.append(float(state.base_pos[0, 2]))
            joints.append(state.joint_pos[0].double().numpy())
        return np.array(heights), np.array(joints)


def test_each_engine_parameter_changes_the_physics(kuafu) -> None:
    # softer contacts sink deeper under the standing robot's weight (MuJoCo's penetration
    # grows with the time constant)
    stiff, _ = _run(kuafu, _fixed(contact_timeconst=0.01), 50)
    soft, _ = _run(kuafu, _fixed(contact_timeconst=0.04), 50)
    assert stiff[-10:].mean() - soft[-10:].mean() > 0.001  # measured 1.6 mm
    # hanging legs stepped 0.3 rad: the joint paths over 3 policy steps move apart
    _, light = _run(kuafu, _fixed(armature=0.75), 3, fixed_base=True, offset=0.3)
    _, heavy = _run(kuafu, _fixed(armature=1.25), 3, fixed_base=True, offset=0.3)
    assert np.abs(light - heavy).max() > 0.005
    _, free = _run(kuafu, _fixed(joint_damping=0.0), 3, fixed_base=True, offset=0.3)
    _, damped = _run(kuafu, _fixed(joint_damping=1.0), 3, fixed_base=True, offset=0.3)
    assert np.abs(free - damped).max() > 0.001
    assert np.isfinite(np.stack([light, heavy, free, damped])).all()
    # and the mass matrix carries the scaled armature
    design = np.tile(kuafu.nominal_design(), (1, 1))
    diag = []
    for scale in (0.75, 1.25):
        with MujocoSimulator(
            kuafu, design, randomization=_fixed(armature=scale), fixed_base=True
        ) as sim:
            sim.reset()
            model = sim.env_model(0)
            data = mujoco.MjData(model)
            mujoco.mj_forward(model, data)
            full = np.zeros((model.nv, model.nv))
            mujoco.mj_fullM(model, data, full)
            diag.append(np.diag(full)[sim._ref.dof_adr])
            armature = model.dof_armature[sim._ref.dof_adr]
    np.testing.assert_allclose(diag[1] - diag[0], armature / 1.25 * 0.5, rtol=1e-9)
