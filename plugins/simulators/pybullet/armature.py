"""The PyBullet engine's joint-space armature: MuJoCo adds each joint's armature (the
reflected rotor inertia) to the mass matrix; Bullet has no such term, so the engine takes
the torque the armature would absorb off the motor torque (`_armature_torque`, predicted over
all of the body's generalized velocities, the floating base's included), and in the
"foot_link" mode also folds the armature of the last actuated joint above each foot into that
joint's child link. `ArmatureMixin` is the part of `Engine` that holds this state and does the
correction."""

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
        # per env the actuated joints' positions among the body's generalized velocities
        self.columns: list[np.ndarray] = [np.arange(j) for _ in range(self.k)]
        self.movable: list[list[int]] = [[] for _ in range(self.k)]
        self.movable_order: list[np.ndarray | None] = [None] * self.k
        self.prev_u: list[np.ndarray] = [np.zeros(0) for _ in range(self.k)]  # [D] each
        self.prev_applied = np.zeros((self.k, j))  # [k, J]
        self.fresh = np.ones(self.k, dtype=bool)  # [k] no physics step since reset
        # per env the generalized accelerations [D] the last correction predicted (tests
        # compare them with the step Bullet took)
        self.predicted: list[np.ndarray] = [np.zeros(0) for _ in range(self.k)]

    def _urdf_armature(self, spec: EnvSpec) -> dict[str, float] | None:
        """Joint name -> armature to write into the URDF's link inertia (None: none)."""
        armature = carried_armature(spec, self.physics_dt)
        if armature is not None and self.armature == "link_inertia":
            return dict(zip(spec.joint_names, armature, strict=True))
        if armature is not None and self.armature == "foot_link":
            folded = set(folded_joints(spec))
            return {n: a for n, a in zip(spec.joint_names, armature, strict=True) if n in folded}
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
        """Where each actuated joint sits among the body's degrees of freedom: Bullet's
        generalized velocities are, on a floating base, the base's angular and then its
        linear velocity (of its centre of mass), both in the base's inertial frame, and then
        the movable joints in order (`base_velocity`; tests check it against the kinetic
        energy)."""
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
        self.columns[e] = np.array([offset + movable.index(jid) for jid in self.joint_ids[e]])
        self.prev_u[e] = np.zeros(offset + len(movable))
        self.fresh[e] = True  # a (re)loaded body: no last step to measure h over
        armature = carried_armature(spec, self.physics_dt)
        use = self.armature in ("joint_space", "foot_link") and armature is not None
        self.armature_diag[e] = armature if use else 0.0
        folded = set(folded_joints(spec)) if use and self.armature == "foot_link" else set()
        self.folded[e] = np.array(
            [i for i, n in enumerate(spec.joint_names) if n in folded], dtype=int
        )

    def _armature_torque(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """[k, J] torque A ddq that MuJoCo's armature A (reflected rotor inertia, added to
        the mass matrix's joint diagonal only) would absorb this step; Bullet has no
        armature, so it is taken off the motor torque.

        In the body's generalized velocities u (the floating base's six first): MuJoCo
        solves (M + S'AS) du = S'tau + h, S selecting the actuated joints and h every other
        generalized force (gravity, Coriolis, damping, contacts, limits); Bullet solves
        M du = S'tau' + h. Predicting du from the current M, the motor torque and h of the
        last step (h = M du - S'tau', measured) gives tau' = tau - A S du. The stiff part
        (the PD torque) is thus exact; only h lags one physics step. The base's rows count:
        a joint's acceleration moves the base back, and predicted from the joints' block of
        M alone (as before issue 49) that reaction entered the lagged h, which made a light
        leg under a large armature (Qilin's) unstable on its feet.

        "foot_link": a foot joint's armature a is already in its foot link's inertia (about
        the joint axis, plus c about the perpendicular axes where the foot's principal
        moments needed it), so Bullet's matrix is M_b = M + dM, dM = (a - c) v v' + c W'W,
        W the foot's angular Jacobian and v = W's the projection of every velocity on the
        foot joint's axis s; the correction becomes tau' = tau - S(S'AS - dM) du. The base's
        rows of dM cannot be applied (no motor drives the base): the folded inertia stays in
        the base's own motion. The contact solver then sees the foot as heavy as MuJoCo's
        does (without it, a light foot under stiff PD chattered on a bouncy ground,
        docs/sim-to-sim.md).

        du is predicted as Bullet will take it: K du = S'tau + h, K's joint rows those of
        M_b - dM + S'AS (what the correction makes of them, MuJoCo's) and its base's rows
        Bullet's own, M_b's, the folded inertia in them. Predicted with M_b - dM + S'AS in
        every row (as before issue 58), the base was taken as lighter than Bullet moves it,
        and the folded joints' coupling to it, -dM on the base's columns, fed that error
        into the motor torque: where the folded armature outweighs the links it sits in
        (the ant's 1 kg m^2 on legs turning 0.008-0.022, minitaur_derpy's motors at 9-13 x)
        the correction diverged or tipped the robot over. Without a folded joint (or on a
        fixed base) both are the same.
        """
        out = np.zeros_like(tau)
        if not np.any(self.armature_diag):
            return out
        finite = np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1)  # [k]
        for e in range(self.k):
            if not finite[e]:  # diverged: its torque is already NaN and it will be reset
                self.fresh[e] = True
                continue
            order = self.movable_order[e]
            positions = q[e][order] if order is not None else self._movable_states(e, 0)
            mass = np.array(
                p.calculateMassMatrix(
                    self.bodies[e], positions.tolist(), physicsClientId=self.clients[e]
                )
            )  # [D, D]
            cols = self.columns[e]
            u = self._velocities(e, dq[e][order] if order is not None else None)  # [D]
            force = np.zeros(len(u))  # [D] S'tau
            force[cols] = tau[e]
            if not self.fresh[e]:  # h, measured over the last step; nothing right after a reset
                force += mass @ ((u - self.prev_u[e]) / self.physics_dt)
                force[cols] -= self.prev_applied[e]
            correction = -self._folded_mass(e, positions, len(u))  # [D, D] S'AS - dM
            correction[cols, cols] += self.armature_diag[e]
            system = mass + correction  # [D, D] the joints' rows: MuJoCo's M + S'AS
            if not self.fixed_base:  # the base's: Bullet's own, the folded inertia in them
                system[:6] = mass[:6]
            predicted = np.linalg.solve(system, force)  # [D] du, the step Bullet takes
            out[e] = (correction @ predicted)[cols]
            self.predicted[e] = predicted
            self.prev_u[e] = u
            self.fresh[e] = False
        return out

    def _velocities(self, e: int, movable_dq: np.ndarray | None) -> np.ndarray:
        """[D] env e's generalized velocities in Bullet's mass matrix's order."""
        if movable_dq is None:
            movable_dq = self._movable_states(e, 1)
        if self.fixed_base:
            return np.asarray(movable_dq, dtype=float)
        return np.concatenate([base_velocity(self.clients[e], self.bodies[e]), movable_dq])

    def _folded_mass(self, e: int, positions: np.ndarray, size: int) -> np.ndarray:
        """[D, D] dM of the armature folded into env e's foot links (see `_armature_torque`)."""
        out = np.zeros((size, size))
        if not self.folded[e].size:
            return out
        client, body = self.clients[e], self.bodies[e]
        zeros = [0.0] * len(positions)
        for j in self.folded[e]:
            _, angular = p.calculateJacobian(
                body,
                self.joint_ids[e][j],
                [0.0, 0.0, 0.0],
                positions.tolist(),
                zeros,
                zeros,
                physicsClientId=client,
            )
            omega = np.asarray(angular)  # [3, D] in the base frame, as the mass matrix
            v = omega.T @ omega[:, self.columns[e][j]]  # [D] projections on the joint's axis
            # added tensor a s s' + c (1 - s s'), s the folded joint's axis
            a, c = self.armature_diag[e, j], self.folded_extra[e, j]
            out += (a - c) * np.outer(v, v) + c * (omega.T @ omega)
        return out

    def _movable_states(self, e: int, which: int) -> np.ndarray:
        """[movable] positions (which=0) or velocities (1) of env e's movable joints."""
        states = p.getJointStates(self.bodies[e], self.movable[e], physicsClientId=self.clients[e])
        return np.array([s_[which] for s_ in states])


