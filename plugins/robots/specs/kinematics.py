"""One leg IK for any leg chain: batched forward kinematics and damped least squares in torch.

A leg is the chain of bodies from the floating base to its foot body, read from the model
at the nominal design; a design scales the links the spec names, so the chain's body
offsets are the nominal ones times the design's scales (designs rounded as `build` rounds
them). The IK places the foot body's origin at a target given relative to the leg's hip
point (the hip body's origin at the standing pose, base frame) with priority, and keeps the
foot's standing orientation as far as the chain's remaining freedom allows (the null space
of the position task): a 3-joint leg places its foot exactly; a leg with an ankle keeps its
sole as it stands. Iterations start from the standing pose, so the knee bends as it does
there. Joints off every leg chain keep their standing angle. Each design of a batch stops
iterating once its own legs have settled, so its solution is the one it gets solved alone
(bit for bit), whatever targets the others have: the rare target out of reach, which takes
every iteration, keeps only its own design iterating.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import torch

#: Newton steps at most; a design stops early once its feet's position error (m) is below
#: TOLERANCE and its last joint step below 1e-6 rad
MAX_ITERATIONS = 30
TOLERANCE = 1e-9
#: the damping of the least-squares steps (m and rad), and the largest joint step (rad)
DAMPING = 1e-9
ADAPTIVE_DAMPING = 1.0
#: the orientation task's damping: a leg with no freedom left after its foot's position
#: (three joints) gets no orientation step
SECONDARY_DAMPING = 1e-4
MAX_STEP = 0.4


@dataclass
class Chain:
    """The legs' chains as padded tensors: L legs, E elements (a body's fixed offset then at
    most one hinge; a body with several hinges is several elements), M joints per leg."""

    pos: torch.Tensor  # [L, E, 3] element offset in its parent element's frame (nominal)
    rot: torch.Tensor  # [L, E, 3, 3] element rotation relative to its parent
    scale: torch.Tensor  # [L, E, P] 1 where continuous parameter p scales the offset
    slot: torch.Tensor  # [L, E] the leg's joint slot this element turns, -1 for none
    axis: torch.Tensor  # [L, E, 3] hinge axis, element frame
    anchor: torch.Tensor  # [L, E, 3] hinge anchor, element frame
    hip_element: torch.Tensor  # [L] the element whose frame origin is the leg's hip point
    joint_index: torch.Tensor  # [L, M] the joint (policy order) of each slot, -1 for padding
    standing: torch.Tensor  # [J] standing pose
    nominal: torch.Tensor  # [P] nominal values of the continuous parameters
    decimals: int = 6
    #: [L, E] the angle at which each hinge leaves its element's frame unturned (MuJoCo's
    #: `ref`, qpos0); None: 0 for every hinge
    ref: torch.Tensor | None = None

    @property
    def num_legs(self) -> int:
        return int(self.pos.shape[0])


def _mat(quat) -> np.ndarray:
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, dtype=float))
    return out.reshape(3, 3)


def _path(model: mujoco.MjModel, base_id: int, foot: str) -> list[int]:
    """The bodies from below the base down to `foot`."""
    path, b = [], model.body(foot).id
    while b != base_id:
        if b == 0:
            raise ValueError(f"foot body '{foot}' does not hang below the base")
        path.append(b)
        b = int(model.body_parentid[b])
    return path[::-1]


def _leg_elements(model, path, joints, scaled_links, owner: dict, leg: int, hip_body: int, held=()):
    """(elements, joint indices of the leg's slots, hip element) of one leg's chain; a
    hinge of `held` is no slot: it stays at its reference (no turn)."""
    elements, slots, hip_element = [], [], 0
    for b in path:
        link = (model.body(int(model.body_parentid[b])).name, model.body(b).name)
        scale = [1.0 if link in links else 0.0 for links in scaled_links]
        hinges = [
            j
            for j in range(model.njnt)
            if model.jnt_bodyid[j] == b and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
        ]
        for k, j in enumerate(hinges or [None]):
            slot = -1
            if j is not None and model.joint(j).name in held:
                j = None
            if j is not None:
                name = model.joint(j).name
                if owner.setdefault(name, leg) != leg:
                    raise ValueError(f"joint '{name}' lies on the chains of two legs")
                slot = len(slots)
                slots.append(joints.index(name))
            first = k == 0  # the body's own offset and rotation go with its first hinge
            elements.append(
                (
                    model.body_pos[b] if first else np.zeros(3),
                    _mat(model.body_quat[b]) if first else np.eye(3),
                    scale if first else [0.0] * len(scale),
                    slot,
                    model.jnt_axis[j] if j is not None else np.zeros(3),
                    model.jnt_pos[j] if j is not None else np.zeros(3),
                    float(model.qpos0[model.jnt_qposadr[j]]) if j is not None else 0.0,
                )
            )
        if b == hip_body:
            hip_element = len(elements) - 1
    return elements, slots, hip_element


def build_chain(
    model: mujoco.MjModel,
    base: str,
    joints: list[str],
    legs: list[tuple[str, str | None]],
    scaled_links: list[set[tuple[str, str]]],
    standing: np.ndarray,
    nominal: np.ndarray,
    decimals: int = 6,
    held: frozenset = frozenset(),
) -> Chain:
    """The chains of `legs` ((foot body, hip body or None) each) in `model` (the nominal
    design); `scaled_links[p]` the links continuous parameter p scales; the hinges of `held`
    stay at their reference. `ValueError` when a foot does not hang below `base` or a joint
    lies on two legs."""
    base_id = model.body(base).id
    rows, owner = [], {}
    for leg, (foot, hip) in enumerate(legs):
        path = _path(model, base_id, foot)
        hip_body = model.body(hip).id if hip else path[0]
        if hip_body not in path:
            raise ValueError(f"hip body '{hip}' is not on the chain of foot '{foot}'")
        rows.append(_leg_elements(model, path, joints, scaled_links, owner, leg, hip_body, held))
    num_e = max(len(r[0]) for r in rows)
    num_m = max(max(len(r[1]) for r in rows), 1)
    pad = (np.zeros(3), np.eye(3), [0.0] * len(scaled_links), -1, np.zeros(3), np.zeros(3), 0.0)

    def stack(k, dtype=torch.float64):
        return torch.tensor(
            np.array([[e[k] for e in r[0] + [pad] * (num_e - len(r[0]))] for r in rows]),
            dtype=dtype,
        )

    ref = stack(6)
    return Chain(
        pos=stack(0),
        rot=stack(1),
        scale=stack(2),
        slot=stack(3, torch.long),
        axis=stack(4),
        anchor=stack(5),
        hip_element=torch.tensor([r[2] for r in rows], dtype=torch.long),
        joint_index=torch.tensor(
            [r[1] + [-1] * (num_m - len(r[1])) for r in rows], dtype=torch.long
        ),
        standing=torch.tensor(np.array(standing), dtype=torch.float64),
        nominal=torch.as_tensor(nominal, dtype=torch.float64),
        decimals=decimals,
        ref=ref if bool(ref.abs().max() > 0) else None,
    )


def _rotation(axis: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """[..., 3, 3] rotations by `angle` [...] about unit `axis` [..., 3] (Rodrigues)."""
    x, y, z = axis.unbind(-1)
    zero = torch.zeros_like(x)
    k = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], dim=-1).reshape(*x.shape, 3, 3)
    s, c = torch.sin(angle)[..., None, None], torch.cos(angle)[..., None, None]
    return torch.eye(3, dtype=axis.dtype) + s * k + (1 - c) * (k @ k)


def _basis_axis(axes: torch.Tensor) -> tuple[int, torch.Tensor]:
    """(k, signs [L]) when each of the legs' axes [L, 3] is +-e_k or zero, else (-1, ones)."""
    signs = torch.ones(axes.shape[0], dtype=axes.dtype)
    for k in range(3):
        others = axes.clone()
        others[:, k] = 0
        if others.abs().max() == 0 and bool((axes[:, k].abs() - 1).abs().max() < 1e-12):
            return k, torch.sign(axes[:, k])
    if axes.abs().max() == 0:  # no hinge at this element in any leg
        return 0, signs
    return -1, signs


def _matvec(m: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """[..., 3] m [..., 3, 3] times v [..., 3], as column sums (far faster than a batched
    matmul or a reduction over so small a dimension)."""
    m0, m1, m2 = m.unbind(-1)
    v0, v1, v2 = v[..., None].unbind(-2)
    return m0 * v0 + m1 * v1 + m2 * v2


def _inverse3(a: torch.Tensor) -> torch.Tensor:
    """[..., 3, 3] inverses of symmetric positive definite 3 x 3 matrices (cofactors)."""
    a00, a01, a02, _, a11, a12, _, _, a22 = a.flatten(-2).unbind(-1)
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    det = (a00 * c00 + a01 * c01 + a02 * c02)[..., None, None]
    cofactors = torch.stack([c00, c01, c02, c01, c11, c12, c02, c12, c22], dim=-1)
    return cofactors.unflatten(-1, (3, 3)) / det


class LegKinematics:
    """Forward kinematics and the IK of every leg of a `Chain`, batched over designs."""

    def __init__(self, chain: Chain):
        self.chain = chain
        #: elements whose hinge anchor is off their frame's origin (most are on it)
        self._anchored = [
            bool(chain.anchor[:, e].abs().max() > 0) for e in range(chain.pos.shape[1])
        ]
        #: elements whose fixed rotation is the identity (most): no product to take
        self._identity = [
            bool((chain.rot[:, e] - torch.eye(3, dtype=chain.rot.dtype)).abs().max() == 0)
            for e in range(chain.pos.shape[1])
        ]
        #: per element, (k, signs [L]) when every leg's hinge axis is +-e_k (or it has none)
        self._basis = [_basis_axis(chain.axis[:, e]) for e in range(chain.pos.shape[1])]
        basis = [b >= 0 and not a for (b, _), a in zip(self._basis, self._anchored, strict=True)]
        self._any_basis = any(basis)
        #: [L, E] the sign of each frame-axis hinge (1 elsewhere); all 1 skips the products
        self._signs = torch.stack(
            [s if b else torch.ones_like(s) for (_, s), b in zip(self._basis, basis, strict=True)],
            dim=-1,
        )
        self._unit_signs = bool((self._signs == 1).all())
        hip_elements = set(chain.hip_element.tolist())
        self._hip_element = hip_elements.pop() if len(hip_elements) == 1 else None
        #: a leg with more joints than its foot's position needs keeps the foot's orientation
        self._redundant = int(chain.joint_index.shape[1]) > 3
        #: [1, L, 1, M] 1 for the slots that are joints (None: no padding), and [1, L, M, 1]
        #: the element each turns (None: slot s turns element s on every leg)
        valid = chain.joint_index >= 0
        self._slot_mask = None if valid.all() else valid.to(torch.float64)[None, :, None, :]
        element = self._element_of_slot()
        identity = element.shape[1] == chain.pos.shape[1] and bool(
            (element == torch.arange(element.shape[1])).all()
        )
        self._slot_element = None if identity else element.clamp(min=0)[None, :, :, None]
        self._eye3 = torch.eye(3, dtype=torch.float64)
        self._eye_slots = torch.eye(int(chain.joint_index.shape[1]), dtype=torch.float64)
        self._damping_eye3 = DAMPING * self._eye3
        self._secondary_eye3 = SECONDARY_DAMPING * self._eye3

    def scales(self, designs: torch.Tensor) -> torch.Tensor:
        """[n, L, E] each element offset's scale for designs [n, D] (continuous part first)."""
        c = self.chain
        p = c.nominal.numel()
        unit = 10.0**c.decimals
        values = torch.round(designs[:, :p].to(torch.float64) * unit) / unit
        logs = torch.log(values / c.nominal)  # [n, P]
        return torch.exp(torch.einsum("lep,np->nle", c.scale, logs))

    def leg_angles(self, q: torch.Tensor) -> torch.Tensor:
        """[n, L, M] each leg's slot angles from full joint vectors q [n, J]."""
        index = self.chain.joint_index.clamp(min=0)
        return q[:, index] * (self.chain.joint_index >= 0)

    def forward(self, scales: torch.Tensor, x: torch.Tensor):
        """(foot [n, L, 3], foot rotation [n, L, 3, 3], hip [n, L, 3], axes [n, L, E, 3],
        anchors [n, L, E, 3]) in the base frame for slot angles x [n, L, M]."""
        return self._forward(self.offsets(scales), x)

    def offsets(self, scales: torch.Tensor) -> torch.Tensor:
        """[n, L, E, 3] each element's offset for the element scales [n, L, E] (`scales`)."""
        return self.chain.pos * scales[..., None]

    def _forward(self, offsets: torch.Tensor, x: torch.Tensor):
        """`forward` from the element offsets [n, L, E, 3]. The frame's rotation is kept as
        its three columns, turned in place by hinges about a frame axis (most), so a chain of
        them takes no matrix products and no stacking until the end."""
        c = self.chain
        n, num_l = x.shape[0], c.num_legs
        eye = torch.eye(3, dtype=x.dtype)
        cols = [eye[:, k].expand(n, num_l, 3) for k in range(3)]  # the rotation's columns
        pos = torch.zeros(n, num_l, 3, dtype=x.dtype)
        axes, anchors, hips = [], [], []
        angle_all = torch.gather(x, 2, c.slot.clamp(min=0).expand(n, -1, -1)) * (c.slot >= 0)
        if c.ref is not None:  # MuJoCo turns a hinge by its angle less its ref
            angle_all = angle_all - c.ref
        if self._any_basis:  # every hinge about a frame axis at once (elementwise, as each)
            signed = angle_all if self._unit_signs else angle_all * self._signs
            sin_all, cos_all = torch.sin(signed)[..., None], torch.cos(signed)[..., None]
            sin_all, cos_all = sin_all.unbind(2), cos_all.unbind(2)  # E of [n, L, 1]
        # each element's offset as its three components [n, L, 1]: one view each, not nine
        components = [o.unbind(2) for o in offsets[..., None].unbind(2)]
        for e in range(c.pos.shape[1]):
            o = components[e]
            # the rotation times the offset, as column sums (`_matvec`)
            pos = pos + (cols[0] * o[0] + cols[1] * o[1] + cols[2] * o[2])
            if not self._identity[e]:
                cols = list((torch.stack(cols, dim=-1) @ c.rot[:, e]).unbind(-1))
            basis, sign = self._basis[e]
            if basis >= 0 and not self._anchored[e]:  # a hinge about a frame axis: no matmul
                axis = cols[basis] if self._unit_signs else cols[basis] * sign[:, None]
                sin, cos = sin_all[e], cos_all[e]
                i, j = (basis + 1) % 3, (basis + 2) % 3
                cols[i], cols[j] = cos * cols[i] + sin * cols[j], cos * cols[j] - sin * cols[i]
                anchor = pos
            else:
                rot = torch.stack(cols, dim=-1)
                axis = (rot @ c.axis[:, e, :, None])[..., 0]
                turn = _rotation(c.axis[:, e].expand(n, -1, -1), angle_all[:, :, e])
                if self._anchored[e]:
                    anchor = pos + (rot @ c.anchor[:, e, :, None])[..., 0]
                    pos = anchor + (rot @ turn @ (-c.anchor[:, e, :, None]))[..., 0]
                else:
                    anchor = pos
                cols = list((rot @ turn).unbind(-1))
            axes.append(axis)
            anchors.append(anchor)
            hips.append(pos)
        if self._hip_element is not None:  # every leg's hip at the same element
            hip = hips[self._hip_element]
        else:
            rows = torch.arange(n)[:, None]
            hip = torch.stack(hips, dim=2)[rows, torch.arange(num_l), c.hip_element]
        rot = torch.stack(cols, dim=-1)
        return pos, rot, hip, torch.stack(axes, dim=2), torch.stack(anchors, dim=2)

    def standing(self, designs: torch.Tensor):
        """(feet relative to hips [n, L, 3], foot rotations [n, L, 3, 3], hips [n, L, 3]) at
        the standing pose."""
        x = self.leg_angles(self.chain.standing.expand(designs.shape[0], -1))
        foot, rot, hip, _, _ = self.forward(self.scales(designs), x)
        return foot - hip, rot, hip

    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        return self.standing(designs)[0]

    def inverse(
        self, designs: torch.Tensor, targets: torch.Tensor, start: torch.Tensor | None = None
    ) -> torch.Tensor:
        """[n, J] joint angles putting each foot at targets [n, L, 3] (relative to its hip),
        iterated from the chain's standing pose or from `start` [J] (the feet's standing
        orientations, a redundant leg's secondary goal, stay the standing pose's).

        Each design's legs stop iterating once they have settled (every foot within
        TOLERANCE of its target after a last joint step below 1e-6 rad, from the third
        iteration on), so the few targets out of reach, which take every iteration, do not
        keep the whole batch iterating (`benchmarks/leg_ik.py`)."""
        c = self.chain
        q = c.standing.expand(designs.shape[0], -1).clone()
        # no autograd bookkeeping unless a gradient is asked for: the iterations are many
        # small operations, and on few designs their dispatch is most of the time
        with torch.inference_mode(not (designs.requires_grad or targets.requires_grad)):
            x = self._solve(designs, targets, start)
        valid = c.joint_index >= 0
        q[:, c.joint_index[valid]] = x[:, valid]
        return q

    def _solve(self, designs: torch.Tensor, targets: torch.Tensor, start=None) -> torch.Tensor:
        """[n, L, M] the slot angles of `inverse`."""
        n = designs.shape[0]
        first = self.chain.standing if start is None else start.to(self.chain.standing)
        x = self.leg_angles(first.expand(n, -1)).clone()
        _, want_rot, hip = self.standing(designs)
        goal = targets.to(torch.float64) + hip
        rows = torch.arange(n)  # the designs still iterating
        part = (x, self.offsets(self.scales(designs)), goal, want_rot)  # their slices
        settled = torch.zeros(n, dtype=torch.bool)
        for it in range(MAX_ITERATIONS):
            foot, rot, _, axes, anchors = self._forward(part[1], part[0])
            err_p = part[2] - foot  # [m, L, 3]
            if it >= 2:
                done = settled & (err_p.abs().amax(dim=(1, 2)) < TOLERANCE)
                if bool(done.any()):
                    x[rows[done]] = part[0][done]
                    keep = ~done
                    if not bool(keep.any()):
                        return x
                    rows, settled = rows[keep], settled[keep]
                    part = tuple(t[keep] for t in part)
                    foot, rot, axes, anchors = foot[keep], rot[keep], axes[keep], anchors[keep]
                    err_p = err_p[keep]
            step = self._step(part[0], foot, rot, axes, anchors, err_p, part[3])
            part = (part[0] + step, *part[1:])
            settled = step.abs().amax(dim=(1, 2)) < 1e-6
        x[rows] = part[0]
        return x

    def _step(self, x, foot, rot, axes, anchors, err_p, want_rot) -> torch.Tensor:
        """[m, L, M] one damped least-squares step of the slot angles x [m, L, M] from the
        forward kinematics at x, the position errors err_p [m, L, 3] and the feet's standing
        rotations want_rot [m, L, 3, 3]."""
        m, mask, eye3 = x.shape[0], self._slot_mask, self._eye3
        if self._slot_element is None:  # slot s turns element s on every leg (most chains)
            a, r = axes, anchors  # [m, L, M, 3]
        else:
            index = self._slot_element.expand(m, -1, -1, 3)
            a, r = torch.gather(axes, 2, index), torch.gather(anchors, 2, index)
        jac_p = torch.cross(a, foot[:, :, None] - r, dim=-1).transpose(-1, -2)
        jac_o = a.transpose(-1, -2)  # [m, L, 3, M]
        if mask is not None:  # padded slots
            jac_p, jac_o = jac_p * mask, jac_o * mask
        # Levenberg-Marquardt damping: grows with the error, so an unreachable target is
        # approached without the steps blowing up at the stretched leg's singularity
        damping = DAMPING + ADAPTIVE_DAMPING * (err_p * err_p).sum(-1)[..., None, None]
        gram = jac_p @ jac_p.transpose(-1, -2)
        if self._redundant:  # both inverses at once (elementwise, as each alone)
            both = torch.stack([gram + damping * eye3, gram + self._damping_eye3])
            damped, undamped = _inverse3(both).unbind(0)
        else:
            damped = _inverse3(gram + damping * eye3)
        solved = _matvec(damped, err_p)  # [m, L, 3]
        # J^T (J J^T + damping)^-1 e, as a sum of J's rows
        rows, weights = jac_p.unbind(-2), solved[..., None].unbind(-2)
        step = rows[0] * weights[0] + rows[1] * weights[1] + rows[2] * weights[2]
        if self._redundant:  # the exact null space: the damped one would leak into position
            exact = jac_p.transpose(-1, -2) @ undamped
            null = self._eye_slots - exact @ jac_p
            jo_n = jac_o @ null
            pinv_o = jo_n.transpose(-1, -2) @ _inverse3(
                jo_n @ jo_n.transpose(-1, -2) + self._secondary_eye3
            )
            # [m, L, 3] the rotation from the foot's to its standing one
            have, want = rot.unbind(-1), want_rot.unbind(-1)
            err_o = torch.cross(have[0], want[0], dim=-1) + torch.cross(have[1], want[1], dim=-1)
            err_o = 0.5 * (err_o + torch.cross(have[2], want[2], dim=-1))
            keep = pinv_o @ (err_o - (jac_o @ step[..., None])[..., 0])[..., None]
            step = step + (null @ keep)[..., 0]
        step = step.clamp(-MAX_STEP, MAX_STEP)
        return step if mask is None else step * mask[:, :, 0]

    def _element_of_slot(self) -> torch.Tensor:
        """[L, M] the element each joint slot turns (-1 for padding)."""
        c = self.chain
        out = torch.full(c.joint_index.shape, -1, dtype=torch.long)
        for leg in range(c.num_legs):
            for e, slot in enumerate(c.slot[leg].tolist()):
                if slot >= 0:
                    out[leg, slot] = e
        return out
