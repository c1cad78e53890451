import numpy as np
import pytest
import torch

from coadapt_core.errors import UserError
from coadapt_core.physics.actuation import DelayLine, pd_torque, torque_speed_bounds
from coadapt_core.physics.randomization import RandomizationConfig, sample_env_params
from coadapt_core.physics.terrain import make_terrain


def _t(values) -> torch.Tensor:
    return torch.as_tensor(values, dtype=torch.float64)


def test_envelope_full_torque_at_rest_zero_at_no_load_speed():
    tau_max, dq_max = _t([100.0]), _t([10.0])
    lo, hi = torque_speed_bounds(_t([0.0]), tau_max, dq_max)
    assert (lo.item(), hi.item()) == (-100.0, 100.0)
    lo, hi = torque_speed_bounds(_t([5.0]), tau_max, dq_max)
    assert (lo.item(), hi.item()) == (-100.0, 50.0)  # braking keeps full torque
    lo, hi = torque_speed_bounds(_t([12.0]), tau_max, dq_max)
    assert hi.item() == 0.0 and lo.item() == -100.0
    lo, hi = torque_speed_bounds(_t([-4.0]), tau_max, dq_max)
    assert (lo.item(), hi.item()) == (-60.0, 100.0)


def test_pd_torque_scaled_then_clipped_to_the_motor_envelope():
    """Known numbers: kp 100, kd 2, factor 1.1 x strength 0.9 = 0.99, tau_max 120, dq_max 10."""
    q_target = _t([[0.1, 5.0, -5.0, 1.0], [0.1, 0.1, 0.1, 0.1]])
    q = torch.zeros(2, 4, dtype=torch.float64)
    dq = _t([[0.0, 0.0, 0.0, 5.0], [0.0, 0.0, 0.0, 0.0]])
    kp, kd = (
        torch.full((2, 4), 100.0, dtype=torch.float64),
        torch.full((2, 4), 2.0, dtype=torch.float64),
    )
    tau_max, dq_max = (
        torch.full((2, 4), 120.0, dtype=torch.float64),
        torch.full((2, 4), 10.0, dtype=torch.float64),
    )
    tau = pd_torque(
        q_target,
        q,
        dq,
        kp,
        kd,
        tau_max,
        dq_max,
        pd_factor=_t([1.1, 1.0]),
        motor_strength=_t([0.9, 0.5]),
    )
    expected = [
        [
            100 * 0.1 * 0.99,
            120.0,
            -120.0,
            60.0,
        ],  # in range; clipped up, down; (100 - 10) * 0.99 above 60 at dq 5
        [5.0, 5.0, 5.0, 5.0],  # env 1: its own factors (1.0 x 0.5)
    ]
    torch.testing.assert_close(tau, _t(expected))
    # written in place when asked, and scalar factors broadcast
    out = torch.empty(2, 4, dtype=torch.float64)
    result = pd_torque(
        q_target, q, torch.zeros_like(dq), kp, kd, tau_max, dq_max, 0.5, 1.0, out=out
    )
    assert result.data_ptr() == out.data_ptr()
    torch.testing.assert_close(out[1], torch.full((4,), 5.0, dtype=torch.float64))


def test_delay_line_returns_each_input_k_steps_later():
    line = DelayLine(num_envs=3, num_joints=2, max_delay_steps=4)
    delays = [0, 2, 4]
    line.set_delay(np.array([0, 1, 2]), np.array(delays))
    line.reset(torch.tensor([0, 1, 2]), torch.full((3, 2), -1.0, dtype=torch.float64))
    pushed = []
    for step in range(10):
        value = torch.full((3, 2), float(step), dtype=torch.float64)
        line.push(value)
        pushed.append(value)
        now = line.current()  # [3, 2]
        for env, k in enumerate(delays):
            # the input of step - k, or the reset targets before k inputs arrived
            expected = float(step - k) if step >= k else -1.0
            assert now[env].tolist() == [expected, expected], (step, env)
    with pytest.raises(ValueError, match="delay steps"):
        line.set_delay(np.array([0]), np.array([5]))


def test_delay_line_reset_touches_only_its_environments():
    line = DelayLine(num_envs=2, num_joints=1, max_delay_steps=2)
    line.set_delay(np.array([0, 1]), np.array([2, 2]))
    for k in range(3):
        line.push(torch.full((2, 1), float(k), dtype=torch.float64))
    line.reset(np.array([1]), torch.full((1, 1), 9.0, dtype=torch.float64))
    assert line.current()[:, 0].tolist() == [0.0, 9.0]


def test_env_params_are_tensors_of_the_requested_device_and_dtype():
    p = sample_env_params(RandomizationConfig(), 5, np.random.default_rng(3), dtype=torch.float32)
    assert all(isinstance(v, torch.Tensor) and v.dtype == torch.float32 for v in vars(p).values())
    assert p.device == torch.device("cpu") and len(p) == 5
    # the same seed draws the same numbers whatever the dtype (the draw itself is numpy's)
    q = sample_env_params(RandomizationConfig(), 5, np.random.default_rng(3))
    assert q.friction.dtype == torch.float64
    torch.testing.assert_close(p.friction, q.friction.float())
    # take / put / repeat / privileged
    sub = q.take(np.array([4, 1]))
    assert sub.friction.tolist() == [q.friction[4].item(), q.friction[1].item()]
    r = q.repeat(3)
    assert len(r) == 15 and torch.equal(r.com_shift[10:], q.com_shift)
    q.put(torch.tensor([0]), sub.take([0]))
    assert q.friction[0] == q.friction[4]
    priv = q.privileged()
    assert priv.shape == (5, 8) and priv.dtype == torch.float32
    torch.testing.assert_close(priv[:, 4], q.delay.float())
    torch.testing.assert_close(priv[:, 5:], q.com_shift.float())


def test_randomization_ranges_and_off():
    cfg = RandomizationConfig()
    p = sample_env_params(cfg, 2000, np.random.default_rng(0))
    assert p.friction.min() >= 0.5 and p.friction.max() <= 1.25
    assert p.com_shift.shape == (2000, 3) and p.com_shift.abs().max() <= 0.025
    assert p.delay.min() >= 0.0 and p.delay.max() <= 0.020
    assert p.friction.std() > 0.1
    off = sample_env_params(RandomizationConfig.off(), 10, np.random.default_rng(0))
    assert (
        bool((off.friction == 1.0).all())
        and bool((off.delay == 0.0).all())
        and bool((off.pd_factor == 1.0).all())
    )
    # delay in whole physics steps, rounded half to even: at 5 ms a step, 7.5 ms is 2 steps,
    # 12.5 ms 2 and 17.5 ms 4
    p.delay[:3] = torch.tensor([0.0075, 0.0125, 0.0175], dtype=torch.float64)
    assert p.delay_steps(0.005)[:3].tolist() == [2, 2, 4]
    assert p.delay_steps(0.005).dtype == torch.long


def test_randomization_rejects_bad_ranges():
    with pytest.raises(UserError, match=r"randomization\.friction must be .*inverted"):
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
