"""The PyBullet engine's joint-space armature: MuJoCo adds each joint's armature (the
reflected rotor inertia) to the joint-space mass matrix; Bullet has no such term, so the
engine takes the torque the armature would absorb off the motor torque (`_armature_torque`),
and in the "foot_link" mode also folds a foot joint's armature into its foot link's inertia.
`ArmatureMixin` is the part of `Engine` that holds this state and does the correction."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pybullet as p
from coadapt_plugins.simulators.pybullet.spec import EnvSpec


class ArmatureMixin:
    """The armature side of `Engine` (which sets k, num_joints, clients, bodies, joint_ids,
    physics_dt, fixed_base and armature before calling `_init_armature`)."""

    def _init_armature(self, j: int) -> None:
        """Per env the armature [J], the positions of the actuated joints in Bullet's mass
        matrix, and the last step's velocities and applied torques, from which the other
        generalized forces follow."""
        self.armature_diag = np.zeros((self.k, j))  # [k, J] kg m^2
        # "foot_link": per env, the actuated joints whose armature sits in their foot link's
        # inertia (Bullet's mass matrix then carries it and its coupling to the joints above)
        self.folded: list[np.ndarray] = [np.zeros(0, dtype=int) for _ in range(self.k)]
        # [k, J] inertia added about the two axes perpendicular to a folded joint's (so
        # that the foot's principal moments stay physical, `urdf._physical`)
        self.folded_extra = np.zeros((self.k, j))
        self.mass_block: list[tuple] = [np.ix_(np.arange(j), np.arange(j)) for _ in range(self.k)]
        self._diag = np.arange(j)
        self.movable: list[list[int]] = [[] for _ in range(self.k)]
        self.movable_order: list[np.ndarray | None] = [None] * self.k
        self.prev_dq = np.zeros((self.k, j))  # [k, J]
        self.prev_applied = np.zeros((self.k, j))  # [k, J]
        self.fresh = np.ones(self.k, dtype=bool)  # [k] no physics step since reset

    def _urdf_armature(self, spec: EnvSpec) -> dict[str, float] | None:
        """Joint name -> armature to write into the URDF's link inertia (None: none)."""
        if spec.joint_armature is not None and self.armature == "link_inertia":
            return dict(zip(spec.joint_names, spec.joint_armature, strict=True))
        if spec.joint_armature is not None and self.armature == "foot_link":
            folded = set(foot_joints(spec))
            return {
                n: a
                for n, a in zip(spec.joint_names, spec.joint_armature, strict=True)
                if n in folded
            }
        return None

    def _fold_extra(self, e: int, spec: EnvSpec, text: str, armature: dict[str, float]) -> None:
        """Record the inertia `prepare_urdf` added about the axes perpendicular to each folded
        joint's: tr(added inertia) = a + 2 c, the extra c."""
        before, after = link_traces(spec.urdf), link_traces(text)
        children = joint_children(spec.urdf)
        for i, name in enumerate(spec.joint_names):
            if name in armature:
                link = children[name]
                self.folded_extra[e, i] = max(
                    0.0, (after[link] - before[link] - armature[name]) / 2
                )

    def _index_dofs(self, e: int, spec: EnvSpec) -> None:
        """Where each actuated joint sits among the body's degrees of freedom (Bullet's mass
        matrix: 6 base dofs first on a floating base, then the movable joints in order)."""
        client, body = self.clients[e], self.bodies[e]
        movable = [
            i
            for i in range(p.getNumJoints(body, physicsClientId=client))
            if p.getJointInfo(body, i, physicsClientId=client)[2] != p.JOINT_FIXED
        ]
        offset = 0 if self.fixed_base else 6
        self.movable[e] = movable
        # mass matrix positions come in Bullet's joint order: the actuated columns to take,
        # or None when some movable joint is not actuated (then they are read)
        self.movable_order[e] = (
            np.array([self.joint_ids[e].index(m) for m in movable])
            if sorted(movable) == sorted(self.joint_ids[e])
            else None
        )
        cols = np.array([offset + movable.index(jid) for jid in self.joint_ids[e]])
        self.mass_block[e] = np.ix_(cols, cols)
        use = self.armature in ("joint_space", "foot_link") and spec.joint_armature is not None
        self.armature_diag[e] = spec.joint_armature if use else 0.0
        folded = set(foot_joints(spec)) if use and self.armature == "foot_link" else set()
        self.folded[e] = np.array(
            [i for i, n in enumerate(spec.joint_names) if n in folded], dtype=int
        )

    def _armature_torque(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """[k, J] torque A ddq that MuJoCo's armature A (reflected rotor inertia, added to
        the joint-space mass matrix only) would absorb this step; Bullet has no armature,
        so it is taken off the motor torque.

        MuJoCo: (M + A) ddq = tau + h, h every other generalized force (gravity, Coriolis,
        damping, contacts, limits). Bullet: M ddq = tau' + h. Predicting ddq from the
        current M, the motor torque and h of the last step (h = M ddq - tau', measured)
        gives tau' = tau - A ddq. The stiff part (the PD torque) is thus exact; only h
        lags one physics step.

        "foot_link": a foot joint's armature a is already in its foot link's inertia (about
        the joint axis, plus c about the perpendicular axes where the foot's principal
        moments needed it), so Bullet's matrix is M_b = M + dM, dM = (a - c) v v^T + c W^T W,
        W the foot's angular Jacobian and v_k = W^T s the cosine between joint k's axis and
        the foot joint's axis s;
        the correction becomes tau' = tau - (A - dM) ddq, ddq = (M_b - dM + A)^-1 (tau + h).
        The contact solver then sees the foot as heavy as MuJoCo's does (without it, a light
        foot under stiff PD chattered on a bouncy ground, docs/sim-to-sim.md).
        """
        if not np.any(self.armature_diag):
            return np.zeros_like(tau)
        ddq = (dq - self.prev_dq) / self.physics_dt  # [k, J] the last step's acceleration
        mass = np.empty((self.k, self.num_joints, self.num_joints))  # [k, J, J] joint blocks
        folded_mass = np.zeros_like(mass)  # [k, J, J] dM of foot-link armature
        finite = np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1)  # [k]
        for e in range(self.k):
            if not finite[e]:  # diverged: its torque is already NaN and it will be reset
                mass[e] = np.eye(self.num_joints)
                continue
            order = self.movable_order[e]
            positions = q[e][order] if order is not None else self._movable_positions(e)
            full = np.array(
                p.calculateMassMatrix(
                    self.bodies[e], positions.tolist(), physicsClientId=self.clients[e]
                )
            )
            mass[e] = full[self.mass_block[e]]
            if self.folded[e].size:
                folded_mass[e] = self._folded_mass(e, positions)
        h = np.einsum("kij,kj->ki", mass, ddq) - self.prev_applied  # [k, J]
        h[self.fresh | ~finite] = 0.0  # nothing measured yet right after a reset
        correction = -folded_mass  # [k, J, J] A - dM
        correction[:, self._diag, self._diag] += self.armature_diag
        predicted = np.linalg.solve(mass + correction, (tau + h)[..., None])[..., 0]  # [k, J]
        self.prev_dq = dq.copy()
        self.fresh[:] = False
        return np.einsum("kij,kj->ki", correction, predicted)

    def _folded_mass(self, e: int, positions: np.ndarray) -> np.ndarray:
        """[J, J] dM of the armature folded into env e's foot links (see `_armature_torque`)."""
        client, body = self.clients[e], self.bodies[e]
        cols = self.mass_block[e][1][0]  # [J] the actuated joints' columns
        zeros = [0.0] * len(positions)
        out = np.zeros((self.num_joints, self.num_joints))
        for j in self.folded[e]:
            link = self.joint_ids[e][j]
            _, angular = p.calculateJacobian(
                body,
                link,
                [0.0, 0.0, 0.0],
                positions.tolist(),
                zeros,
                zeros,
                physicsClientId=client,
            )
            omega = np.asarray(angular)[
                :, cols
            ]  # [3, J] each column an actuated joint's world axis
            v = omega.T @ omega[:, j]  # [J] cosines with the folded joint's axis
            # added tensor a s s^T + c (1 - s s^T), s the folded joint's axis
            a, c = self.armature_diag[e, j], self.folded_extra[e, j]
            out += (a - c) * np.outer(v, v) + c * (omega.T @ omega)
        return out

    def _movable_positions(self, e: int) -> np.ndarray:
        states = p.getJointStates(self.bodies[e], self.movable[e], physicsClientId=self.clients[e])
        return np.array([s_[0] for s_ in states])


def foot_joints(spec: EnvSpec) -> list[str]:
    """Actuated joints whose child link is a foot (their armature goes into the foot link
    in the "foot_link" mode)."""
    feet = set(spec.foot_bodies)
    root = ET.fromstring(spec.urdf)
    out = []
    for joint in root.findall("joint"):
        child = joint.find("child")
        if (
            child is not None
            and child.get("link") in feet
            and joint.get("name") in spec.joint_names
        ):
            out.append(joint.get("name"))
    return out


def joint_children(urdf: str) -> dict[str, str]:
    return {
        j.get("name"): j.find("child").get("link") for j in ET.fromstring(urdf).findall("joint")
    }


def link_traces(urdf: str) -> dict[str, float]:
    """Trace of each link's inertia tensor (kg m^2)."""
    out = {}
    for link in ET.fromstring(urdf).findall("link"):
        tensor = link.find("inertial/inertia")
        if tensor is not None:
            out[link.get("name")] = sum(float(tensor.get(k, 0.0)) for k in ("ixx", "iyy", "izz"))
    return out
