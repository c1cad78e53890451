"""Conformance suite for `Objective` plugins. Supply a fixture `objective` (an instance)."""

from __future__ import annotations

import pytest

from coadapt_core.objective import Objective, StepBatch


def make_step(n: int = 16, joints: int = 8, seed: int = 0, scale: float = 1.0) -> StepBatch:
    import torch

    g = torch.Generator().manual_seed(seed)
    return StepBatch(
        command=torch.rand(n, 3, generator=g) * scale,
        base_lin_vel=torch.rand(n, 3, generator=g) * scale,
        base_ang_vel=torch.rand(n, 3, generator=g) * scale,
        joint_torque=(torch.rand(n, joints, generator=g) - 0.5) * 100 * scale,
        joint_vel=(torch.rand(n, joints, generator=g) - 0.5) * 10 * scale,
        action=torch.rand(n, joints, generator=g) * scale,
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
        single = StepBatch(**{k: getattr(step, k)[3:4] for k in step.__dataclass_fields__})
        assert torch.allclose(full[3:4], objective.step_cost(single))

    def test_improvement_sign(self, objective: Objective) -> None:
        assert objective.improvement(0.5, 1.0) > 0
        assert objective.improvement(2.0, 1.0) < 0
        assert objective.improvement(1.0, 1.0) == pytest.approx(0.0)
