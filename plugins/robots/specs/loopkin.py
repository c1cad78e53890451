"""The leg IK of legs closed by spec `loops` (four-bar legs): the generic leg IK
(`kinematics`) on every hinge, passive ones included, over three sets of chains: the legs'
(to their feet), and per loop the chain to its first body (the pin on the leg's own half: its
foot, or a `pins` body on it) and to its second (the other half's end; its hip the first
body on it that turns).

A design's standing toe (`default_foot_positions`) is where the leg's foot lies once the two
halves meet with the motors at the standing pose: the passive hinges solved (Gauss-Newton,
finite differences, batched over designs) so that each loop's two bodies come nearest, as the
built model closes them (`loops`). A target for a leg's toe (`inverse`) is solved for the
leg's chain, then the other half is solved to where that puts the pin (offset as the two lie
at that design's closed standing pose: along the hinges' axis), and the motors' angles are
returned.
"""

from __future__ import annotations

import numpy as np
import torch
from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain
from coadapt_plugins.robots.specs.loops import loop_leg
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
        base = model.body(prepared.base).id
        feet = [leg.foot for leg in rs.legs]
        self.owner = []
        for k, (a, _, _) in enumerate(rs.loops):
            leg = loop_leg(model, base, feet, a)
            if leg is None:
                raise spec_error(f"loops[{k}].bodies", f"'{a}' is on no leg's chain")
            self.owner.append(leg)
        self.num_legs, self.num_joints = len(feet), len(prepared.joints)
        joints = [*prepared.joints, *prepared.passive]
        standing = np.concatenate([prepared.standing, prepared.passive_seeds])

        def kin(ends):
            return LegKinematics(
                build_chain(model, prepared.base, joints, ends, links, standing, nominal, decimals)
            )

        self.legs = kin([(leg.foot, leg.hip) for leg in rs.legs])
        self.pins = kin([(a, _hip_of(model, base, a)) for a, _, _ in rs.loops])
        self.others = kin([(b, _hip_of(model, base, b)) for _, b, _ in rs.loops])
        self.chain = self.legs.chain
        index = self.others.chain.joint_index
        self._other_joints = sorted({int(j) for j in index.flatten() if j >= 0})

    def _closed(self, designs: torch.Tensor):
        """(feet, hips [n, L, 3]; the loops' pins, the other halves' ends and their hips
        [n, K, 3]; base frame) at each design's closed standing pose."""
        n = designs.shape[0]
        scales = [k.scales(designs) for k in (self.legs, self.pins, self.others)]
        q = self.chain.standing.expand(n, -1).clone()
        passive = list(range(self.num_joints, q.shape[1]))

        def ends(kin, scale, angles):
            foot, _, hip, _, _ = kin.forward(scale, kin.leg_angles(angles))
            return foot, hip

        def gaps(angles):
            pin = ends(self.pins, scales[1], angles)[0]
            return (pin - ends(self.others, scales[2], angles)[0]).reshape(n, -1)

        for _ in range(ITERATIONS):
            gap = gaps(q)
            columns = []
            for j in passive:
                moved = q.clone()
                moved[:, j] += DELTA
                columns.append((gaps(moved) - gap) / DELTA)
            step = -(torch.linalg.pinv(torch.stack(columns, dim=-1), rtol=1e-10) @ gap[..., None])
            q[:, passive] += step[..., 0].clamp(-0.5, 0.5)
            if float(step.abs().max()) < 1e-12:
                break
        foot, hip = ends(self.legs, scales[0], q)
        pin = ends(self.pins, scales[1], q)[0]
        other, other_hip = ends(self.others, scales[2], q)
        return foot, hip, pin, other, other_hip

    def scales(self, designs: torch.Tensor) -> torch.Tensor:
        """[n, L, E] the legs' chains' element scales (`LegKinematics.scales`)."""
        return self.legs.scales(designs)

    def standing(self, designs: torch.Tensor):
        """(toes relative to hips [n, L, 3], None, hips [n, L, 3]) at the closed standing
        pose."""
        foot, hip, _, _, _ = self._closed(designs)
        return foot - hip, None, hip

    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        return self.standing(designs)[0]

    def inverse(self, designs: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """[n, J] the motors' angles putting each leg's toe at targets [n, L, 3] (relative to
        its hip), the other half of each loop solved to the pin."""
        _, _, pin, other, other_hip = self._closed(designs)
        q = self.legs.inverse(designs, targets)
        moved = self.pins.forward(self.pins.scales(designs), self.pins.leg_angles(q))[0]
        q_other = self.others.inverse(designs, moved + other - pin - other_hip)
        q[:, self._other_joints] = q_other[:, self._other_joints]
        return q[:, : self.num_joints]
