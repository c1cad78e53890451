"""The paper's locomotion objectives (eqs. 6-8) and their weighted composite, as a plugin.

Costs are per policy step and per environment; real fitness (Algorithm 2) is their mean over
a rollout, and each one gets its own pseudo-critic (section 3.2.2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, ClassVar

from coadapt_core import hookimpl
from coadapt_core.errors import UserError
from coadapt_core.objective import Objective, StepBatch
from coadapt_core.options import PluginOption

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"

if TYPE_CHECKING:
    import torch


#: cap of the exponent of w_t (our addition: eqs. 7-8 have none). Commands stay within
#: 1.25 m/s and 0 rad/s, so a robot that stands still or walks badly has e_v^2 + e_w^2 below
#: about 2 (w_t < 7.4) and is weighed exactly as the paper says; only a robot that is falling,
#: spinning or diverged exceeds 5 (errors over 2.2 m/s or rad/s). Uncapped, those few steps
#: decide the mean: a fall weighs a step by up to e^20 = 4.9e8 before the reset, so with the
#: earlier cap of 20 one falling agent in 50 multiplied a design's mean torque cost by 1e4
#: (the Kuafu README's evaluation tables), real fitness became a lottery on falls and the
#: pseudo-critics learned the lottery's mean. At 5 a falling step still costs up to 148 x an
#: upright one; above 88, exp() would overflow float32.
W_T_MAX_EXPONENT = 5.0


def tracking_penalty_weight(step: StepBatch) -> torch.Tensor:
    """[N] w_t = exp(e_v^2 + e_w^2): the adaptive penalty of eqs. 7-8 that keeps a robot from
    saving power or torque by standing still (exponent capped at `W_T_MAX_EXPONENT`)."""
    import torch

    exponent = step.linear_tracking_error**2 + step.yaw_tracking_error**2  # [N]
    return torch.exp(exponent.clamp(max=W_T_MAX_EXPONENT))


class TrackingObjective(Objective):
    """P_cmd = e_v^2 + e_w^2 (eq. 6)."""

    name: ClassVar[str] = "tracking"
    default_rank: ClassVar[int] = 1  # one of the default objectives (of a grid, of training)
    display_name: ClassVar[str] = "Command tracking"
    short_label: ClassVar[str] = "Cmd"  # Table 6's column
    unit: ClassVar[str] = "(m/s)^2"  # and (rad/s)^2 for the yaw term
    summary_key: ClassVar[str] = "tracking_error"  # `coadapt eval` reports it always
    description: ClassVar[str] = "P_cmd = e_v^2 + e_w^2, velocity command tracking error (eq. 6)"

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return step.linear_tracking_error**2 + step.yaw_tracking_error**2  # [N]

    def improvement(self, cost: float, nominal_cost: float) -> float:
        """The paper compares the tracking *error*, not its square: the mean cost is a mean
        squared error, so the error is its square root (an RMS error) and the improvement is
        (rms_nominal - rms) / rms_nominal."""
        if nominal_cost <= 0:
            return 0.0
        error, nominal_error = math.sqrt(max(cost, 0.0)), math.sqrt(nominal_cost)
        return (nominal_error - error) / nominal_error


class PowerObjective(Objective):
    """P_p = w_t sum_i |tau_i| |dtheta_i| (eq. 7)."""

    name: ClassVar[str] = "power"
    default_rank: ClassVar[int] = 2  # one of the default objectives (of a grid, of training)
    display_name: ClassVar[str] = "Power consumption"
    short_label: ClassVar[str] = "P"  # Table 6's column
    unit: ClassVar[str] = "W"
    summary_key: ClassVar[str] = "power_cost"  # `coadapt eval` reports it always
    description: ClassVar[str] = (
        "P_p = w_t sum |tau| |dtheta|, mechanical power with tracking penalty (eq. 7)"
    )

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        power = (step.joint_torque.abs() * step.joint_vel.abs()).sum(dim=-1)  # [N]
        return tracking_penalty_weight(step) * power


class TorqueObjective(Objective):
    """P_tau = w_t sum_i tau_i^2 (eq. 8)."""

    name: ClassVar[str] = "torque"
    default_rank: ClassVar[int] = 10  # the default --objective, last of the default objectives
    display_name: ClassVar[str] = "Joint torque"
    short_label: ClassVar[str] = "τ"  # Table 6's column
    unit: ClassVar[str] = "(Nm)^2"
    summary_key: ClassVar[str] = "torque_cost"  # `coadapt eval` reports it always
    description: ClassVar[str] = (
        "P_tau = w_t sum tau^2, squared joint torque with tracking penalty (eq. 8)"
    )

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        return tracking_penalty_weight(step) * (step.joint_torque**2).sum(dim=-1)  # [N]


#: the components a composite may weigh, by name
COMPONENTS: dict[str, type[Objective]] = {
    cls.name: cls for cls in (TrackingObjective, PowerObjective, TorqueObjective)
}


class CompositeObjective(Objective):
    """A weighted sum of tracking, power and torque costs. Default: the paper's real-robot
    check P_cmd + P_p + P_tau (all weights 1). Improvement is the cost reduction."""

    name: ClassVar[str] = "composite"
    display_name: ClassVar[str] = "Composite"
    description: ClassVar[str] = (
        "weighted sum of tracking, power and torque (default P_cmd + P_p + P_tau)"
    )

    option_specs: ClassVar[tuple[PluginOption, ...]] = (
        PluginOption(
            "weights",
            "str",
            "",
            "component weights, e.g. 'tracking=1,power=0.5,torque=1' (missing ones "
            "weigh 0; empty: all 1)",
            alias="objective_weights",
        ),
    )

    def __init__(self, weights: Mapping[str, float] | str | None = None, **options):
        super().__init__(**options)
        self.weights = parse_weights(weights if weights is not None else self.options["weights"])
        self._components = [(COMPONENTS[n](), w) for n, w in self.weights.items()]

    def step_cost(self, step: StepBatch) -> torch.Tensor:
        total = None
        for objective, weight in self._components:
            term = weight * objective.step_cost(step)  # [N]
            total = term if total is None else total + term
        return total


def parse_weights(weights: Mapping[str, float] | str | None) -> dict[str, float]:
    """`{'tracking': 1, 'power': 1, 'torque': 1}` from a mapping, from text such as
    'tracking=1,torque=0.5' (missing components weigh 0), or the default (all 1)."""
    if weights is None or (isinstance(weights, str) and not weights.strip()):
        return {name: 1.0 for name in COMPONENTS}
    if isinstance(weights, str):
        parsed: dict[str, float] = {}
        for part in weights.split(","):
            key, sep, value = part.partition("=")
            try:
                if not sep:
                    raise ValueError
                parsed[key.strip()] = float(value)
            except ValueError:
                raise UserError(
                    f"objective weights '{weights}' must look like 'tracking=1,power=1,torque=1'",
                    field="objective_options",
                ) from None
        weights = parsed
    out: dict[str, float] = {}
    for key, value in dict(weights).items():
        if key not in COMPONENTS:
            raise UserError(
                f"objective weight for unknown component '{key}'; accepted: "
                f"{', '.join(COMPONENTS)}",
                field="objective_options",
            )
        value = float(value)
        if not math.isfinite(value) or value < 0:
            raise UserError(
                f"objective weight '{key}' = {value:g} must be a finite number >= 0",
                field="objective_options",
            )
        out[key] = value
    if not any(v > 0 for v in out.values()):
        raise UserError(
            "objective weights must give at least one component a weight > 0",
            field="objective_options",
        )
    return out


@hookimpl
def coadapt_register_objectives() -> list[type[Objective]]:
    return [TrackingObjective, PowerObjective, TorqueObjective, CompositeObjective]
