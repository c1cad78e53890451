"""The PyBullet engine: a slice of environments, one DIRECT physics client each.

The same class runs in-process (small batches) and inside each worker process (large
batches), so both modes give identical numbers. Every environment lives alone in its own
client at the world origin on its own copy of the terrain: a trajectory never depends on
which other environments share a process. Arrays over the slice are [k, ...].
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET

import numpy as np
import pybullet as p
import torch
from coadapt_plugins.simulators.pybullet.spec import EnvSpec
from coadapt_plugins.simulators.pybullet.urdf import prepare_urdf

from coadapt_core.physics.actuation import DelayLine, bind_speed, pd_torque
from coadapt_core.physics.simulator import spawn_base_height
from coadapt_core.physics.terrain import Terrain

#: gravity, m/s^2 (MuJoCo's default)
GRAVITY = 9.81
#: random terrain: the safety floor lies this far below z = 0 (as in MuJoCo), m
FLOOR_BELOW_FIELD = 0.001
#: divergence: any state beyond these magnitudes (or not finite) resets the environment
MAX_BASE_DISTANCE = 1.0e3  # m
MAX_BASE_SPEED = 1.0e2  # m/s
MAX_ANGULAR_SPEED = 1.0e3  # rad/s (base and joints)

STATE_KEYS = (
    "base_pos",
    "base_quat",
    "base_lin_vel",
    "base_ang_vel",
    "joint_pos",
    "joint_vel",
    "joint_torque",
    "foot_pos",
    "foot_contact",
    "foot_contact_force",
)


class Engine:
    """Environments [k] of one slice; methods take local indices into the slice."""

    def __init__(
        self,
        specs: list[EnvSpec],
        *,
        terrain: str,
        terrain_seed: int,
        physics_dt: float,
        decimation: int,
        fixed_base: bool,
        max_delay_steps: int,
        armature: str = "foot_link",
        solver_iterations: int = 50,
    ):
        self.k = len(specs)
        self.terrain = Terrain(name=terrain, seed=terrain_seed)
        self.physics_dt = float(physics_dt)
        self.decimation = int(decimation)
        self.fixed_base = bool(fixed_base)
        self.armature = armature
        self.solver_iterations = int(solver_iterations)
        self._tmpdir = tempfile.mkdtemp(prefix="coadapt-pybullet-")
        self._loads = 0
        self.specs: list[EnvSpec] = list(specs)
        self.num_joints = len(specs[0].joint_names)
        self.num_feet = len(specs[0].foot_bodies)
        j = self.num_joints
        self.kp = np.zeros((self.k, j))
        self.kd = np.zeros((self.k, j))
        self.tau_max = np.zeros((self.k, j))
        self.dq_max = np.zeros((self.k, j))
        self.default_joint_pos = np.zeros((self.k, j))
        self.pd_factor = np.ones(self.k)
        self.motor_strength = np.ones(self.k)
        # zero-copy torch faces of the actuation inputs (the shared law is torch)
        self._actuation = tuple(
            torch.from_numpy(a)
            for a in (
                self.kp,
                self.kd,
                self.tau_max,
                self.dq_max,
                self.pd_factor,
                self.motor_strength,
            )
        )
        self.friction = np.ones(self.k)
        self.restitution = np.zeros(self.k)
        self.delay = DelayLine(self.k, j, max_delay_steps)
        self.binding = False  # the binding motor speed limit (`set_binding`)
        self.last_torque = np.zeros((self.k, j))  # [k, J] mean over the last policy step
        # joint-space armature (see `_armature_torque`): per env the armature [J], the
        # positions of the actuated joints in Bullet's mass matrix, and the last step's
        # velocities and applied torques, from which the other generalized forces follow
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
        self.clients: list[int] = []
        self.grounds: list[list[int]] = []  # per env: the terrain's bodies
        self.bodies: list[int] = [-1] * self.k
        self.joint_ids: list[list[int]] = [[] for _ in range(self.k)]
        self.foot_ids: list[list[int]] = [[] for _ in range(self.k)]
        self.all_links: list[list[int]] = [[] for _ in range(self.k)]
        self.loaded_shift = np.zeros((self.k, 3))
        self.foot_xy = np.zeros(
            (self.k, self.num_feet, 2)
        )  # [k, L, 2] feet around the base, default pose
        self.spawn_xy = np.zeros((self.k, 2))  # [k, 2] where each base last spawned
        # base link frame expressed in the base inertial frame (PyBullet reports the latter)
        self.inertial_pos = np.zeros((self.k, 3))
        self.inertial_quat = np.tile([0.0, 0.0, 0.0, 1.0], (self.k, 1))
        for _ in range(self.k):
            client = p.connect(p.DIRECT)
            if client < 0:
                raise RuntimeError("pybullet could not open a DIRECT physics client")
            self.clients.append(client)
            self._setup_world(client)
        for e in range(self.k):
            self._load(e, self.specs[e])
        self.reset(np.arange(self.k), _nominal_params(self.k))

    # -- world ---------------------------------------------------------------------------
    def _setup_world(self, client: int) -> None:
        p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=client)
        p.setTimeStep(self.physics_dt, physicsClientId=client)
        p.setPhysicsEngineParameter(
            numSubSteps=0,
            numSolverIterations=self.solver_iterations,
            deterministicOverlappingPairs=1,
            physicsClientId=client,
        )
        self.grounds.append(self._create_ground(client))

    def _create_ground(self, client: int) -> list[int]:
        t = self.terrain
        bodies = []
        if t.name == "random":
            grid = t.height_grid()  # [rows along y, cols along x]
            shape = p.createCollisionShape(
                p.GEOM_HEIGHTFIELD,
                meshScale=[t.resolution, t.resolution, 1.0],
                heightfieldData=grid.ravel().tolist(),
                numHeightfieldRows=t.samples,
                numHeightfieldColumns=t.samples,
                physicsClientId=client,
            )
            # Bullet centres a height field on its bounding box, heights included
            position = [0.0, 0.0, 0.5 * (float(grid.min()) + float(grid.max()))]
            # a safety floor just below the field (as in MuJoCo): a robot walking off its
            # edge lands instead of falling forever
            floor = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client)
            bodies.append(
                p.createMultiBody(
                    0, floor, basePosition=[0.0, 0.0, -FLOOR_BELOW_FIELD], physicsClientId=client
                )
            )
        else:
            angle = t.slope_radians  # 0 on flat ground; the slope rises along +x
            shape = p.createCollisionShape(
                p.GEOM_PLANE,
                planeNormal=[-np.sin(angle), 0.0, np.cos(angle)],
                physicsClientId=client,
            )
            position = [0.0, 0.0, 0.0]
        bodies.insert(0, p.createMultiBody(0, shape, basePosition=position, physicsClientId=client))
        for ground in bodies:
            # Bullet multiplies the two bodies' coefficients: 1 on the ground makes the
            # robot's own friction and restitution the ones in force
            p.changeDynamics(
                ground,
                -1,
                lateralFriction=1.0,
                restitution=1.0,
                spinningFriction=0.0,
                rollingFriction=0.0,
                physicsClientId=client,
            )
        return bodies

    def _urdf_path(self, e: int, spec: EnvSpec, com_shift: np.ndarray) -> str:
        armature = None
        if spec.joint_armature is not None and self.armature == "link_inertia":
            armature = dict(zip(spec.joint_names, spec.joint_armature, strict=True))
        elif spec.joint_armature is not None and self.armature == "foot_link":
            folded = set(_foot_joints(spec))
            armature = {
                n: a
                for n, a in zip(spec.joint_names, spec.joint_armature, strict=True)
                if n in folded
            }
        text = prepare_urdf(spec.urdf, spec.base_body, com_shift=com_shift, armature=armature)
        if self.armature == "foot_link" and armature:
            # tr(added inertia) = a + 2 c: the extra c about the perpendicular axes
            before, after = _link_traces(spec.urdf), _link_traces(text)
            children = _joint_children(spec.urdf)
            for i, name in enumerate(spec.joint_names):
                if name in armature:
                    link = children[name]
                    self.folded_extra[e, i] = max(
                        0.0, (after[link] - before[link] - armature[name]) / 2
                    )
        # a new name per load: PyBullet caches files by path and would reuse a stale one
        self._loads += 1
        path = os.path.join(self._tmpdir, f"env{e}-{self._loads}.urdf")
        with open(path, "w") as f:
            f.write(text)
        return path

    def _load(self, e: int, spec: EnvSpec, com_shift: np.ndarray | None = None) -> None:
        """(Re)load environment e's robot from its URDF (a new design or a new CoM shift)."""
        client = self.clients[e]
        shift = np.zeros(3) if com_shift is None else np.asarray(com_shift, dtype=float)
        if self.bodies[e] >= 0:
            p.removeBody(self.bodies[e], physicsClientId=client)
        path = self._urdf_path(e, spec, shift)
        body = p.loadURDF(
            path,
            basePosition=[0.0, 0.0, spec.standing_base_height + 1.0],
            useFixedBase=self.fixed_base,
            flags=p.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=client,
        )
        os.remove(path)
        self.bodies[e] = body
        self.loaded_shift[e] = shift
        names = {}
        for i in range(p.getNumJoints(body, physicsClientId=client)):
            info = p.getJointInfo(body, i, physicsClientId=client)
            names[info[1].decode()] = i  # joint name -> index
            names["link:" + info[12].decode()] = i  # child link name -> index
        missing = [n for n in spec.joint_names if n not in names]
        missing += [n for n in spec.foot_bodies if "link:" + n not in names]
        if missing:
            raise ValueError(f"URDF lacks joints/links {missing}")
        self.joint_ids[e] = [names[n] for n in spec.joint_names]
        self.foot_ids[e] = [names["link:" + n] for n in spec.foot_bodies]
        self.all_links[e] = [-1, *range(p.getNumJoints(body, physicsClientId=client))]
        for link in self.all_links[e]:
            # Bullet damps every link's motion by 0.04 by default; MuJoCo does not
            p.changeDynamics(
                body,
                link,
                linearDamping=0.0,
                angularDamping=0.0,
                maxJointVelocity=1.0e4,
                physicsClientId=client,
            )
        if spec.joint_damping is not None:
            for jid, damping in zip(self.joint_ids[e], spec.joint_damping, strict=True):
                p.changeDynamics(body, jid, jointDamping=float(damping), physicsClientId=client)
        # the default velocity motors would hold the joints; keep them only as MuJoCo's
        # dry joint friction (frictionloss): a zero-velocity motor of that much force
        frictionloss = (
            spec.joint_frictionloss
            if spec.joint_frictionloss is not None
            else np.zeros(self.num_joints)
        )
        p.setJointMotorControlArray(
            body,
            self.joint_ids[e],
            p.VELOCITY_CONTROL,
            targetVelocities=[0.0] * self.num_joints,
            forces=[float(f) for f in frictionloss],
            physicsClientId=client,
        )
        info = p.getDynamicsInfo(body, -1, physicsClientId=client)
        self.inertial_pos[e] = info[3]
        self.inertial_quat[e] = info[4]
        self.kp[e] = spec.kp
        self.kd[e] = spec.kd
        self.tau_max[e] = spec.torque_limit
        self.dq_max[e] = spec.speed_limit
        self.default_joint_pos[e] = spec.default_joint_pos
        self._apply_contact_params(e)
        self._index_dofs(e, spec)
        self.foot_xy[e] = self._foot_offsets(e, spec)

    def _foot_offsets(self, e: int, spec: EnvSpec) -> np.ndarray:
        """[L, 2] foot origins relative to the base origin at the default pose, level base."""
        client, body = self.clients[e], self.bodies[e]
        self._place_base(e, np.zeros(3))
        for jid, q in zip(self.joint_ids[e], spec.default_joint_pos, strict=True):
            p.resetJointState(body, jid, float(q), 0.0, physicsClientId=client)
        feet = p.getLinkStates(
            body, self.foot_ids[e], computeForwardKinematics=1, physicsClientId=client
        )
        return np.array([np.asarray(f[4])[:2] for f in feet])

    def _place_base(self, e: int, link_pos: np.ndarray) -> None:
        """Put the base link origin at `link_pos`, level, at rest. PyBullet places a base by
        its inertial frame: com = link * inertial offset."""
        com_pos, com_quat = p.multiplyTransforms(
            [float(v) for v in link_pos],
            [0.0, 0.0, 0.0, 1.0],
            self.inertial_pos[e].tolist(),
            self.inertial_quat[e].tolist(),
        )
        client, body = self.clients[e], self.bodies[e]
        p.resetBasePositionAndOrientation(body, com_pos, com_quat, physicsClientId=client)
        p.resetBaseVelocity(body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=client)

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
        folded = set(_foot_joints(spec)) if use and self.armature == "foot_link" else set()
        self.folded[e] = np.array(
            [i for i, n in enumerate(spec.joint_names) if n in folded], dtype=int
        )

    def _apply_contact_params(self, e: int) -> None:
        for link in self.all_links[e]:
            p.changeDynamics(
                self.bodies[e],
                link,
                lateralFriction=float(self.friction[e]),
                restitution=float(self.restitution[e]),
                spinningFriction=0.0,
                rollingFriction=0.0,
                physicsClientId=self.clients[e],
            )

    # -- commands ------------------------------------------------------------------------
    def spawn_pose(self, e: int) -> np.ndarray:
        """[3] base link origin at reset: standing height above the highest ground under
        either foot (`coadapt_core.physics.simulator.spawn_base_height`, every backend's rule)."""
        xy = self.spawn_xy[e]
        spec = self.specs[e]
        (z,) = spawn_base_height(
            self.terrain,
            xy[None],
            self.foot_xy[e][None],
            np.array([spec.foot_radius]),
            np.array([spec.standing_base_height]),
            fixed_base=self.fixed_base,
        )
        return np.array([xy[0], xy[1], z])

    def set_specs(self, env_ids: np.ndarray, specs: list[EnvSpec]) -> None:
        for e, spec in zip(np.asarray(env_ids, dtype=int), specs, strict=True):
            self.specs[e] = spec
            self._load(e, spec, self.loaded_shift[e])

    def reset(self, env_ids: np.ndarray, params: dict[str, np.ndarray]) -> None:
        """Reset environments to the standing pose with new physical parameters; `params`
        holds arrays over env_ids (friction, restitution, com_shift, pd_factor,
        motor_strength, delay_steps, spawn_xy)."""
        env_ids = np.asarray(env_ids, dtype=int)
        for i, e in enumerate(env_ids):
            self.spawn_xy[e] = params["spawn_xy"][i]
            self.friction[e] = params["friction"][i]
            self.restitution[e] = params["restitution"][i]
            self.pd_factor[e] = params["pd_factor"][i]
            self.motor_strength[e] = params["motor_strength"][i]
            # always a fresh body: Bullet keeps contact manifolds and solver warm starts of a
            # body across resetJointState, so a reused body would not repeat a trajectory
            self._load(e, self.specs[e], np.asarray(params["com_shift"][i], dtype=float))
            self._reset_pose(e)
        self.delay.set_delay(env_ids, params["delay_steps"])
        self.delay.reset(env_ids, self.default_joint_pos[env_ids])
        self.last_torque[env_ids] = 0.0
        self.prev_dq[env_ids] = 0.0
        self.prev_applied[env_ids] = 0.0
        self.fresh[env_ids] = True

    def _reset_pose(self, e: int) -> None:
        client, body = self.clients[e], self.bodies[e]
        self._place_base(e, self.spawn_pose(e))
        for jid, q in zip(self.joint_ids[e], self.default_joint_pos[e], strict=True):
            p.resetJointState(body, jid, float(q), 0.0, physicsClientId=client)

    def _joints(self) -> tuple[np.ndarray, np.ndarray]:
        q = np.empty((self.k, self.num_joints))  # [k, J]
        dq = np.empty((self.k, self.num_joints))  # [k, J]
        for e in range(self.k):
            states = p.getJointStates(
                self.bodies[e], self.joint_ids[e], physicsClientId=self.clients[e]
            )
            for j, s in enumerate(states):
                q[e, j] = s[0]
                dq[e, j] = s[1]
        return q, dq

    def set_binding(self, binding: bool) -> None:
        """No torque beyond the no-load speed from now on (`bind_speed` after `pd_torque`)."""
        self.binding = bool(binding)

    def step(self, targets: np.ndarray) -> dict[str, np.ndarray]:
        """`decimation` physics steps holding joint targets [k, J]; returns the state with
        a `diverged` flag [k] (the caller resets those environments)."""
        targets = np.asarray(targets, dtype=float)
        tau_sum = np.zeros((self.k, self.num_joints))
        broken = np.zeros(self.k, dtype=bool)
        for _ in range(self.decimation):
            self.delay.push(torch.from_numpy(targets))
            q, dq = self._joints()
            tau_t = pd_torque(
                self.delay.current(), torch.from_numpy(q), torch.from_numpy(dq), *self._actuation
            )
            if self.binding:
                bind_speed(tau_t, torch.from_numpy(dq), self._actuation[3])
            tau = tau_t.numpy()  # [k, J]
            applied = tau - self._armature_torque(q, dq, tau)  # [k, J]
            bad = ~np.isfinite(applied).all(axis=1)
            broken |= bad
            tau[bad] = 0.0  # never feed NaN to Bullet; the env is reset after this step
            applied[bad] = 0.0
            self.prev_applied = applied
            for e in range(self.k):
                p.setJointMotorControlArray(
                    self.bodies[e],
                    self.joint_ids[e],
                    p.TORQUE_CONTROL,
                    forces=applied[e].tolist(),
                    physicsClientId=self.clients[e],
                )
                p.stepSimulation(physicsClientId=self.clients[e])
            tau_sum += tau
        self.last_torque = tau_sum / self.decimation
        state = self.get_state()
        state["diverged"] = broken | _diverged(state)
        return state

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

    def get_state(self) -> dict[str, np.ndarray]:
        k, nf = self.k, self.num_feet
        com_pos = np.empty((k, 3))
        quat = np.empty((k, 4))  # (x, y, z, w) as Bullet gives it
        com_vel = np.empty((k, 3))
        ang_vel = np.empty((k, 3))
        foot_pos = np.empty((k, nf, 3))
        contact_force = np.zeros((k, nf))
        for e in range(k):
            client, body = self.clients[e], self.bodies[e]
            pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=client)
            lin, ang = p.getBaseVelocity(body, physicsClientId=client)
            com_pos[e], quat[e], com_vel[e], ang_vel[e] = pos, orn, lin, ang
            links = p.getLinkStates(
                body, self.foot_ids[e], computeForwardKinematics=1, physicsClientId=client
            )
            for f, link in enumerate(links):
                foot_pos[e, f] = link[4]  # the link frame origin, not its centre of mass
            contacts = p.getContactPoints(bodyA=body, physicsClientId=client)
            for c in contacts:
                if c[2] in self.grounds[e] and c[3] in self.foot_ids[e]:
                    contact_force[e, self.foot_ids[e].index(c[3])] += c[9]
        q, dq = self._joints()
        # base link frame = inertial frame * inverse(inertial offset)
        link_quat = np.empty((k, 4))
        base_pos = np.empty((k, 3))
        for e in range(k):
            inv_pos, inv_quat = p.invertTransform(
                self.inertial_pos[e].tolist(), self.inertial_quat[e].tolist()
            )
            pos, orn = p.multiplyTransforms(
                com_pos[e].tolist(), quat[e].tolist(), inv_pos, inv_quat
            )
            base_pos[e], link_quat[e] = pos, orn
        # velocity of the link origin: v_com + w x (origin - com)
        base_lin_vel = com_vel + np.cross(ang_vel, base_pos - com_pos)
        return {
            "base_pos": base_pos,
            "base_quat": link_quat[:, [3, 0, 1, 2]],  # (w, x, y, z)
            "base_lin_vel": base_lin_vel,
            "base_ang_vel": ang_vel,
            "joint_pos": q,
            "joint_vel": dq,
            "joint_torque": self.last_torque.copy(),
            "foot_pos": foot_pos,
            "foot_contact": contact_force > 0.0,
            "foot_contact_force": contact_force,
        }

    def inject(self, env_ids: np.ndarray, base_velocity: float) -> None:
        """Test hook: kick environments' bases to a given speed (divergence checks)."""
        for e in np.asarray(env_ids, dtype=int):
            p.resetBaseVelocity(
                self.bodies[e],
                [base_velocity, 0.0, base_velocity],
                [base_velocity, 0.0, 0.0],
                physicsClientId=self.clients[e],
            )

    def dynamics_info(self, e: int) -> dict[str, object]:
        """Masses and joint damping as loaded (tests compare them with MuJoCo's model)."""
        client, body = self.clients[e], self.bodies[e]
        masses = {}
        for link in self.all_links[e]:
            name = (
                p.getBodyInfo(body, physicsClientId=client)[0].decode()
                if link < 0
                else p.getJointInfo(body, link, physicsClientId=client)[12].decode()
            )
            masses[name] = p.getDynamicsInfo(body, link, physicsClientId=client)[0]
        return {
            "masses": masses,
            "friction": [
                p.getDynamicsInfo(body, link, physicsClientId=client)[1]
                for link in self.foot_ids[e]
            ],
            "restitution": [
                p.getDynamicsInfo(body, link, physicsClientId=client)[5]
                for link in self.foot_ids[e]
            ],
            "joint_damping": [
                p.getJointInfo(body, j, physicsClientId=client)[6] for j in self.joint_ids[e]
            ],
            "inertial_pos": self.inertial_pos[e].tolist(),
        }

    def close(self) -> None:
        for client in self.clients:
            with contextlib.suppress(Exception):  # already gone (interpreter shutdown)
                p.disconnect(physicsClientId=client)
        self.clients = []
        shutil.rmtree(self._tmpdir, ignore_errors=True)


