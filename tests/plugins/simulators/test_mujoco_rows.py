"""The MuJoCo backend's batch rows: randomization written into the model per environment,
subset reset and re-design, divergence recovery, the row shuffle, closing the batch and the
model cache."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
import torch
from coadapt_plugins.robots.kuafu.robot import Kuafu
from coadapt_plugins.simulators.mujoco.row_reset import restitution_to_dampratio
from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import SPAWN_CLEARANCE
from tests.plugins.simulators.mujoco_helpers import batch_designs


# -- randomization --------------------------------------------------------------------------
def test_randomization_draws_every_range_per_environment_in_the_model(kuafu) -> None:
    rand = RandomizationConfig()
    with MujocoSimulator(kuafu, batch_designs(kuafu, 48), randomization=rand, seed=4) as sim:
        draws = []
        for _ in range(2):
            sim.reset()
            draws.append(SimpleNamespace(**sim.env_params.numpy()))
        base = sim._ref.base_body_id
        for name in ("friction", "restitution", "pd_factor", "motor_strength", "delay"):
            lo, hi = getattr(rand, name)
            values = np.concatenate([getattr(p, name) for p in draws])
            assert values.min() >= lo and values.max() <= hi, name
            assert np.ptp(values) > 0.6 * (hi - lo), name  # spread over the range
        shifts = np.concatenate([p.com_shift for p in draws])
        assert (
            shifts.min() >= -0.025 and shifts.max() <= 0.025 and np.ptp(shifts, axis=0).min() > 0.03
        )
        params = draws[-1]
        for env in (0, 17, 47):
            model = sim.env_model(env)
            nominal = kuafu.build(sim.designs[env])
            # every geom carries the env's sliding friction (a contact takes the max of its pair)
            np.testing.assert_allclose(model.geom_friction[:, 0], params.friction[env])
            np.testing.assert_allclose(
                model.geom_solref[:, 1],
                restitution_to_dampratio(params.restitution[env : env + 1])[0],
            )
            compiled = mujoco.MjModel.from_xml_string(nominal.text("mjcf"))
            np.testing.assert_allclose(
                model.body_ipos[base] - compiled.body_ipos[base], params.com_shift[env], atol=1e-12
            )
            assert sim._delay.delay_steps[sim.rows(env)] == round(
                params.delay[env] / sim.physics_dt
            )


def test_randomization_off_means_nominal_everywhere(kuafu) -> None:
    with MujocoSimulator(
        kuafu, batch_designs(kuafu, 4), randomization=RandomizationConfig.off()
    ) as sim:
        sim.reset()
        params = SimpleNamespace(**sim.env_params.numpy())
        assert np.all(params.friction == 1.0) and np.all(params.pd_factor == 1.0)
        assert np.all(params.motor_strength == 1.0) and np.all(params.com_shift == 0.0)
        assert bool((sim._delay.delay_steps == 0).all())
        model = sim.env_model(2)
        compiled = mujoco.MjModel.from_xml_string(kuafu.build(sim.designs[2]).text("mjcf"))
        base = sim._ref.base_body_id
        np.testing.assert_allclose(model.body_ipos[base], compiled.body_ipos[base])
        np.testing.assert_allclose(model.geom_solref[:, 1], 1.0)


def _drop_rebound(dampratio: float, speed: float = 1.0) -> float:
    """Rebound speed ratio of a 40 kg box hitting the ground at `speed` (5 ms steps)."""
    xml = f"""<mujoco><option timestep="0.005"/><worldbody>
      <geom type="plane" size="0 0 1" solref="0.02 {dampratio}"/>
      <body pos="0 0 0.101"><freejoint/>
        <geom type="box" size="0.1 0.05 0.1" mass="40" solref="0.02 {dampratio}"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[2] = -speed
    rebound = 0.0
    for _ in range(60):
        mujoco.mj_step(model, data)
        rebound = max(rebound, data.qvel[2])
    return rebound / speed


def test_restitution_maps_to_a_contact_damping_with_that_measured_bounce() -> None:
    """Table 2 restitution becomes the contact damping ratio whose drop-test bounce it is,
    within MuJoCo's reachable [0.14, 0.33]; nominal 0 keeps MuJoCo's default 1.0."""
    assert restitution_to_dampratio(np.array([0.0]))[0] == 1.0
    for e in (0.15, 0.2, 0.25, 0.3):
        zeta = float(restitution_to_dampratio(np.array([e]))[0])
        assert 0.5 <= zeta < 1.0
        assert abs(_drop_rebound(zeta) - e) < 0.01, (e, zeta)
    # beyond the reachable bounce the damping ratio stays at 0.5: lower rings forever
    assert restitution_to_dampratio(np.array([0.4]))[0] == 0.5
    assert abs(_drop_rebound(0.5) - 0.328) < 0.005


