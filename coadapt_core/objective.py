"""The `Objective` plugin kind: a per-step design cost (paper equations 6-8).

An objective turns one batched step of locomotion (commands, base velocities, joint
torques, speeds and targets, and the context of each environment: its design, total mass,
base height, foot contacts and the step's duration) into a cost per environment. Real
fitness is its mean over rollouts (Algorithm 2); its pseudo-critic learns to predict it
(section 3.2.2). Costs are minimised.

Options: an objective declares its settings in `option_specs` (see `coadapt_core.options`);
they reach it as constructor keywords from YAML `objective_options:` and the CLI's
`--objective-option KEY=VALUE`, checked, defaults filled in, in `self.options`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_core.options import PluginOption, resolve_options

if TYPE_CHECKING:
    import torch


@dataclass
class StepBatch:
    """What an objective may look at, one policy step of N environments (base frame).

    Every tensor's first axis is the environment; row i depends on environment i only.
    J actuated joints in the robot's `joint_names` order, L legs in its `legs` order."""

    command: torch.Tensor  # [N, 3] (vx, vy, yaw rate) commanded
    base_lin_vel: torch.Tensor  # [N, 3] base frame, m/s
    base_ang_vel: torch.Tensor  # [N, 3] base frame, rad/s
    joint_torque: torch.Tensor  # [N, J] N m
    joint_vel: torch.Tensor  # [N, J] rad/s
    joint_targets: torch.Tensor  # [N, J] PD position targets the policy issued this step, rad
    design: torch.Tensor  # [N, D] each environment's design vector
    total_mass: torch.Tensor  # [N] kg, of each environment's robot (designs change it)
    base_height: torch.Tensor  # [N] base origin above the terrain under it, m
    foot_contact: torch.Tensor  # [N, L] bool, foot touching the ground
    dt: float  # seconds of simulated time this step covers (the policy period)

    def rows(self, index: Any) -> StepBatch:
        """The same step restricted to some environments (`index` into the first axis)."""
        return StepBatch(
            **{
                f.name: getattr(self, f.name) if f.name == "dt" else getattr(self, f.name)[index]
                for f in fields(self)
            }
        )

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
    #: rank as the default of its kind: with no name given, a command takes the installed
    #: plugin of highest rank (ties: the first name in alphabetical order; docs/plugins.md)
    default_rank: ClassVar[int] = 0
    #: label for tables and plots
    display_name: ClassVar[str]
    #: short label for a table's objective column (the paper's Table 6 writes "τ" for joint
    #: torque); "" shows the name
    short_label: ClassVar[str] = ""
    #: the unit of the per-step cost (`coadapt run` prints it with every cost; "" when none)
    unit: ClassVar[str] = ""
    #: the key of its mean cost per step in `coadapt eval`'s result (its standard error:
    #: `<key>_se`) for an objective eval always reports; "" (the default): reported when
    #: asked for (`coadapt eval --objective`, under `costs`)
    summary_key: ClassVar[str] = ""
    #: always "minimize" for costs; kept explicit for reports
    direction: ClassVar[str] = "minimize"
    description: ClassVar[str] = ""
    #: the plugin's own options (`coadapt_core.options.PluginOption`), read from `self.options`
    option_specs: ClassVar[tuple[PluginOption, ...]] = ()

    def __init__(self, **options: Any):
        """Options declared in `option_specs`, checked, with defaults filled in; an
        undeclared one is a user error. A subclass with its own constructor calls this."""
        self.options = resolve_options(
            type(self).option_specs,
            options,
            owner=f"objective '{self.name}'",
            field="objective_options",
        )

    @abstractmethod
    def step_cost(self, step: StepBatch) -> torch.Tensor:
        """[N] cost of this step for each environment."""

    def improvement(self, cost: float, nominal_cost: float) -> float:
        """Relative improvement of `cost` over the nominal design's cost (positive = better).
        Default: cost reduction (nominal - cost) / nominal."""
        if nominal_cost == 0:
            return 0.0
        return (nominal_cost - cost) / abs(nominal_cost)
