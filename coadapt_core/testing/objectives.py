"""Conformance suite for `Objective` plugins. Supply a fixture `objective` (an instance)."""

from __future__ import annotations

import pytest

from coadapt_core.objective import Objective, StepBatch


def make_step(
    n: int = 16,
    joints: int = 8,
    seed: int = 0,
    scale: float = 1.0,
    legs: int = 2,
    design_dim: int = 2,
) -> StepBatch:
    """A random step of `n` environments with every field of `StepBatch` filled."""
    import torch

    g = torch.Generator().manual_seed(seed)
    return StepBatch(
        command=torch.rand(n, 3, generator=g) * scale,
        base_lin_vel=torch.rand(n, 3, generator=g) * scale,
        base_ang_vel=torch.rand(n, 3, generator=g) * scale,
        joint_torque=(torch.rand(n, joints, generator=g) - 0.5) * 100 * scale,
        joint_vel=(torch.rand(n, joints, generator=g) - 0.5) * 10 * scale,
        joint_targets=(torch.rand(n, joints, generator=g) - 0.5) * scale,
        design=0.5 + torch.rand(n, design_dim, generator=g),
        total_mass=5.0 + 10.0 * torch.rand(n, generator=g),
        base_height=0.3 + 0.5 * torch.rand(n, generator=g),
        foot_contact=torch.rand(n, legs, generator=g) < 0.5,
        dt=0.02,
    )


def standing_step(n: int = 6, joints: int = 8, legs: int = 2, design_dim: int = 2) -> StepBatch:
    """A robot standing still under zero commands: every velocity and command 0, feet down,
    joints holding the pose (torques only against gravity). Costs that divide by speed or by
    the command must stay finite here."""
    import torch

    step = make_step(n=n, joints=joints, legs=legs, design_dim=design_dim, seed=9)
    zero3 = torch.zeros(n, 3)
    return StepBatch(
        command=zero3,
        base_lin_vel=zero3.clone(),
        base_ang_vel=zero3.clone(),
        joint_torque=step.joint_torque * 0.2,
        joint_vel=torch.zeros(n, joints),
        joint_targets=step.joint_targets,
        design=step.design,
        total_mass=step.total_mass,
        base_height=step.base_height,
        foot_contact=torch.ones(n, legs, dtype=torch.bool),
        dt=step.dt,
    )


class ObjectiveConformance:
    """Every objective: one finite cost per environment, deterministic, labelled."""

    def test_calls_the_base_initialiser(self, objective: Objective) -> None:
        """A constructor of its own calls `super().__init__(**options)`: the base class checks
        the options and fills in their defaults (`self.options`)."""
        assert hasattr(objective, "options"), (
            "Objective.__init__ did not run (no `self.options`): call super().__init__(**options)"
        )
        declared = {s.name for s in type(objective).option_specs}
        assert set(objective.options) >= declared

    def test_standing_still_and_zero_commands_give_finite_costs(self, objective: Objective) -> None:
        """A robot standing still (zero speed, zero joint speed, feet down) under a zero
        command, alone and beside moving ones: a real rollout has such steps (a fallen-back
        robot, a command of 0)."""
        import torch

        still = standing_step(n=6)
        cost = objective.step_cost(still)
        assert cost.shape == (6,) and torch.isfinite(cost).all(), (
            f"non-finite cost when standing still: {cost}"
        )
        moving = make_step(n=6, seed=3)
        mixed = StepBatch(
            **{
                f: (
                    getattr(still, f)
                    if f == "dt"
                    else torch.cat([getattr(still, f), getattr(moving, f)])
                )
                for f in StepBatch.__dataclass_fields__
            }
        )
        cost = objective.step_cost(mixed)
        assert cost.shape == (12,) and torch.isfinite(cost).all(), (
            f"non-finite cost beside moving robots: {cost}"
        )

    def test_is_objective_with_labels(self, objective: Objective) -> None:
        assert isinstance(objective, Objective)
        assert objective.name and objective.display_name
        assert objective.direction == "minimize"

    def test_one_finite_cost_per_env(self, objective: Objective) -> None:
        import torch

        step = make_step(n=13)
        cost = objective.step_cost(step)
        assert cost.shape == (13,)
        assert torch.isfinite(cost).all()

    def test_deterministic(self, objective: Objective) -> None:
        import torch

        a = objective.step_cost(make_step(seed=4))
        b = objective.step_cost(make_step(seed=4))
        assert torch.equal(a, b)

    def test_envs_independent(self, objective: Objective) -> None:
        """The cost of env i depends only on env i's row."""
        import torch

        step = make_step(n=8, seed=2)
        full = objective.step_cost(step)
        assert torch.allclose(full[3:4], objective.step_cost(step.rows(slice(3, 4))))

    @pytest.mark.parametrize("joints,legs", [(4, 2), (12, 4)])
    def test_any_joint_and_leg_count(self, objective: Objective, joints: int, legs: int) -> None:
        """Robots differ: a cost must not assume Kuafu's 8 joints or two legs."""
        import torch

        cost = objective.step_cost(make_step(n=5, joints=joints, legs=legs))
        assert cost.shape == (5,) and torch.isfinite(cost).all()

    def test_declared_options_are_well_formed(self, objective: Objective) -> None:
        from coadapt_core.options import check_specs

        specs = check_specs(type(objective).option_specs, objective.name)
        if specs:  # built with no options, every default is in force
            assert set(objective.options) >= {s.name for s in specs}

    def test_improvement_sign(self, objective: Objective) -> None:
        assert objective.improvement(0.5, 1.0) > 0
        assert objective.improvement(2.0, 1.0) < 0
        assert objective.improvement(1.0, 1.0) == pytest.approx(0.0)
