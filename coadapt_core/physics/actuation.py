"""Joint actuation shared by every simulator backend: PD law, motor torque-speed envelope
and system delay. One definition, so MuJoCo and PyBullet apply identical semantics.

Per physics step, for each environment and actuated joint:

    q_target   = the policy's target issued `delay_steps` physics steps ago
    tau_pd     = pd_factor * (kp * (q_target - q) - kd * dq)
    tau_cmd    = motor_strength * tau_pd
    tau        = clip(tau_cmd, lower(dq), upper(dq))       # torque-speed envelope

with the linear envelope of a DC motor behind its gearbox (limits at the joint):

    upper(dq) =  tau_max * clip(1 - dq / dq_max, 0, 1)
    lower(dq) = -tau_max * clip(1 + dq / dq_max, 0, 1)

so full torque is available at rest and for braking, and no torque can push a joint
further beyond its no-load speed `dq_max`.
"""

from __future__ import annotations

import numpy as np


def torque_speed_bounds(dq: np.ndarray, tau_max: np.ndarray, dq_max: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) torque bounds [..., J] at joint speeds dq [..., J]."""
    ratio = dq / dq_max
    upper = tau_max * np.clip(1.0 - ratio, 0.0, 1.0)
    lower = -tau_max * np.clip(1.0 + ratio, 0.0, 1.0)
    return lower, upper


def pd_torque(
    q_target: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    kp: np.ndarray,
    kd: np.ndarray,
    tau_max: np.ndarray,
    dq_max: np.ndarray,
    pd_factor: np.ndarray | float = 1.0,
    motor_strength: np.ndarray | float = 1.0,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Joint torques [N, J]. `pd_factor` and `motor_strength` are [N] or scalars; the rest
    [N, J] (or broadcastable). Written to `out` when given (no allocation in the hot loop)."""
    pd_factor = np.asarray(pd_factor, dtype=float)
    motor_strength = np.asarray(motor_strength, dtype=float)
    if pd_factor.ndim == 1:
        pd_factor = pd_factor[:, None]
    if motor_strength.ndim == 1:
        motor_strength = motor_strength[:, None]
    tau = (kp * (q_target - q) - kd * dq) * (pd_factor * motor_strength)
    lower, upper = torque_speed_bounds(dq, tau_max, dq_max)
    return np.clip(tau, lower, upper, out=out)


class DelayLine:
    """Per-environment delay of joint targets by a whole number of physics steps.

    `push(targets)` once per physics step, then `current()` gives for each environment the
    targets pushed `delay_steps[env]` steps ago (0 = the newest). After `reset(env_ids,
    targets)` those environments see `targets` until enough new ones have been pushed.
    """

    def __init__(self, num_envs: int, num_joints: int, max_delay_steps: int):
        self.capacity = int(max_delay_steps) + 1
        self.buffer = np.zeros((self.capacity, num_envs, num_joints))  # [capacity, N, J] ring
        self.head = 0  # slot of the newest entry
        self.delay_steps = np.zeros(num_envs, dtype=int)  # [N]
        self._envs = np.arange(num_envs)

    def set_delay(self, env_ids: np.ndarray, delay_steps: np.ndarray) -> None:
        delay_steps = np.asarray(delay_steps, dtype=int)
        if np.any(delay_steps < 0) or np.any(delay_steps >= self.capacity):
            raise ValueError(f"delay steps must lie in [0, {self.capacity - 1}]")
        self.delay_steps[env_ids] = delay_steps

    def reset(self, env_ids: np.ndarray, targets: np.ndarray) -> None:
        self.buffer[:, env_ids] = targets[None]

    def push(self, targets: np.ndarray) -> None:
        self.head = (self.head + 1) % self.capacity
        self.buffer[self.head] = targets

    def current(self) -> np.ndarray:
        slots = (self.head - self.delay_steps) % self.capacity
        return self.buffer[slots, self._envs]
