"""The MuJoCo backend: conformance suite, terrains, randomization, subset reset and
re-design, divergence recovery, motor limits, contact and foot-position readings."""

from __future__ import annotations

import math
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
import torch
from coadapt_plugins.robots.kuafu.robot import Kuafu
from coadapt_plugins.simulators.mujoco.row_reset import restitution_to_dampratio
from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

from coadapt_core.errors import DesignError, UserError
from coadapt_core.physics.actuation import pd_torque
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import FIXED_BASE_LIFT, SPAWN_CLEARANCE
from coadapt_core.physics.terrain import SLOPE_DEGREES, make_terrain
from coadapt_core.testing import SimulatorConformance

G = 9.81


class TestMujocoConformance(SimulatorConformance):
    @pytest.fixture
    def robot(self, kuafu):
        return kuafu

    @pytest.fixture
    def simulator_cls(self):
        return MujocoSimulator


# -- helpers ------------------------------------------------------------------------------
def _designs(robot: Kuafu, n: int, seed: int = 0, mixed: bool = False) -> np.ndarray:
    designs = robot.design_space(mixed).sample(n, rng=seed)
    designs[0] = robot.nominal_design(mixed)
    return designs


def _fixed(**overrides) -> RandomizationConfig:
    """Randomization with every range a point (nominal unless overridden)."""
    values = {k: (v, v) for k, v in RandomizationConfig.NOMINAL.items()}
    values.update({k: (v, v) for k, v in overrides.items()})
    return RandomizationConfig(**values)


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
    designs = _designs(kuafu, 2)
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
    with MujocoSimulator(kuafu, _designs(kuafu, 1), terrain="slope") as sim:
        xy = np.array([[-3.0, 0.5], [0.0, -2.0], [2.0, 1.0], [4.0, 0.0]])
        heights = _ray_heights(sim, 0, xy)
        np.testing.assert_allclose(
            heights, xy[:, 0] * math.tan(math.radians(SLOPE_DEGREES)), atol=1e-6
        )
        terrain = make_terrain("slope")
        np.testing.assert_allclose(heights, terrain.height_at(xy), atol=1e-6)


def test_random_terrain_is_the_shared_height_grid(kuafu) -> None:
    with MujocoSimulator(kuafu, _designs(kuafu, 1), terrain="random", seed=3) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 16, mixed=True), terrain=terrain, seed=1) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 6), terrain="random", seed=2) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 2), fixed_base=True) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 4), randomization=randomization) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 3), fixed_base=fixed_base) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 1)) as sim:
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
        kuafu, _designs(kuafu, 8, mixed=True), randomization=rand, decimation=1, fixed_base=True
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
        kuafu, _designs(kuafu, 1), randomization=_fixed(delay=0.010), decimation=1, fixed_base=True
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
    rand = _fixed(pd_factor=1.1, motor_strength=1.1)
    designs = _designs(kuafu, 12)
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


# -- randomization --------------------------------------------------------------------------
def test_randomization_draws_every_range_per_environment_in_the_model(kuafu) -> None:
    rand = RandomizationConfig()
    with MujocoSimulator(kuafu, _designs(kuafu, 48), randomization=rand, seed=4) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 4), randomization=RandomizationConfig.off()) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 4), randomization=RandomizationConfig()) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 4)) as sim:
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
    with MujocoSimulator(kuafu, _designs(kuafu, 2)) as sim:
        sim.reset()
        sim._qpos[sim.rows(0), 2] = np.inf
        state = sim.step(sim.default_joint_pos)
        assert state.diverged.tolist() == [True, False]
        assert (
            abs(float(state.base_pos[0, 2]) - float(sim.reset(np.array([0])).base_pos[0, 2])) < 0.05
        )


def test_device_and_dtype(kuafu) -> None:
    with MujocoSimulator(kuafu, _designs(kuafu, 2), device="cpu") as sim:
        state = sim.reset()
        assert state.joint_pos.dtype == torch.float32 and state.joint_pos.device.type == "cpu"
        assert state.foot_contact.dtype == torch.bool and state.diverged.dtype == torch.bool
        assert sim.control_dt == pytest.approx(0.02)


def test_same_seed_draws_the_same_parameters_as_the_core_sampler(kuafu) -> None:
    """Construction consumes no randomness: the first reset's parameters are the first draw
    of default_rng(seed), as on every backend."""
    from coadapt_core.physics.simulator import sample_env_params

    rand = RandomizationConfig()
    with MujocoSimulator(kuafu, _designs(kuafu, 5), randomization=rand, seed=9) as sim:
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
    designs = np.repeat(_designs(kuafu, 2), 8, axis=0)  # 2 designs x 8 agents
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
    warm = MujocoSimulator(kuafu, _designs(kuafu, 4), num_threads=3)
    warm.step(warm.default_joint_pos)
    warm.close()
    before = threads()
    sim = MujocoSimulator(kuafu, _designs(kuafu, 4), num_threads=3)
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