# -- subset reset, re-design ----------------------------------------------------------------
def test_subset_reset_redraws_only_those_environments(kuafu) -> None:
    with MujocoSimulator(
        kuafu, batch_designs(kuafu, 4), randomization=RandomizationConfig()
    ) as sim:
        sim.reset()
        for _ in range(5):
            sim.step(sim.default_joint_pos + 0.1)
        before = sim.env_params
        qvel_before = sim._qvel[sim.rows(np.arange(4))]  # [4, nv] environment order
        sim.reset(torch.tensor([False, True, False, True]))
        after = sim.env_params
        for env in (0, 2):
            assert after.friction[env] == before.friction[env]
            np.testing.assert_array_equal(sim._qvel[sim.rows(env)], qvel_before[env])
        for env in (1, 3):
            assert after.friction[env] != before.friction[env]
            assert np.all(sim._qvel[sim.rows(env)] == 0.0)


def test_set_designs_rebuilds_only_the_given_environments(kuafu) -> None:
    designs = np.array([[1.0, 1.0], [1.0, 1.0], [1.0, 1.0]])
    with MujocoSimulator(kuafu, designs) as sim, MujocoSimulator(kuafu, designs) as twin:
        sim.reset()
        twin.reset()
        for _ in range(3):
            sim.step(sim.default_joint_pos)
            twin.step(twin.default_joint_pos)
        sim.set_designs(np.array([1]), np.array([[1.4, 0.6]]))
        np.testing.assert_allclose(sim.designs[1], [1.4, 0.6])
        new = kuafu.build(np.array([1.4, 0.6]))
        np.testing.assert_allclose(
            sim.default_joint_pos[1].numpy(), new.default_joint_pos, atol=1e-6
        )
        assert (
            abs(
                float(sim.get_state().base_pos[1, 2]) - (new.standing_base_height + SPAWN_CLEARANCE)
            )
            < 1e-6
        )
        thigh = mujoco.mj_name2id(sim._ref.model, mujoco.mjtObj.mjOBJ_BODY, "left_shank")
        assert not np.allclose(sim.env_model(1).body_pos[thigh], sim.env_model(0).body_pos[thigh])
        for _ in range(3):
            a = sim.step(sim.default_joint_pos)
            b = twin.step(twin.default_joint_pos)
        # environments 0 and 2 ran on exactly as if nothing had happened
        assert torch.equal(a.joint_pos[[0, 2]], b.joint_pos[[0, 2]])
        assert torch.equal(a.base_pos[[0, 2]], b.base_pos[[0, 2]])


# -- divergence -------------------------------------------------------------------------------
def test_nan_and_runaway_speeds_reset_that_environment_only(kuafu) -> None:
    with MujocoSimulator(kuafu, batch_designs(kuafu, 4)) as sim:
        sim.reset()
        for _ in range(3):
            sim.step(sim.default_joint_pos)
        sim._qvel[sim.rows(1), 7] = np.nan  # through the live bound array: a blown-up state
        sim._qvel[sim.rows(3), 0] = 5e4  # beyond MAX_QVEL but below MuJoCo's own 1e10 check
        state = sim.step(sim.default_joint_pos)
        assert state.diverged.tolist() == [False, True, False, True]
        for name in (
            "base_pos",
            "joint_pos",
            "joint_vel",
            "joint_torque",
            "foot_pos",
            "foot_contact_force",
        ):
            assert torch.isfinite(getattr(state, name)).all(), name
        assert (
            float(state.base_pos[1, 2]) > 0.5 and float(state.base_pos[3, 2]) > 0.5
        )  # respawned standing
        assert sim.divergence_count == 2
        state = sim.step(sim.default_joint_pos)
        assert not bool(state.diverged.any())  # the flag describes the last step only


def test_mujoco_self_reset_is_detected_as_divergence(kuafu) -> None:
    """MuJoCo resets a simulation itself on a bad state (here a non-finite position):
    the backend notices the restarted clock and respawns it properly."""
    with MujocoSimulator(kuafu, batch_designs(kuafu, 2)) as sim:
        sim.reset()
        sim._qpos[sim.rows(0), 2] = np.inf
        state = sim.step(sim.default_joint_pos)
        assert state.diverged.tolist() == [True, False]
        assert (
            abs(float(state.base_pos[0, 2]) - float(sim.reset(np.array([0])).base_pos[0, 2])) < 0.05
        )


