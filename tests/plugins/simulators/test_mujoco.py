"""The MuJoCo backend: conformance suite, terrains, motor limits, contact and foot-position
readings (randomization, resets, re-design and divergence: test_mujoco_rows.py)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import torch
from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

from coadapt_core.errors import DesignError, UserError
from coadapt_core.physics.actuation import pd_torque
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import FIXED_BASE_LIFT, SPAWN_CLEARANCE
from coadapt_core.physics.terrain import SLOPE_DEGREES, make_terrain
from tests.plugins.simulators.mujoco_helpers import batch_designs, fixed_randomization

G = 9.81


# -- helpers ------------------------------------------------------------------------------
def _sole_corners(sim: MujocoSimulator, env: int) -> np.ndarray:
    """[L, 4, 3] world positions of each foot's sole corners at env's current state."""
    model = sim.env_model(env)
    data = sim._live().get_data(int(sim.rows(env)))
    mujoco.mj_kinematics(model, data)
    points = sim._ref.robot_model.foot_contact_points  # [4, 3] in the foot frame
    return np.stack(
        [data.xpos[b] + points @ data.xmat[b].reshape(3, 3).T for b in sim._ref.foot_body_ids]
    )


def _ray_heights(sim: MujocoSimulator, env: int, xy: np.ndarray) -> np.ndarray:
    """Ground height at points xy [k, 2], by rays cast down onto env's world with the robot
    lifted far out of the way."""
    model = sim.env_model(env)
    data = mujoco.MjData(model)
    data.qpos[2] = 100.0
    mujoco.mj_forward(model, data)
    geomid = np.zeros(1, dtype=np.int32)
    down = np.array([0.0, 0.0, -1.0])
    return np.array(
        [
            5.0 - mujoco.mj_ray(model, data, np.array([x, y, 5.0]), down, None, 1, -1, geomid)
            for x, y in xy
        ]
    )


# -- registration and input checks --------------------------------------------------------
def test_registered_as_mujoco_through_the_entry_point() -> None:
    from coadapt_core.plugins import load_registry

    info = load_registry().entries["simulator"]["mujoco"]
    assert info.cls is MujocoSimulator
    assert info.entry_point == "coadapt.simulators.mujoco"


def test_bad_arguments_are_one_line_user_errors(kuafu) -> None:
    designs = batch_designs(kuafu, 2)
    with pytest.raises(UserError, match="terrain"):
        MujocoSimulator(kuafu, designs, terrain="mars")
    with pytest.raises(UserError, match="decimation"):
        MujocoSimulator(kuafu, designs, decimation=0)
    with MujocoSimulator(kuafu, designs) as sim:
        with pytest.raises(DesignError, match="thigh_scale"):
            sim.set_designs(np.array([0]), np.array([[3.0, 1.0]]))
        with pytest.raises(UserError, match="env_ids"):
            sim.reset(np.array([5]))
    with pytest.raises(RuntimeError, match="closed"):
        sim.step(sim.default_joint_pos)


# -- terrains -----------------------------------------------------------------------------
def test_slope_ground_is_ten_degrees_rising_along_x(kuafu) -> None:
    with MujocoSimulator(kuafu, batch_designs(kuafu, 1), terrain="slope") as sim:
        xy = np.array([[-3.0, 0.5], [0.0, -2.0], [2.0, 1.0], [4.0, 0.0]])
        heights = _ray_heights(sim, 0, xy)
        np.testing.assert_allclose(
            heights, xy[:, 0] * math.tan(math.radians(SLOPE_DEGREES)), atol=1e-6
        )
        terrain = make_terrain("slope")
        np.testing.assert_allclose(heights, terrain.height_at(xy), atol=1e-6)


def test_random_terrain_is_the_shared_height_grid(kuafu) -> None:
    with MujocoSimulator(kuafu, batch_designs(kuafu, 1), terrain="random", seed=3) as sim:
        terrain = make_terrain("random", seed=3)
        grid = terrain.height_grid()
        rng = np.random.default_rng(0)
        rows, cols = rng.integers(5, terrain.samples - 5, size=(2, 40))
        vertices = np.column_stack([cols, rows]) * terrain.resolution - terrain.size / 2
        # at grid vertices MuJoCo's height field is exactly the grid (row along y)
        np.testing.assert_allclose(
            _ray_heights(sim, 0, vertices + 1e-7), grid[rows, cols], atol=2e-5
        )
        # between vertices MuJoCo triangulates each cell, `height_at` interpolates bilinearly:
        # they differ by at most a quarter of the cell's twist, 2.5 cm for 5 cm noise
        points = rng.uniform(-8, 8, size=(400, 2))
        gap = np.abs(_ray_heights(sim, 0, points) - terrain.height_at(points))
        assert gap.max() <= 0.025 + 1e-6
        assert np.median(gap) < 0.005


@pytest.mark.parametrize("terrain", ["flat", "slope", "random"])
def test_spawn_puts_soles_just_above_the_highest_ground(kuafu, terrain) -> None:
    with MujocoSimulator(
        kuafu, batch_designs(kuafu, 16, mixed=True), terrain=terrain, seed=1
    ) as sim:
        state = sim.reset()
        ground = make_terrain(terrain, seed=1)
        u, v = np.meshgrid(np.linspace(0, 1, 23), np.linspace(0, 1, 11))
        for env in range(sim.num_envs):
            c = _sole_corners(sim, env)  # [L, 4, 3] toe-left, toe-right, heel-left, heel-right
            soles = (
                c[:, None, None, 2]
                + u[..., None] * (c[:, None, None, 0] - c[:, None, None, 2])
                + v[..., None] * (c[:, None, None, 3] - c[:, None, None, 2])
            )  # [L, 11, 23, 3] points over each sole
            clearance = soles[..., 2] - ground.height_at(soles[..., :2])
            assert clearance.min() >= SPAWN_CLEARANCE - 1e-6, (terrain, env, clearance)
            # never far above: the highest ground within the sole's reach sets the height
            assert clearance.min() <= SPAWN_CLEARANCE + (0.05 if terrain == "random" else 0.04)
        np.testing.assert_allclose(
            state.terrain_height.numpy(), ground.height_at(state.base_pos[:, :2].numpy()), atol=1e-5
        )


def test_soles_rest_on_random_terrain_within_a_centimetre(kuafu) -> None:
    """After settling, a foot in contact touches `Terrain.height_at`: over its sole, the
    smallest gap between sole and ground is zero within a centimetre."""
    with MujocoSimulator(kuafu, batch_designs(kuafu, 6), terrain="random", seed=2) as sim:
        sim.reset()
        for _ in range(25):
            state = sim.step(sim.default_joint_pos)
        ground = make_terrain("random", seed=2)
        u, v = np.meshgrid(np.linspace(0, 1, 12), np.linspace(0, 1, 6))
        checked = 0
        for env in range(sim.num_envs):
            corners = _sole_corners(sim, env)
            for foot in range(2):
                if not bool(state.foot_contact[env, foot]):
                    continue
                c = corners[foot]  # toe-left, toe-right, heel-left, heel-right
                pts = c[2] + u[..., None] * (c[0] - c[2]) + v[..., None] * (c[3] - c[2])  # the sole
                gap = (pts[..., 2] - ground.height_at(pts[..., :2])).min()
                assert abs(gap) < 0.01, (env, foot, gap)
                checked += 1
        assert checked >= 6


def test_fixed_base_hangs_in_the_air_without_contacts(kuafu) -> None:
    with MujocoSimulator(kuafu, batch_designs(kuafu, 2), fixed_base=True) as sim:
        start = sim.reset()
        heights = np.array([kuafu.build(d).standing_base_height for d in sim.designs])
        np.testing.assert_allclose(
            start.base_pos[:, 2].numpy(), heights + SPAWN_CLEARANCE + FIXED_BASE_LIFT, atol=1e-5
        )
        for _ in range(25):
            state = sim.step(sim.default_joint_pos + 0.4)
        assert torch.equal(state.base_pos, start.base_pos)
        assert not bool(state.foot_contact.any())
        assert float(state.joint_vel.abs().max()) > 0.01  # the legs did swing


# -- state readings -----------------------------------------------------------------------
@pytest.mark.parametrize(
    "randomization", [RandomizationConfig.off(), RandomizationConfig()], ids=["off", "table2"]
)
def test_standing_contact_force_carries_the_weight(kuafu, randomization) -> None:
    """Standing still, the feet's normal forces sum to the weight (also with Table 2
    randomization: a bouncier contact must still come to rest, not ring)."""
    with MujocoSimulator(kuafu, batch_designs(kuafu, 4), randomization=randomization) as sim:
        sim.reset()
        for _ in range(50):
            state = sim.step(sim.default_joint_pos)
        weights = np.array([kuafu.build(d).total_mass for d in sim.designs]) * G
        assert bool(state.foot_contact.all())
        np.testing.assert_allclose(state.foot_contact_force.sum(dim=1).numpy(), weights, rtol=0.05)


@pytest.mark.parametrize("fixed_base", [True, False])
def test_foot_positions_are_current_not_one_physics_step_old(kuafu, fixed_base) -> None:
    """Fast swings (fixed base) and falls with ground impacts (free base): foot_pos matches
    the kinematics of the state handed out within 3 mm (a foot moves up to 5 cm per step;
    xpos alone lags by up to 1 cm)."""
    with MujocoSimulator(kuafu, batch_designs(kuafu, 3), fixed_base=fixed_base) as sim:
        sim.reset()
        worst = 0.0
        for k in range(20):
            state = sim.step(sim.default_joint_pos + (0.6 if k % 10 < 5 else -0.6))
            for env in range(sim.num_envs):
                data = sim._live().get_data(int(sim.rows(env)))
                mujoco.mj_kinematics(sim.env_model(env), data)
                exact = data.xpos[sim._ref.foot_body_ids]
                worst = max(worst, float(np.abs(state.foot_pos[env].numpy() - exact).max()))
        print(f"foot_pos error: {worst * 1e3:.2f} mm")
        assert worst < 3e-3, worst


def test_base_angular_velocity_is_in_the_world_frame(kuafu) -> None:
    with MujocoSimulator(kuafu, batch_designs(kuafu, 1)) as sim:
        sim.reset()
        qpos, qvel = sim._qpos, sim._qvel  # one environment: row 0
        qpos[0, 3:7] = [
            math.cos(0.25 * math.pi),
            0.0,
            0.0,
            math.sin(0.25 * math.pi),
        ]  # yaw 90 degrees
        qvel[0, 3:6] = [1.0, 0.0, 0.0]  # roll rate about the body x axis = world y
        state = sim._build_state()
        np.testing.assert_allclose(state.base_ang_vel[0].numpy(), [0.0, 1.0, 0.0], atol=1e-6)


# -- actuation ----------------------------------------------------------------------------
def test_applied_torque_follows_the_shared_actuation_law(kuafu) -> None:
    """One physics step from rest: joint_torque equals coadapt_core.physics.actuation with each
    environment's own PD factor and motor strength."""
    rand = RandomizationConfig(
        friction=(1.0, 1.0), restitution=(0.0, 0.0), com_shift=(0.0, 0.0), delay=(0.0, 0.0)
    )
    with MujocoSimulator(
        kuafu,
        batch_designs(kuafu, 8, mixed=True),
        randomization=rand,
        decimation=1,
        fixed_base=True,
    ) as sim:
        sim.reset()
        params = sim.env_params
        assert (
            float(params.pd_factor.max() - params.pd_factor.min()) > 0.05
            and float(params.motor_strength.max() - params.motor_strength.min()) > 0.05
        )
        q0 = sim.default_joint_pos.double().numpy()
        offsets = np.linspace(-0.3, 0.3, 8)[None, :].repeat(sim.num_envs, 0)
        state = sim.step(torch.as_tensor(q0 + offsets))
        models = [kuafu.build(d) for d in sim.designs]
        kp, kd = np.stack([m.kp for m in models]), np.stack([m.kd for m in models])
        tmax, vmax = (
            np.stack([m.torque_limit for m in models]),
            np.stack([m.speed_limit for m in models]),
        )
        gains = (q0 + offsets, q0, np.zeros_like(q0), kp, kd, tmax, vmax)
        expected = pd_torque(
            *(torch.tensor(a, dtype=torch.float64) for a in gains),
            params.pd_factor,
            params.motor_strength,
        )
        np.testing.assert_allclose(
            state.joint_torque.double().numpy(), expected.numpy(), rtol=1e-5, atol=1e-3
        )


