"""Joint actuation shared by every simulator backend: PD law, motor torque-speed envelope
and system delay, on torch tensors of the backend's device and dtype. One definition, so
MuJoCo, PyBullet and any GPU backend apply identical semantics.

Per physics step, for each environment and actuated joint:

    q_target   = the policy's target issued `delay_steps` physics steps ago
    tau_pd     = pd_factor * (kp * (q_target - q) - kd * dq)
    tau_cmd    = motor_strength * tau_pd
    tau        = clip(tau_cmd, lower(dq), upper(dq))       # torque-speed envelope

with the linear envelope of a DC motor behind its gearbox (limits at the joint):

    upper(dq) =  tau_max * clip(1 - dq / dq_max, 0, 1)
    lower(dq) = -tau_max * clip(1 + dq / dq_max, 0, 1)

so full torque is available at rest and for braking, and no torque can push a joint
further beyond its no-load speed `dq_max` (the "soft" limit, the default: a joint driven past
it by gravity or the other joints may still brake there at full torque).

The "binding" speed limit (`bind_speed`; `task.motor_speed_limit`, issue 41) adds:

    tau = 0   where |dq| > dq_max

no torque at all beyond the no-load speed, either way: the motor cannot follow, and the task
ends an episode whose joint stays beyond it (`task.overspeed_seconds`). A CPU backend whose
state lives in numpy arrays passes `torch.from_numpy` views (no copy) and reads the result
back the same way.
"""

from __future__ import annotations

import torch


def torque_speed_bounds(
    dq: torch.Tensor, tau_max: torch.Tensor, dq_max: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """(lower, upper) torque bounds [..., J] at joint speeds dq [..., J]."""
    ratio = dq / dq_max
    upper = tau_max * torch.clamp(1.0 - ratio, 0.0, 1.0)
    lower = -tau_max * torch.clamp(1.0 + ratio, 0.0, 1.0)
    return lower, upper


def _per_env(factor: torch.Tensor | float) -> torch.Tensor | float:
    """A per-environment factor [N] as a column [N, 1]; scalars and [N, 1] pass through."""
    if isinstance(factor, torch.Tensor) and factor.dim() == 1:
        return factor[:, None]
    return factor


def pd_torque(
    q_target: torch.Tensor,
    q: torch.Tensor,
    dq: torch.Tensor,
    kp: torch.Tensor,
    kd: torch.Tensor,
    tau_max: torch.Tensor,
    dq_max: torch.Tensor,
    pd_factor: torch.Tensor | float = 1.0,
    motor_strength: torch.Tensor | float = 1.0,
    out: torch.Tensor | None = None,
) -> torch.Tensor:
    """Joint torques [N, J]. `pd_factor` and `motor_strength` are [N] or scalars; the rest
    [N, J] (or broadcastable), all on one device. Written to `out` when given (no
    allocation for the result in the hot loop)."""
    # torque_speed_bounds and the PD law, with the temporaries reused in place (this runs
    # every physics step; the numbers are the same to the last bit)
    ratio = dq / dq_max
    upper = tau_max * torch.rsub(ratio, 1.0).clamp_(0.0, 1.0)
    lower = (tau_max * ratio.add_(1.0).clamp_(0.0, 1.0)).neg_()
    tau = (kp * (q_target - q) - kd * dq).mul_(_per_env(pd_factor) * _per_env(motor_strength))
    return torch.clamp(tau, min=lower, max=upper, out=out)


def bind_speed(tau: torch.Tensor, dq: torch.Tensor, dq_max: torch.Tensor) -> torch.Tensor:
    """The binding speed limit on `pd_torque`'s torques [N, J], in place: zero where
    |dq| > dq_max (a backend whose `speed_limit` is "binding" applies it after `pd_torque`)."""
    return tau.masked_fill_(dq.abs() > dq_max, 0.0)


class DelayLine:
    """Per-environment delay of joint targets by a whole number of physics steps.

    `push(targets)` once per physics step, then `current()` gives for each environment the
    targets pushed `delay_steps[env]` steps ago (0 = the newest). After `reset(env_ids,
    targets)` those environments see `targets` until enough new ones have been pushed.
    Tensors live on `device` in `dtype`; env ids may be tensors or numpy arrays.
    """

    def __init__(
        self,
        num_envs: int,
        num_joints: int,
        max_delay_steps: int,
        *,
        device: str | torch.device = "cpu",
        dtype: torch.dtype = torch.float64,
    ):
        self.capacity = int(max_delay_steps) + 1
        self.buffer = torch.zeros(
            (self.capacity, num_envs, num_joints), dtype=dtype, device=device
        )  # ring
        self._rows = self.buffer.view(self.capacity * num_envs, num_joints)  # the ring as rows
        self.head = 0  # slot of the newest entry
        self.delay_steps = torch.zeros(num_envs, dtype=torch.long, device=device)  # [N]
        # [capacity, N]: for each head slot, the row of every environment's delayed target
        # (rebuilt for the environments whose delay changes), so `current` is one gather
        self._slots = torch.arange(self.capacity, device=device)[:, None]
        self._lookup = self._slots * num_envs + torch.arange(num_envs, device=device)

    def _index(self, env_ids) -> torch.Tensor:
        return torch.as_tensor(env_ids, dtype=torch.long, device=self.buffer.device)

    def set_delay(self, env_ids, delay_steps) -> None:
        delay_steps = torch.as_tensor(delay_steps, dtype=torch.long, device=self.buffer.device)
        if bool((delay_steps < 0).any()) or bool((delay_steps >= self.capacity).any()):
            raise ValueError(f"delay steps must lie in [0, {self.capacity - 1}]")
        ids = self._index(env_ids)
        self.delay_steps[ids] = delay_steps
        slots = torch.remainder(self._slots - delay_steps, self.capacity)  # [capacity, n]
        self._lookup[:, ids] = slots * self.buffer.shape[1] + ids

    def reset(self, env_ids, targets: torch.Tensor) -> None:
        self.buffer[:, self._index(env_ids)] = torch.as_tensor(
            targets, dtype=self.buffer.dtype, device=self.buffer.device
        )[None]

    def push(self, targets: torch.Tensor) -> None:
        self.head = (self.head + 1) % self.capacity
        self.buffer[self.head] = targets

    def current(self) -> torch.Tensor:
        """[N, J] each environment's target of `delay_steps` pushes ago."""
        return self._rows.index_select(0, self._lookup[self.head])
