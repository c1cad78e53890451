"""Which PyBullet states count as diverged: not finite, or beyond any magnitude a physical
robot reaches. The simulator resets such environments after the step."""

from __future__ import annotations

import numpy as np

#: divergence: any state beyond these magnitudes (or not finite) resets the environment
MAX_BASE_DISTANCE = 1.0e3  # m
MAX_BASE_SPEED = 1.0e2  # m/s
MAX_ANGULAR_SPEED = 1.0e3  # rad/s (base and joints)


def diverged(state: dict[str, np.ndarray]) -> np.ndarray:
    """[k] bool: a state no physical robot reaches (or not finite)."""
    finite = np.ones(state["base_pos"].shape[0], dtype=bool)
    for key in (
        "base_pos",
        "base_quat",
        "base_lin_vel",
        "base_ang_vel",
        "joint_pos",
        "joint_vel",
        "foot_pos",
    ):
        finite &= np.isfinite(state[key]).reshape(finite.shape[0], -1).all(axis=1)
    with np.errstate(invalid="ignore"):
        huge = (
            (np.abs(state["base_pos"]).max(axis=1) > MAX_BASE_DISTANCE)
            | (np.linalg.norm(state["base_lin_vel"], axis=1) > MAX_BASE_SPEED)
            | (np.linalg.norm(state["base_ang_vel"], axis=1) > MAX_ANGULAR_SPEED)
            | (np.abs(state["joint_vel"]).max(axis=1) > MAX_ANGULAR_SPEED)
        )
    return ~finite | huge
