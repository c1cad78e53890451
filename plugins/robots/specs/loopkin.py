"""The leg IK of legs closed by spec `loops` (four-bar legs): the generic leg IK
(`kinematics`) on every hinge, passive ones included, over the legs' chains and, for each
loop, the chain of its other half (its foot the loop's second body, its hip the first body on
it that turns).

A design's standing toe (`default_foot_positions`) is where the two halves meet with the
motors at the standing pose: the passive hinges solved (Gauss-Newton, finite differences,
batched over designs) so that each loop's two feet come nearest, as the built model closes
them (`loops`). A target for a leg's toe (`inverse`) is solved for both halves, the second
half's target offset from the first's as the two feet lie at that design's closed standing
pose (their offset along the hinges' axis), and the motors' angles are returned.
"""

from __future__ import annotations

import numpy as np
import torch
from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain
from coadapt_plugins.robots.specs.spec import spec_error

#: Gauss-Newton steps closing the loops, and the finite-difference step (rad)
ITERATIONS = 12
DELTA = 1e-6


def _hip_of(model, base_id: int, foot: str) -> str:
    """The first body from the base down to `foot` that holds a hinge."""
    path, b = [], model.body(foot).id
    while b not in (base_id, 0):
        path.append(b)
        b = int(model.body_parentid[b])
    hinged = [b for b in reversed(path) if model.body_jntnum[b] > 0]
    return model.body(hinged[0] if hinged else path[-1]).name


class LoopKinematics:
    """`LegKinematics`'s face (`default_foot_positions`, `inverse`, `standing`) for a robot
    whose legs are closed by `loops` (module docstring)."""

    def __init__(self, model, prepared, rs, links, nominal, decimals):
        feet = [leg.foot for leg in rs.legs]
        partners, self.owner = [], []
        for k, (a, b, _) in enumerate(rs.loops):
            if a not in feet:
                raise spec_error(
                    f"loops[{k}].bodies", f"'{a}' is not a leg's foot (the leg IK pins a foot)"
                )
            self.owner.append(feet.index(a))
            partners.append((b, _hip_of(model, model.body(prepared.base).id, b)))
        self.num_legs, self.num_joints = len(feet), len(prepared.joints)
        standing = np.concatenate([prepared.standing, prepared.passive_seeds])
        chain = build_chain(
            model, prepared.base, [*prepared.joints, *prepared.passive],
            [(leg.foot, leg.hip) for leg in rs.legs] + partners, links, standing, nominal,
            decimals,
        )  # fmt: skip
        self.inner = LegKinematics(chain)
        self.chain = chain

    def _closed(self, designs: torch.Tensor):
        """(feet [n, L+K, 3] and hips [n, L+K, 3], base frame) at each design's closed
        standing pose."""
        inner, n = self.inner, designs.shape[0]
        scales = inner.scales(designs)
        q = self.chain.standing.expand(n, -1).clone()
        passive = list(range(self.num_joints, q.shape[1]))
        owner = torch.tensor(self.owner)
        partner = torch.arange(self.num_legs, self.num_legs + len(self.owner))

        def gaps(angles):
            foot, _, hip, _, _ = inner.forward(scales, inner.leg_angles(angles))
            return (foot[:, owner] - foot[:, partner]).reshape(n, -1), foot, hip

        for _ in range(ITERATIONS):
            gap, _, _ = gaps(q)
            columns = []
            for j in passive:
                moved = q.clone()
                moved[:, j] += DELTA
                columns.append((gaps(moved)[0] - gap) / DELTA)
            jac = torch.stack(columns, dim=-1)  # [n, 3K, P]
            step = -(torch.linalg.pinv(jac, rtol=1e-10) @ gap[..., None])[..., 0]
            q[:, passive] += step.clamp(-0.5, 0.5)
            if float(step.abs().max()) < 1e-12:
                break
        _, foot, hip = gaps(q)
        return foot, hip, q

    def standing(self, designs: torch.Tensor):
        """(toes relative to hips [n, L, 3], None, hips [n, L, 3]) at the closed standing
        pose."""
        foot, hip, _ = self._closed(designs)
        legs = slice(0, self.num_legs)
        return foot[:, legs] - hip[:, legs], None, hip[:, legs]

    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        return self.standing(designs)[0]

    def inverse(self, designs: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """[n, J] the motors' angles putting each leg's toe at targets [n, L, 3] (relative to
        its hip), both halves of each loop solved to it."""
        foot, hip, _ = self._closed(designs)
        owner = torch.tensor(self.owner)
        partner = torch.arange(self.num_legs, self.num_legs + len(self.owner))
        toe = hip[:, owner] + targets[:, owner]  # [n, K, 3] base frame
        other = toe + foot[:, partner] - foot[:, owner] - hip[:, partner]
        inner_targets = torch.cat([targets, other], dim=1)
        return self.inner.inverse(designs, inner_targets)[:, : self.num_joints]
