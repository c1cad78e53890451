"""Sim-to-sim: PyBullet reproduces MuJoCo's motion of the same robot (docs/sim-to-sim.md).

Tolerances, from the figures measured on the default designs (largest seen in brackets),
with margin for changes of the robot model:
- swing (fixed base, no contact): joint angle RMS < 0.01 rad (0.002, design 1.5/1.5),
  joint velocity RMS < 3 rad/s (0.61), torque RMS < 2 N m (0.39), against a joint motion
  of about 0.3 rad RMS;
- standing on flat ground for 1 s: base height within 5 mm at every step (1.1 mm), base
  orientation within 0.02 rad (0.0062), joint angles within 0.02 rad (0.014).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pybullet")

from coadapt_core.experiments.transfer import (
    DEFAULT_DESIGNS,
    ErrorFigure,
    compare_backends,
    markdown_tables,
    swing_targets,
)
from coadapt_core.plugins import get_registry


@pytest.fixture(scope="module")
def figures():
    registry = get_registry()
    return compare_backends(registry.create("robot", "kuafu"), reference="mujoco", other="pybullet")


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(DEFAULT_DESIGNS)))
def test_swing_trajectories_agree(figures, index):
    fig = figures[index]
    assert fig.design == DEFAULT_DESIGNS[index]
    assert fig.swing_amplitude > 0.2  # the joints really moved
    assert fig.swing["joint_pos"].rms < 0.01, fig.to_dict()
    assert fig.swing["joint_vel"].rms < 3.0, fig.to_dict()
    assert fig.swing["joint_torque"].rms < 2.0, fig.to_dict()


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(DEFAULT_DESIGNS)))
def test_standing_agrees(figures, index):
    fig = figures[index]
    assert fig.standing["base_height"].max < 0.005, fig.to_dict()
    assert fig.standing["orientation"].max < 0.02, fig.to_dict()
    assert fig.standing["joint_pos"].max < 0.02, fig.to_dict()
    # both backends settle by the same amount (soft MuJoCo contact vs rigid Bullet contact)
    assert abs(fig.height_drop["reference"] - fig.height_drop["other"]) < 0.005


@pytest.mark.slow
def test_markdown_has_a_table_per_design(figures):
    text = markdown_tables(figures)
    assert text.count("#### Design") == len(DEFAULT_DESIGNS)
    assert "| swing | joint_pos (rad) |" in text


def test_error_figure_and_swing_targets():
    err = ErrorFigure.of(np.array([0.0, 3.0, -4.0]), np.zeros(3))
    assert err.max == 4.0
    assert err.rms == pytest.approx(np.sqrt(25 / 3))
    targets = swing_targets(np.zeros((2, 8)), steps=50, control_dt=0.02)
    assert targets.shape == (50, 2, 8)
    assert np.abs(targets).max() <= 0.5 + 1e-12
    assert not np.allclose(targets[:, 0, :4], targets[:, 0, 4:])  # legs are not mirrored


@pytest.mark.parametrize("terrain", ["flat", "random"])
def test_same_seed_same_parameters_and_spawn_on_both_backends(terrain):
    """Randomized parameters and spawn points come from the seed alone, not the backend."""
    from coadapt_core.physics.randomization import RandomizationConfig

    registry = get_registry()
    robot = registry.create("robot", "kuafu")
    designs = np.array([[1.0, 1.0], [0.6, 1.4]])
    seen = []
    for name in ("mujoco", "pybullet"):
        with registry.create(
            "simulator",
            name,
            robot,
            designs,
            terrain=terrain,
            randomization=RandomizationConfig(),
            seed=9,
        ) as sim:
            first = sim.env_params
            state = sim.reset()
            seen.append(
                (
                    first,
                    sim.env_params,
                    state.base_pos.double().numpy(),
                    state.joint_pos.double().numpy(),
                )
            )
    (a_first, a_params, a_pos, a_q), (b_first, b_params, b_pos, b_q) = seen
    for key in ("friction", "restitution", "com_shift", "pd_factor", "motor_strength", "delay"):
        np.testing.assert_array_equal(getattr(a_first, key), getattr(b_first, key))
        np.testing.assert_array_equal(getattr(a_params, key), getattr(b_params, key))
    assert not np.array_equal(a_first.friction, a_params.friction)  # reset drew new ones
    np.testing.assert_allclose(b_pos, a_pos, atol=1e-6)  # the same spawn point and height
    np.testing.assert_allclose(b_q, a_q, atol=1e-6)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["nope", "mujoco", "pybullet"], "error: unknown robot 'nope'"),
        (["kuafu", "mujoco", "nosim"], "error: unknown simulator 'nosim'"),
        (["kuafu"], "usage: python -m coadapt_core.experiments.transfer"),
    ],
)
def test_the_check_script_says_bad_arguments_in_one_line(capsys, argv, message):
    from coadapt_core.experiments.transfer import main

    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(message)
