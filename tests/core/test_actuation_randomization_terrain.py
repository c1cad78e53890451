import numpy as np
import pytest

from coadapt_core.errors import UserError
from coadapt_core.physics.actuation import DelayLine, pd_torque, torque_speed_bounds
from coadapt_core.physics.randomization import RandomizationConfig, sample_env_params
from coadapt_core.physics.terrain import make_terrain


def test_envelope_full_torque_at_rest_zero_at_no_load_speed():
    tau_max, dq_max = np.array([100.0]), np.array([10.0])
    lo, hi = torque_speed_bounds(np.array([0.0]), tau_max, dq_max)
    assert (lo[0], hi[0]) == (-100.0, 100.0)
    lo, hi = torque_speed_bounds(np.array([5.0]), tau_max, dq_max)
    assert (lo[0], hi[0]) == (-100.0, 50.0)  # braking keeps full torque
    lo, hi = torque_speed_bounds(np.array([12.0]), tau_max, dq_max)
    assert hi[0] == 0.0 and lo[0] == -100.0


def test_pd_torque_scaled_then_clipped():
    q_target = np.array([[0.1, 5.0]])
    q = np.zeros((1, 2))
    dq = np.zeros((1, 2))
    tau = pd_torque(q_target, q, dq, kp=np.array([100.0, 100.0]), kd=np.array([1.0, 1.0]),
                    tau_max=np.array([120.0, 120.0]), dq_max=np.array([10.0, 10.0]),
                    pd_factor=np.array([1.1]), motor_strength=np.array([0.9]))
    assert tau[0, 0] == pytest.approx(100 * 0.1 * 1.1 * 0.9)
    assert tau[0, 1] == pytest.approx(120.0)


def test_delay_line_delays_per_env():
    line = DelayLine(num_envs=2, num_joints=1, max_delay_steps=4)
    line.set_delay(np.array([0, 1]), np.array([0, 2]))
    line.reset(np.array([0, 1]), np.zeros((2, 1)))
    seen = []
    for k in range(1, 5):
        line.push(np.full((2, 1), float(k)))
        seen.append(line.current()[:, 0].tolist())
    assert [s[0] for s in seen] == [1, 2, 3, 4]
    assert [s[1] for s in seen] == [0, 0, 1, 2]


def test_randomization_ranges_and_off():
    cfg = RandomizationConfig()
    p = sample_env_params(cfg, 2000, np.random.default_rng(0))
    assert p.friction.min() >= 0.5 and p.friction.max() <= 1.25
    assert p.com_shift.shape == (2000, 3) and np.abs(p.com_shift).max() <= 0.025
    assert p.delay.min() >= 0.0 and p.delay.max() <= 0.020
    assert p.friction.std() > 0.1
    off = sample_env_params(RandomizationConfig.off(), 10, np.random.default_rng(0))
    assert np.all(off.friction == 1.0) and np.all(off.delay == 0.0) and np.all(off.pd_factor == 1.0)
    np.testing.assert_array_equal(p.delay_steps(0.005)[:5], np.rint(p.delay[:5] / 0.005))


def test_randomization_rejects_bad_ranges():
    with pytest.raises(UserError, match=r"randomization\.friction: inverted"):
        RandomizationConfig(friction=(1.2, 0.5))
    with pytest.raises(UserError, match=r"randomization\.delay"):
        RandomizationConfig(delay=(-0.01, 0.0))


def test_terrains():
    flat, slope, rough = make_terrain("flat"), make_terrain("slope"), make_terrain("random", seed=1)
    xy = np.array([[1.0, 0.0], [-2.0, 3.0]])
    np.testing.assert_allclose(flat.height_at(xy), 0.0)
    np.testing.assert_allclose(slope.height_at(xy), xy[:, 0] * np.tan(np.radians(10.0)))
    h = rough.height_at(np.random.default_rng(0).uniform(-5, 5, (1000, 2)))
    assert h.min() >= 0.0 and h.max() <= 0.05 and h.std() > 0.005
    grid = rough.height_grid()
    assert grid.shape == (201, 201)
    # grid vertices are hit exactly
    assert rough.height_at(np.array([-10.0, -10.0])) == pytest.approx(grid[0, 0])
    assert np.all(rough.max_height_near(xy, 0.2) >= rough.height_at(xy))
    with pytest.raises(UserError, match="unknown terrain 'ice'"):
        make_terrain("ice")