def _diverged(state: dict[str, np.ndarray]) -> np.ndarray:
    """[k] bool: a state no physical robot reaches (or not finite)."""
    finite = np.ones(state["base_pos"].shape[0], dtype=bool)
    for key in (
        "base_pos",
        "base_quat",
        "base_lin_vel",
        "base_ang_vel",
        "joint_pos",
        "joint_vel",
        "foot_pos",
    ):
        finite &= np.isfinite(state[key]).reshape(finite.shape[0], -1).all(axis=1)
    with np.errstate(invalid="ignore"):
        huge = (
            (np.abs(state["base_pos"]).max(axis=1) > MAX_BASE_DISTANCE)
            | (np.linalg.norm(state["base_lin_vel"], axis=1) > MAX_BASE_SPEED)
            | (np.linalg.norm(state["base_ang_vel"], axis=1) > MAX_ANGULAR_SPEED)
            | (np.abs(state["joint_vel"]).max(axis=1) > MAX_ANGULAR_SPEED)
        )
    return ~finite | huge


def _nominal_params(k: int) -> dict[str, np.ndarray]:
    return {
        "friction": np.ones(k),
        "restitution": np.zeros(k),
        "com_shift": np.zeros((k, 3)),
        "pd_factor": np.ones(k),
        "motor_strength": np.ones(k),
        "delay_steps": np.zeros(k, dtype=int),
        "spawn_xy": np.zeros((k, 2)),
    }


def _foot_joints(spec: EnvSpec) -> list[str]:
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


def _joint_children(urdf: str) -> dict[str, str]:
    return {
        j.get("name"): j.find("child").get("link") for j in ET.fromstring(urdf).findall("joint")
    }


def _link_traces(urdf: str) -> dict[str, float]:
    """Trace of each link's inertia tensor (kg m^2)."""
    out = {}
    for link in ET.fromstring(urdf).findall("link"):
        tensor = link.find("inertial/inertia")
        if tensor is not None:
            out[link.get("name")] = sum(float(tensor.get(k, 0.0)) for k in ("ixx", "iyy", "izz"))
    return out