def carried_armature(spec: EnvSpec, physics_dt: float) -> np.ndarray | None:
    """[J] kg m^2 the joints carry beyond Bullet's mass matrix: MuJoCo's armature, plus h d
    where MuJoCo's integrator takes a joint's damping d implicitly (`EnvSpec.implicit_damping`,
    h the physics step). MuJoCo's velocity update then solves (M + A + h D) dv = h f, f
    with -D v in it: Bullet applies -D v (its joint damping) but solves with M alone, so an
    explicit PD law that MuJoCo's step keeps stable could chatter on Bullet's. pybullet_data's
    humanoid at its 6 x gains: the ankle roll turns 0.0043 kg m^2 under a 0.0006 armature and
    damping 1 N m s/rad, h d = 0.005 more than doubles it (kd h / I from 6.99 to 3.2); without
    it both ankles chattered from 0.36 s and the robot fell, with it PyBullet holds it 3 s as
    MuJoCo does (docs/sim-to-sim.md). None when the spec has no MJCF dynamics."""
    if spec.joint_armature is None:
        return None
    if not spec.implicit_damping or spec.joint_damping is None:
        return spec.joint_armature
    return spec.joint_armature + physics_dt * spec.joint_damping


def base_velocity(client: int, body: int) -> np.ndarray:
    """[6] the floating base's angular velocity and its centre of mass's linear velocity,
    both in the base's inertial frame: the first six generalized velocities of Bullet's
    `calculateMassMatrix` and `calculateJacobian` on a floating base."""
    _, orn = p.getBasePositionAndOrientation(body, physicsClientId=client)
    linear, angular = p.getBaseVelocity(body, physicsClientId=client)
    rotation = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
    return np.concatenate([rotation.T @ np.asarray(angular), rotation.T @ np.asarray(linear)])


