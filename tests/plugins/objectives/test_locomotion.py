"""The locomotion objectives: conformance, exact costs on hand-made steps, improvements."""

from __future__ import annotations

import math

import pytest
import torch
from coadapt_plugins.objectives.locomotion import (
    CompositeObjective,
    PowerObjective,
    TorqueObjective,
    TrackingObjective,
)

from coadapt_core.errors import UserError
from coadapt_core.objective import StepBatch
from coadapt_core.plugins import get_registry
from coadapt_core.testing import ObjectiveConformance


def hand_step() -> StepBatch:
    """Two environments: env 0 tracks perfectly, env 1 has e_v = 0.5 (0.3, 0.4) and e_w = 0.2."""
    return StepBatch(
        command=torch.tensor([[1.0, 0.0, 0.0], [1.0, 0.0, 0.5]]),
        base_lin_vel=torch.tensor([[1.0, 0.0, 0.1], [0.7, 0.4, -0.2]]),
        base_ang_vel=torch.tensor([[0.3, 0.1, 0.0], [0.0, 0.0, 0.3]]),
        joint_torque=torch.tensor(
            [[1.0, -2.0, 0, 0, 0, 0, 0, 3.0], [10.0, 0, 0, 0, 0, 0, 0, -1.0]]
        ),
        joint_vel=torch.tensor(
            [[2.0, 1.0, 5.0, 0, 0, 0, 0, -1.0], [-0.5, 4.0, 0, 0, 0, 0, 0, 2.0]]
        ),
        joint_targets=torch.zeros(2, 8),
        design=torch.ones(2, 2),
        total_mass=torch.tensor([20.0, 21.0]),
        base_height=torch.tensor([0.9, 0.9]),
        foot_contact=torch.ones(2, 2, dtype=torch.bool),
        dt=0.02,
    )


@pytest.mark.parametrize(
    "cls", [TrackingObjective, PowerObjective, TorqueObjective, CompositeObjective]
)
class TestConformance(ObjectiveConformance):
    @pytest.fixture
    def objective(self, cls):
        return cls()


def test_tracking_is_squared_velocity_errors():
    cost = TrackingObjective().step_cost(hand_step())
    # env 1: e_v^2 = 0.3^2 + 0.4^2 = 0.25, e_w^2 = 0.2^2 = 0.04
    assert cost.tolist() == pytest.approx([0.0, 0.29])


def test_power_is_penalised_sum_of_abs_torque_times_speed():
    cost = PowerObjective().step_cost(hand_step())
    # env 0: |1*2| + |-2*1| + |3*-1| = 7, w_t = 1; env 1: 10*0.5 + 1*2 = 7, w_t = exp(0.29)
    assert cost.tolist() == pytest.approx([7.0, 7.0 * math.exp(0.29)], rel=1e-6)


def test_torque_is_penalised_sum_of_squared_torques():
    cost = TorqueObjective().step_cost(hand_step())
    assert cost.tolist() == pytest.approx([14.0, 101.0 * math.exp(0.29)], rel=1e-6)


def test_composite_default_is_paper_sum_and_weights_apply():
    step = hand_step()
    parts = [o.step_cost(step) for o in (TrackingObjective(), PowerObjective(), TorqueObjective())]
    assert CompositeObjective().step_cost(step).tolist() == pytest.approx(
        (parts[0] + parts[1] + parts[2]).tolist()
    )
    weighted = CompositeObjective("tracking=2,torque=0.5").step_cost(step)
    assert weighted.tolist() == pytest.approx((2 * parts[0] + 0.5 * parts[2]).tolist())
    assert CompositeObjective({"power": 1.0}).step_cost(step).tolist() == pytest.approx(
        parts[1].tolist()
    )


@pytest.mark.parametrize("text", ["speed=1", "tracking=x", "tracking", "torque=-1", "tracking=0"])
def test_composite_rejects_bad_weights_with_user_error(text):
    with pytest.raises(UserError, match="objective weight"):
        CompositeObjective(text)


def test_tracking_improvement_compares_rms_error():
    # mean squared error 0.25 vs nominal 1.0: RMS errors 0.5 vs 1.0 -> 50 % better
    assert TrackingObjective().improvement(0.25, 1.0) == pytest.approx(0.5)
    assert TrackingObjective().improvement(4.0, 1.0) == pytest.approx(-1.0)


def test_power_and_torque_improvement_is_cost_reduction():
    assert PowerObjective().improvement(75.0, 100.0) == pytest.approx(0.25)
    assert TorqueObjective().improvement(120.0, 100.0) == pytest.approx(-0.2)


def test_registered_through_entry_point():
    registry = get_registry()
    for name in ("tracking", "power", "torque", "composite"):
        assert registry.entries["objective"][name].distribution == "coadapt"


def test_penalty_weight_stays_finite_for_a_diverged_robot():
    step = hand_step()
    step.base_lin_vel[1, 0] = 50.0  # e_v^2 ~ 2400: exp() would overflow float32
    for objective in (PowerObjective(), TorqueObjective(), CompositeObjective()):
        cost = objective.step_cost(step)
        assert torch.isfinite(cost).all()
    assert TorqueObjective().step_cost(step)[1].item() == pytest.approx(
        101.0 * math.exp(5.0), rel=1e-5
    )
    # the tracking cost itself is not capped
    assert TrackingObjective().step_cost(step)[1].item() == pytest.approx(
        49.0**2 + 0.4**2 + 0.04, rel=1e-5
    )
    # below the cap eqs. 7-8 hold exactly: a robot standing still under the fastest command
    step.base_lin_vel[1] = torch.tensor([0.0, 0.0, 0.0])
    step.command[1] = torch.tensor([1.25, 0.0, 0.0])
    step.base_ang_vel[1] = torch.tensor([0.0, 0.0, 0.5])
    assert TorqueObjective().step_cost(step)[1].item() == pytest.approx(
        101.0 * math.exp(1.25**2 + 0.25), rel=1e-5
    )