def test_delay_holds_the_previous_target_for_whole_physics_steps(kuafu) -> None:
    with MujocoSimulator(
        kuafu,
        batch_designs(kuafu, 1),
        randomization=fixed_randomization(delay=0.010),
        decimation=1,
        fixed_base=True,
    ) as sim:
        sim.reset()
        assert sim._delay.delay_steps.tolist() == [2]  # one environment
        moved = sim.default_joint_pos + 0.5
        torques = [float(sim.step(moved).joint_torque[0, 1].abs()) for _ in range(4)]
        # 10 ms = 2 physics steps: two steps still hold the reset pose (tiny torque),
        # then full effort
        assert torques[0] < 5.0 and torques[1] < 5.0
        assert torques[2] > 100.0


@pytest.mark.parametrize("offset", [3.0, -3.0])
@pytest.mark.parametrize("fixed_base", [True, False])
def test_far_target_respects_torque_limit_and_speed_limit_margin(kuafu, fixed_base, offset) -> None:
    """Targets 3 rad beyond the pose for 1 s: never more than the motor's peak torque, and
    joint speed above no-load speed dq_max only by the stated margin.

    The envelope stops the motor pushing beyond dq_max, but (1) it is sampled once per
    physics step: a step that starts just below dq_max at full torque ends above it by up
    to 1.1 tau_max dt / M_jj (M_jj the joint's own inertia with rotor armature: 24 rad/s
    for the light ankle, 2.6 rad/s for the knee); (2) beyond dq_max the motor is free, not
    braking, so gravity, the other joints' motion and joint-limit impacts speed it up
    further (measured up to 0.44 dq_max here). Margin: (1) + 0.5 dq_max."""
    rand = fixed_randomization(pd_factor=1.1, motor_strength=1.1)
    designs = batch_designs(kuafu, 12)
    with MujocoSimulator(kuafu, designs, randomization=rand, fixed_base=fixed_base) as sim:
        sim.reset()
        models = [kuafu.build(d) for d in designs]
        tmax = torch.as_tensor(np.stack([m.torque_limit for m in models]))
        vmax = torch.as_tensor(np.stack([m.speed_limit for m in models]))
        inertia = torch.as_tensor(
            np.stack([sim.env_model(e).dof_M0[sim._ref.dof_adr] for e in range(sim.num_envs)])
        )
        margin = 1.1 * tmax * sim.physics_dt / inertia + 0.5 * vmax
        fastest = 0.0
        for _ in range(50):
            state = sim.step(sim.default_joint_pos + offset)
            assert torch.all(state.joint_torque.abs().double() <= tmax * (1 + 1e-6))
            excess = state.joint_vel.abs().double() - vmax
            assert torch.all(excess <= margin), float((excess - margin).max())
            fastest = max(fastest, float((state.joint_vel.abs().double() / vmax).max()))
        assert fastest > 0.9  # the test reached the limit it is about