def foot_joints(spec: EnvSpec) -> list[str]:
    """The last actuated joint above each foot: an actuated joint whose child link is a foot
    or carries one through fixed joints only (Kuafu's ankle turns its foot link; Qilin's
    knee turns the calf its foot sphere is fixed to). Their armature goes into that child
    link in the "foot_link" mode."""
    feet = set(spec.foot_bodies)
    joints = ET.fromstring(spec.urdf).findall("joint")
    fixed: dict[str, list[str]] = {}  # link -> the links fixed to it
    for joint in joints:
        if joint.get("type") == "fixed":
            fixed.setdefault(joint.find("parent").get("link"), []).append(
                joint.find("child").get("link")
            )

    def carries_foot(link: str) -> bool:
        return link in feet or any(carries_foot(child) for child in fixed.get(link, []))

    return [
        joint.get("name")
        for joint in joints
        if joint.get("name") in spec.joint_names and carries_foot(joint.find("child").get("link"))
    ]


#: armature over turned inertia above which "foot_link" folds a joint (`folded_joints`)
FOLD_RATIO = 2.0


def folded_joints(spec: EnvSpec) -> list[str]:
    """The joints whose armature the "foot_link" mode folds into their child link: the last
    actuated joint above each foot (`foot_joints`) and every joint whose armature is more
    than `FOLD_RATIO` times the inertia it turns at the standing pose
    (`EnvSpec.joint_inertia`). There the joint-space correction's one-step-late h outweighs
    the joint's own dynamics: nezha's ankle pitch (armature 0.01 kg m^2, 3.3 times the 0.003
    it turns, behind a 0.074 kg link) left in joint space made its policy fall on PyBullet
    (docs/sim-to-sim.md); the folded foot joints of Kuafu and Qilin are at 2.7 and 2.8 at
    their nominal designs. Every other joint of the three robots, nominal design and corners,
    is at most 1.54 times (Qilin's hips at its shortest design, which walks on PyBullet
    unfolded), so Kuafu's and Qilin's sets stay their foot joints."""
    feet = foot_joints(spec)
    if spec.joint_armature is None or spec.joint_inertia is None:
        return feet
    heavy = {
        n
        for n, a, i in zip(spec.joint_names, spec.joint_armature, spec.joint_inertia, strict=True)
        if a > FOLD_RATIO * i
    }
    return [n for n in spec.joint_names if n in heavy or n in feet]


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
