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

import numpy as np
import pybullet as p
import torch
from coadapt_plugins.simulators.pybullet.armature import ArmatureMixin
from coadapt_plugins.simulators.pybullet.divergence import diverged
from coadapt_plugins.simulators.pybullet.loops import add_loops
from coadapt_plugins.simulators.pybullet.spec import EnvSpec
from coadapt_plugins.simulators.pybullet.urdf import prepare_urdf
from coadapt_plugins.simulators.pybullet.world import open_world, renew_world

from coadapt_core.physics.actuation import DelayLine, bind_speed, pd_torque
from coadapt_core.physics.simulator import spawn_base_height
from coadapt_core.physics.terrain import Terrain


class Engine(ArmatureMixin):
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
        self._init_actuation(self.num_joints, max_delay_steps)
        self._init_armature(self.num_joints)
        self._init_bodies()
        for _ in range(self.k):
            client, ground = open_world(self.terrain, self.physics_dt, self.solver_iterations)
            self.clients.append(client)
            self.grounds.append(ground)
        for e in range(self.k):
            self._load(e, self.specs[e])
        self.reset(np.arange(self.k), _nominal_params(self.k))

    def _init_actuation(self, j: int, max_delay_steps: int) -> None:
        """Per env the PD law's inputs [k, J], the randomized factors [k] and the delay line."""
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

    def _init_bodies(self) -> None:
        """Per env its client, terrain bodies, robot body and the ids and frames read from it."""
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

    # -- world ---------------------------------------------------------------------------
    def _urdf_path(self, e: int, spec: EnvSpec, com_shift: np.ndarray) -> str:
        armature = self._urdf_armature(spec)
        text = prepare_urdf(spec.urdf, spec.base_body, com_shift=com_shift, armature=armature)
        if self.armature == "foot_link" and armature:
            self._fold_extra(e, spec, text, armature)
        # a new name per load: PyBullet caches files by path and would reuse a stale one
        self._loads += 1
        path = os.path.join(self._tmpdir, f"env{e}-{self._loads}.urdf")
        with open(path, "w") as f:
            f.write(text)
        for name, content in spec.urdf_files.items():  # named by their content's hash
            mesh = os.path.join(self._tmpdir, os.path.basename(name))
            if not os.path.exists(mesh):
                with open(mesh, "w") as f:
                    f.write(content)
        return path

    def _load(self, e: int, spec: EnvSpec, com_shift: np.ndarray | None = None) -> None:
        """(Re)load environment e's robot from its URDF (a new design or a new CoM shift)."""
        client = self.clients[e]
        shift = np.zeros(3) if com_shift is None else np.asarray(com_shift, dtype=float)
        if self.bodies[e] >= 0:  # its world renewed, not the body removed (`renew_world`)
            self.grounds[e] = renew_world(
                client, self.terrain, self.physics_dt, self.solver_iterations
            )
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
        add_loops(client, body, names, spec.loops, self.joint_ids[e])  # a four-bar's pins
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
        state["diverged"] = broken | diverged(state)
        return state

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
