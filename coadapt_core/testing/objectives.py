"""Conformance suite for `Objective` plugins. Supply a fixture `objective` (an instance)."""

from __future__ import annotations

import pytest

from coadapt_core.objective import Objective, StepBatch


def make_step(
    n: int = 16, joints: int = 8, seed: int = 0, scale: float = 1.0, legs: int = 2, design_dim: int = 2
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


class ObjectiveConformance:
    """Every objective: one finite cost per environment, deterministic, labelled."""

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
