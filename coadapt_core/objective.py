"""The `Objective` plugin kind: a per-step design cost (paper equations 6-8).

An objective turns one batched step of locomotion (commands, base velocities, joint
torques and speeds) into a cost per environment. Real fitness is its mean over rollouts
(Algorithm 2); its pseudo-critic learns to predict it (section 3.2.2). Costs are minimised.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    import torch


@dataclass
class StepBatch:
    """What an objective may look at, one policy step of N environments (base frame)."""

    command: torch.Tensor  # [N, 3] (vx, vy, yaw rate) commanded
    base_lin_vel: torch.Tensor  # [N, 3] base frame, m/s
    base_ang_vel: torch.Tensor  # [N, 3] base frame, rad/s
    joint_torque: torch.Tensor  # [N, J] N m
    joint_vel: torch.Tensor  # [N, J] rad/s
    action: torch.Tensor  # [N, J] joint targets issued

    @property
    def linear_tracking_error(self) -> torch.Tensor:
        """[N] e_v: norm of the planar velocity error."""
        return (self.command[:, :2] - self.base_lin_vel[:, :2]).norm(dim=-1)

    @property
    def yaw_tracking_error(self) -> torch.Tensor:
        """[N] e_w: yaw-rate error magnitude."""
        return (self.command[:, 2] - self.base_ang_vel[:, 2]).abs()


class Objective(ABC):
    """A per-step cost to minimise."""

    #: user-facing key (`--objective torque`)
    name: ClassVar[str]
    #: label for tables and plots
    display_name: ClassVar[str]
    #: always "minimize" for costs; kept explicit for reports
    direction: ClassVar[str] = "minimize"
    description: ClassVar[str] = ""

    @abstractmethod
    def step_cost(self, step: StepBatch) -> torch.Tensor:
        """[N] cost of this step for each environment."""

    def improvement(self, cost: float, nominal_cost: float) -> float:
        """Relative improvement of `cost` over the nominal design's cost (positive = better).
        Default: cost reduction (nominal - cost) / nominal."""
        if nominal_cost == 0:
            return 0.0
        return (nominal_cost - cost) / abs(nominal_cost)