def test_device_and_dtype(kuafu) -> None:
    with MujocoSimulator(kuafu, batch_designs(kuafu, 2), device="cpu") as sim:
        state = sim.reset()
        assert state.joint_pos.dtype == torch.float32 and state.joint_pos.device.type == "cpu"
        assert state.foot_contact.dtype == torch.bool and state.diverged.dtype == torch.bool
        assert sim.control_dt == pytest.approx(0.02)


def test_same_seed_draws_the_same_parameters_as_the_core_sampler(kuafu) -> None:
    """Construction consumes no randomness: the first reset's parameters are the first draw
    of default_rng(seed), as on every backend."""
    from coadapt_core.physics.randomization import sample_env_params

    rand = RandomizationConfig()
    with MujocoSimulator(kuafu, batch_designs(kuafu, 5), randomization=rand, seed=9) as sim:
        sim.reset()
        expected = sample_env_params(rand, 5, np.random.default_rng(9))
        np.testing.assert_array_equal(sim.env_params.friction, expected.friction)
        np.testing.assert_array_equal(sim.env_params.com_shift, expected.com_shift)
        sim.reset(np.array([1, 3]))
        rng = np.random.default_rng(9)  # the second draw continues the same stream
        sample_env_params(rand, 5, rng)
        second = sample_env_params(rand, 2, rng)
        np.testing.assert_array_equal(sim.env_params.delay[[1, 3]], second.delay)


def test_environments_are_spread_over_the_batch_rows(kuafu) -> None:
    """mujoco.batch gives each thread a contiguous block of rows; the environments of one
    design must not all land in one block. Environment order is restored in the state."""
    designs = np.repeat(batch_designs(kuafu, 2), 8, axis=0)  # 2 designs x 8 agents
    with MujocoSimulator(kuafu, designs, num_threads=2) as sim:
        rows = sim.rows(np.arange(16))
        assert sorted(rows.tolist()) == list(range(16))
        first_design_rows = rows[:8]
        assert 2 <= int((first_design_rows < 8).sum()) <= 6
        state = sim.reset()
        heights = np.array([kuafu.build(d).standing_base_height for d in designs])
        np.testing.assert_allclose(
            state.base_pos[:, 2].numpy(), heights + SPAWN_CLEARANCE, atol=1e-6
        )
        np.testing.assert_allclose(
            sim.default_joint_pos.numpy(),
            np.stack([kuafu.build(d).default_joint_pos for d in designs]),
            atol=1e-6,
        )


def test_close_joins_the_batch_threads(kuafu) -> None:
    import os

    def threads() -> set[str]:
        return set(os.listdir("/proc/self/task"))

    if not os.path.isdir("/proc/self/task"):
        pytest.skip("needs Linux /proc to count threads")
    # A first batch lets every lazily started pool (torch's, OpenMP's) exist before counting,
    # so the threads that appear below are the batch's own.
    warm = MujocoSimulator(kuafu, batch_designs(kuafu, 4), num_threads=3)
    warm.step(warm.default_joint_pos)
    warm.close()
    before = threads()
    sim = MujocoSimulator(kuafu, batch_designs(kuafu, 4), num_threads=3)
    sim.step(sim.default_joint_pos)
    started = threads() - before
    assert len(started) >= 2  # two workers beside the caller's thread
    sim.close()
    # Compared by thread id, so a thread some other library starts meanwhile does not count.
    assert not (threads() & started)


def test_a_robot_subclass_named_like_its_parent_gets_its_own_compiled_models():
    """The compiled-model cache is keyed by the robot's class too: a variant named like its
    parent (here with 2 % of its PD gains, a planted fault a conformance suite must see)
    is compiled from its own build, before and after the parent's."""
    import dataclasses

    class Weak(Kuafu):
        def build(self, design):
            model = super().build(design)
            return dataclasses.replace(model, kp=model.kp * 0.02, kd=model.kd * 0.02)

    design = Kuafu().nominal_design()[None]
    kp = {}
    for robot in (Kuafu(), Weak(), Kuafu()):
        with MujocoSimulator(robot, design, randomization=RandomizationConfig.off()) as sim:
            kp.setdefault(type(robot).__name__, []).append(
                float(sim._compile(design[0]).robot_model.kp[0])
            )
    assert kp["Weak"][0] == pytest.approx(0.02 * kp["Kuafu"][0])
    assert kp["Kuafu"][0] == kp["Kuafu"][1]
