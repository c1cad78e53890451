"""The batched MuJoCo backend: every environment its own design, stepped in C on a thread
pool by `mujoco.batch.Batch`, with the shared actuation law (torch, on zero-copy views of
the batch's state) applied per physics step.

One `Batch` holds all environments. Its model is the first design's compiled model; the
model fields in which other designs (and the per-environment randomization) differ are
*expanded* to per-simulation values, so a design change or a reset rewrites a few rows of a
few arrays and never rebuilds the batch. See docs/simulators.md for the measurements behind
this choice (expand vs `set_models` vs `mujoco.rollout`).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import mujoco
import mujoco.batch
import numpy as np
import torch
from coadapt_plugins.simulators.mujoco.compose import (
    CONTACT_SENSOR_DIM,
    CompiledDesign,
    ModelCache,
    terrain_normal,
)

from coadapt_core import threads
from coadapt_core.errors import UserError
from coadapt_core.physics.actuation import DelayLine, bind_speed, pd_torque
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import SimState, Simulator, quat_rotate, spawn_base_height

if TYPE_CHECKING:
    from coadapt_core.robot import Robot

#: |qvel| above this (rad/s or m/s) counts as a blow-up: no walking robot gets near it
MAX_QVEL = 1e3
#: each environment's MuJoCo clock restarts here at reset, so that MuJoCo resetting a
#: simulation itself on a bad state (clock back to 0) is always visible
RESET_CLOCK = 1.0

#: MuJoCo's warnings for a bad state, after which it resets the simulation itself
_BAD_STATE_WARNINGS = [
    int(mujoco.mjtWarning.mjWARN_BADQPOS),
    int(mujoco.mjtWarning.mjWARN_BADQVEL),
    int(mujoco.mjtWarning.mjWARN_BADQACC),
]
#: attributes holding arrays bound to the batch (they keep it and its threads alive)
_BOUND = (
    "_qpos",
    "_qvel",
    "_ctrl",
    "_time",
    "_xpos",
    "_sensordata",
    "_cdof",
    "_subtree_com",
    "_warnings",
)
#: seed of the fixed environment-to-batch-row shuffle (load balance across threads)
ROW_SHUFFLE_SEED = 0x5EED
#: model fields never expanded per design (MuJoCo options, shared by the whole batch)
_SKIP_PREFIX = ("opt.",)

#: shared across simulator instances: a PSO iteration re-uses the compilations of the last.
#: A Kuafu model is about 0.03 MB (0.19 MB with the random terrain's height field).
_CACHE = ModelCache(capacity=256)


#: restitution calibration: a 40 kg box dropped at 1 m/s onto the plane (dt 5 ms, MuJoCo's
#: default solref time constant 0.02 s and solimp) rebounds with speed ratio RESTITUTION_MEASURED
#: at contact damping ratio RESTITUTION_DAMPRATIO (docs/simulators.md). Below 0.5 a resting
#: contact rings in a sustained 50 Hz limit cycle; above 1 MuJoCo softens the contact
#: (its stiffness scales with 1 / dampratio^2). So the reachable bounce is [0.14, 0.33].
RESTITUTION_DAMPRATIO = np.array([1.0, 0.8, 0.6, 0.5])
RESTITUTION_MEASURED = np.array([0.139, 0.191, 0.276, 0.328])


def restitution_to_dampratio(restitution: np.ndarray) -> np.ndarray:
    """Contact damping ratio (solref[1]) whose measured bounce is `restitution`, clamped to
    the reachable [0.14, 0.33]: 0 (and anything up to 0.14) is MuJoCo's default 1.0."""
    e = np.asarray(restitution, dtype=float)
    return np.interp(e, RESTITUTION_MEASURED, RESTITUTION_DAMPRATIO)


class MujocoSimulator(Simulator):
    """MuJoCo 4 batched backend (`mujoco.batch`), one compiled model per design."""

    name = "mujoco"
    default_rank = 10  # the default --sim (the reference backend)
    description = "MuJoCo 4 on a C thread pool (mujoco.batch), one model per design, CPU"
    model_formats = ("mjcf",)  # the robot model it compiles
    renderer = "coadapt_plugins.simulators.mujoco.render"  # pictures and videos, offscreen
    speed_limit_modes = ("soft", "binding")  # coadapt_core.physics.actuation, `bind_speed`
    gain_laws = (
        "robot",
        "nominal",
    )  # models compiled through self.robot (a NominalGains is its own cache key)
    model_tools = "coadapt_plugins.simulators.mujoco.model_tools"  # link facts, feet, handoff check

    def __init__(self, robot: Robot, designs: np.ndarray, **options: Any):
        """The `Simulator` options (terrain, randomization, physics_dt, decimation, seed,
        device, num_threads, fixed_base), checked by the base class."""
        super().__init__(robot, designs, **options)
        self._normal = terrain_normal(self.terrain_model)
        n = self.num_envs
        self._n = n
        compiled = [self._compile(d) for d in self._designs]
        ref = compiled[0]
        self._ref = ref
        self._j = ref.robot_model.num_joints
        # the process's thread budget unless told (--threads; `coadapt_core.threads`)
        self._threads = self.num_threads if self.num_threads is not None else threads.budget()
        # Environment e lives in batch row _row[e]. mujoco.batch hands each thread one
        # contiguous block of rows, so a fixed shuffle spreads each design's agents (and
        # whatever makes some environments costlier, such as falling) over all threads.
        self._row = (
            np.random.default_rng(ROW_SHUFFLE_SEED).permutation(n)
            if ROW_SHUFFLE_SEED is not None
            else np.arange(n)
        )  # [N] env -> row
        self._env_of_row = np.argsort(self._row)  # [N] row -> env
        self._env_of_row_t = torch.from_numpy(self._env_of_row)
        self._batch = mujoco.batch.Batch(ref.model, n, nthread=self._threads)
        b = self._batch
        self._qpos = b.bind("qpos")  # [N, nq] live state rows
        self._qvel = b.bind("qvel")  # [N, nv]
        self._ctrl = b.bind("ctrl")  # [N, nu]
        self._time = b.bind("time")  # [N]
        self._warnings = b.warning  # [N, mjNWARNING, 2] live (last info, count)
        self._warnings_seen = self._warnings[:, _BAD_STATE_WARNINGS, 1].copy()  # [N, 3]
        self._xpos = b.bind("xpos")  # [N, nbody, 3], refreshed after each call
        self._sensordata = b.bind("sensordata")  # [N, nsensordata]
        self._cdof = b.bind(
            "cdof"
        )  # [N, nv, 6] motion axes (angular, linear) at the root subtree's CoM
        self._subtree_com = b.bind("subtree_com")  # [N, nbody, 3]
        self._foot_root = ref.model.body_rootid[
            ref.foot_body_ids
        ]  # [L] root body of each foot's tree
        self._foot_dofs = [self._ancestor_dofs(ref.model, body) for body in ref.foot_body_ids]
        self._sensor_adr = np.array(
            [
                ref.model.sensor_adr[
                    mujoco.mj_name2id(ref.model, mujoco.mjtObj.mjOBJ_SENSOR, "coadapt_contact_" + f)
                ]
                for f in ref.robot_model.foot_bodies
            ]
        )
        # contiguous joint blocks read as slices (no gather in the hot loop)
        self._q_index = self._as_slice(ref.qpos_adr)
        self._dq_index = self._as_slice(ref.dof_adr)
        self._act_index = self._as_slice(ref.actuator_ids)
        # the actuation law reads joint state through zero-copy torch views of the live rows
        # (views only when the joints are contiguous; otherwise gathered per physics step)
        self._q_view = self._joint_view(self._qpos, self._q_index)
        self._dq_view = self._joint_view(self._qvel, self._dq_index)

        # per-environment model fields: those the designs differ in, plus randomization's
        self._expanded: dict[str, np.ndarray] = {}
        for name in (
            "geom_friction",
            "geom_solref",
            "body_ipos",
            "body_pos",
            "dof_damping",
            "dof_armature",
        ):
            self._expanded[name] = b.expand(name)
        self._design_fields: set[str] = set()
        self._field_diff_cache: dict[int, tuple[CompiledDesign, list[str]]] = {}

        j = self._j
        self._kp = np.zeros((n, j))  # [N, J] row order, as every per-environment array here
        self._kd = np.zeros((n, j))
        self._tau_max = np.zeros((n, j))
        self._dq_max = np.zeros((n, j))
        self._gains = tuple(
            torch.from_numpy(a) for a in (self._kp, self._kd, self._tau_max, self._dq_max)
        )
        self._default_q = np.zeros((n, j))
        self._standing_height = np.zeros(n)
        self._foot_xy = np.zeros((n, len(ref.robot_model.foot_bodies), 2))
        self._foot_radius = np.zeros(n)
        self._base_ipos = np.zeros((n, 3))  # [N, 3] the design's base CoM, before the shift
        self._geom_friction = np.zeros((n, ref.model.ngeom, 3))
        self._geom_solref = np.zeros((n, ref.model.ngeom, 2))
        self._dof_damping = np.zeros(
            (n, ref.model.nv)
        )  # [N, nv] the design's own, before randomization
        self._dof_armature = np.zeros((n, ref.model.nv))
        self._base_pos0 = np.zeros((n, 3))
        self._write_designs(self._row, compiled)

        # the actuation runs where the physics state lives: on the CPU, in float64
        self._delay = DelayLine(n, j, self.max_delay_steps(), dtype=self.dtype)
        self._pd_factor = torch.ones(
            n, dtype=self.dtype
        )  # [N] row order, of the parameters in force
        self._motor_strength = torch.ones(n, dtype=self.dtype)
        self._torque = np.zeros((n, j))  # [N, J] mean applied torque of the last policy step
        self._tau = np.zeros((n, j))  # [N, J] scratch, one physics step
        self._tau_t = torch.from_numpy(self._tau)
        self._diverged = np.zeros(n, dtype=bool)
        self._expected_time = np.zeros(n)
        self._state: SimState | None = None
        self.divergence_count = 0
        #: seconds spent in physics / actuation / state extraction (benchmark breakdown)
        self.timings = {"physics": 0.0, "actuation": 0.0, "state": 0.0}
        #: set to a list to receive each physics step's ctrl [N, nu] (open-loop replay)
        self.record_controls: list[np.ndarray] | None = None
        self._reset_rows(self._row, draw=False)
        self._state = self._build_state()

    # -- construction helpers ------------------------------------------------------------
    @staticmethod
    def _as_slice(index: np.ndarray) -> slice | np.ndarray:
        index = np.asarray(index, dtype=int)
        if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
            return slice(int(index[0]), int(index[0] + index.size))
        return index

    @staticmethod
    def _joint_view(live: np.ndarray, index: slice | np.ndarray) -> torch.Tensor | None:
        return torch.from_numpy(live[:, index]) if isinstance(index, slice) else None

    def _joint_state(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(q, dq) [N, J] of the actuated joints, row order, as float64 tensors."""
        q = (
            self._q_view
            if self._q_view is not None
            else torch.from_numpy(self._qpos[:, self._q_index])
        )
        dq = (
            self._dq_view
            if self._dq_view is not None
            else torch.from_numpy(self._qvel[:, self._dq_index])
        )
        return q, dq

    @staticmethod
    def _ancestor_dofs(model: mujoco.MjModel, body: int) -> np.ndarray:
        """Degrees of freedom that move `body` (its own and its ancestors')."""
        dofs = []
        while body > 0:
            start, count = model.body_dofadr[body], model.body_dofnum[body]
            dofs.extend(range(start, start + count))
            body = model.body_parentid[body]
        return np.array(sorted(dofs), dtype=int)

    def _compile(self, design: np.ndarray) -> CompiledDesign:
        return _CACHE.get(
            self.robot,
            design,
            self.terrain_model,
            physics_dt=self.physics_dt,
            fixed_base=self.fixed_base,
        )

    def _diff_fields(self, item: CompiledDesign) -> list[str]:
        """Model fields in which `item` differs from the batch's reference model."""
        key = id(item)
        cached = self._field_diff_cache.get(key)
        if cached is not None and cached[0] is item:
            return cached[1]
        ref, other = self._ref.model, item.model
        if item is self._ref:
            self._field_diff_cache[key] = (item, [])
            return []
        if (ref.nq, ref.nv, ref.nu, ref.nbody, ref.ngeom, ref.nsensordata) != (
            other.nq,
            other.nv,
            other.nu,
            other.nbody,
            other.ngeom,
            other.nsensordata,
        ) or not (
            np.array_equal(item.qpos_adr, self._ref.qpos_adr)
            and np.array_equal(item.actuator_ids, self._ref.actuator_ids)
            and np.array_equal(item.foot_body_ids, self._ref.foot_body_ids)
        ):
            raise UserError(
                f"design {np.round(item.robot_model.design, 4).tolist()} changes the model's structure "
                "(bodies, joints, geoms or actuators); one MuJoCo batch needs designs that differ only in "
                "parameters",
                field="designs",
            )
        out = []
        for name in mujoco.batch.MODEL_FIELDS:
            if name.startswith(_SKIP_PREFIX):
                continue
            try:
                a, c = getattr(ref, name), getattr(other, name)
            except AttributeError:
                continue
            a, c = np.asarray(a), np.asarray(c)
            if a.shape != c.shape:
                raise UserError(
                    f"design {np.round(item.robot_model.design, 4).tolist()} changes the size of model "
                    f"field {name}; one MuJoCo batch needs designs that differ only in parameters",
                    field="designs",
                )
            if not np.array_equal(a, c):
                out.append(name)
        # holding `item` keeps its id from being reused by a later compilation
        self._field_diff_cache[key] = (item, out)
        return out

    def _write_designs(self, rows: np.ndarray, compiled: list[CompiledDesign]) -> None:
        """Copy each design's model fields and actuator facts into its batch rows."""
        groups: dict[int, tuple[CompiledDesign, list[int]]] = {}
        for row, item in zip(rows, compiled, strict=True):
            groups.setdefault(id(item), (item, []))[1].append(int(row))
        for item, _ in groups.values():
            for name in self._diff_fields(item):
                if name not in self._expanded:
                    self._expanded[name] = self._batch.expand(name)
                self._design_fields.add(name)
        for item, envs in groups.values():
            ids = np.array(envs)
            m = item.model
            for name in self._design_fields:
                self._expanded[name][ids] = np.asarray(getattr(m, name))
            rm = item.robot_model
            self._kp[ids] = rm.kp
            self._kd[ids] = rm.kd
            self._tau_max[ids] = rm.torque_limit
            self._dq_max[ids] = rm.speed_limit
            self._default_q[ids] = rm.default_joint_pos
            self._standing_height[ids] = rm.standing_base_height
            self._foot_xy[ids] = item.foot_xy_offset
            self._foot_radius[ids] = item.foot_radius
            self._base_ipos[ids] = m.body_ipos[item.base_body_id]
            self._geom_friction[ids] = m.geom_friction
            self._geom_solref[ids] = m.geom_solref
            self._dof_damping[ids] = m.dof_damping
            self._dof_armature[ids] = m.dof_armature
            self._base_pos0[ids] = m.body_pos[item.base_body_id]

    # -- sizes and facts -----------------------------------------------------------------
    @property
    def num_joints(self) -> int:
        return self._j

    @property
    def default_joint_pos(self) -> torch.Tensor:
        import torch

        return torch.as_tensor(self._default_q[self._row], dtype=torch.float32, device=self.device)

    @property
    def num_threads_used(self) -> int:
        """The threads of the batch's pool, as MuJoCo reports them."""
        return int(self._batch.nthread)

    def env_model(self, env: int) -> mujoco.MjModel:
        """A copy of environment `env`'s model with its design and randomization."""
        return self._live().get_model(int(self._row[int(env)]))

    def rows(self, env_ids: np.ndarray | int) -> np.ndarray:
        """Batch rows of environments (for reading the live bound arrays in tests and tools)."""
        return self._row[env_ids]

    # -- control -------------------------------------------------------------------------
    def _live(self) -> mujoco.batch.Batch:
        if self._batch is None:
            raise RuntimeError("this MujocoSimulator was closed")
        return self._batch

    def reset(self, env_ids: torch.Tensor | np.ndarray | None = None) -> SimState:
        rows = self._row[self.parse_env_ids(env_ids)]
        self._live()
        self._reset_rows(rows)
        self._diverged[rows] = False
        self._state = self._build_state()
        return self._state

    def _reset_rows(self, ids: np.ndarray, draw: bool = True) -> None:
        """New parameters, spawn pose and clean delay line for batch rows `ids` (in the
        order of the environments asked for); others untouched.
        `draw=False` (construction) keeps the parameters in force and spawns at the origin,
        consuming no randomness: the first `reset()` makes the first draw, as in every
        backend, so one seed gives one set of parameters everywhere."""
        if ids.size == 0:
            return
        b = self._live()
        envs = self._env_of_row[ids]
        params = self.draw_env_params(envs) if draw else self._params.take(envs)
        rows = torch.from_numpy(ids)
        self._pd_factor[rows] = params.pd_factor.cpu()
        self._motor_strength[rows] = params.motor_strength.cpu()
        delay_steps = params.delay_steps(self.physics_dt).clamp(max=self._delay.capacity - 1)
        params = params.numpy()
        # Table 2 parameters living in the model: sliding friction of every geom (MuJoCo
        # combines a contact's two geoms by max, so robot and terrain both carry it),
        # restitution as contact damping, base CoM shift
        friction = self._geom_friction[ids].copy()
        friction[..., 0] = params["friction"][:, None]
        self._expanded["geom_friction"][ids] = friction
        solref = self._geom_solref[ids].copy()
        solref[..., 1] = restitution_to_dampratio(params["restitution"])[:, None]
        # engine robustness (RandomizationConfig.contact_timeconst, joint_damping, armature):
        # contact softness, extra damping and armature of the robot's joints; a contact time
        # constant left at its nominal point keeps the model's own
        if self._timeconst_randomized():
            solref[..., 0] = params["contact_timeconst"][:, None]
        self._expanded["geom_solref"][ids] = solref
        dofs = self._dq_index
        damping = self._dof_damping[ids].copy()
        damping[:, dofs] += params["joint_damping"][:, None]
        self._expanded["dof_damping"][ids] = damping
        armature = self._dof_armature[ids].copy()
        armature[:, dofs] *= params["armature"][:, None]
        self._expanded["dof_armature"][ids] = armature
        base = self._ref.base_body_id
        ipos = self._expanded["body_ipos"]
        ipos[ids, base] = self._base_ipos[ids] + params["com_shift"]

        # spawn: standing height above the highest ground under either foot
        xy = self.draw_spawn_xy(envs) if draw else np.zeros((ids.size, 2))
        z = spawn_base_height(
            self.terrain_model,
            xy,
            self._foot_xy[ids],
            self._foot_radius[ids],
            self._standing_height[ids],
            fixed_base=self.fixed_base,
        )
        if self.fixed_base:
            body_pos = self._expanded["body_pos"]
            body_pos[ids, base] = np.column_stack([xy, z])
        batch_ids = np.unique(ids)  # mujoco.batch takes sorted, unique ids
        b.set_const(batch_ids)
        b.reset(batch_ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        if not self.fixed_base:
            self._qpos[ids, 0:2] = xy
            self._qpos[ids, 2] = z
            self._qpos[ids, 3:7] = (1.0, 0.0, 0.0, 0.0)
        q = self._qpos[ids]
        q[:, self._q_index] = self._default_q[ids]
        self._qpos[ids] = q
        self._qvel[ids] = 0.0
        self._ctrl[ids] = 0.0
        self._time[ids] = RESET_CLOCK
        b.forward(batch_ids, stage=mujoco.mjtStage.mjSTAGE_ACC)
        self._delay.reset(ids, torch.from_numpy(self._default_q[ids]))
        self._delay.set_delay(ids, delay_steps)
        self._expected_time[ids] = RESET_CLOCK
        self._warnings_seen[ids] = self._warnings[ids][:, _BAD_STATE_WARNINGS, 1]
        self._torque[ids] = 0.0

    def _timeconst_randomized(self) -> bool:
        lo, hi = self.randomization.contact_timeconst
        nominal = RandomizationConfig.NOMINAL["contact_timeconst"]
        return self.randomization.enabled and not (lo == hi == nominal)

    def set_designs(self, env_ids: torch.Tensor | np.ndarray, designs: np.ndarray) -> None:
        ids, designs = self.parse_new_designs(env_ids, designs)
        self._live()
        compiled = [self._compile(d) for d in designs]
        rows = self._row[ids]
        self._write_designs(rows, compiled)
        self._designs[ids] = designs
        self._reset_rows(rows)
        self._diverged[rows] = False
        self._state = self._build_state()

    def step(self, joint_targets: torch.Tensor) -> SimState:
        b = self._live()
        if not isinstance(joint_targets, torch.Tensor):
            joint_targets = torch.as_tensor(np.asarray(joint_targets, dtype=float), device="cpu")
        targets = joint_targets.detach().to("cpu", self.dtype)  # [N, J] environment order
        if tuple(targets.shape) != (self._n, self._j):
            raise UserError(
                f"joint_targets must be [{self._n}, {self._j}], got {tuple(targets.shape)}",
                field="joint_targets",
            )
        targets = targets[self._env_of_row_t]  # [N, J] row order, as everything below
        timings = self.timings
        perf = time.perf_counter
        self._torque[:] = 0.0
        diverged = np.zeros(self._n, dtype=bool)
        for _sub in range(self.decimation):
            t0 = perf()
            # coadapt_core.physics.actuation: delayed target, PD, strength, torque-speed envelope
            self._delay.push(targets)
            q, dq = self._joint_state()  # [N, J]
            pd_torque(
                self._delay.current(),
                q,
                dq,
                *self._gains,
                self._pd_factor,
                self._motor_strength,
                out=self._tau_t,
            )
            if self.speed_limit == "binding":
                bind_speed(self._tau_t, dq, self._gains[3])
            tau = self._tau  # the numpy face of _tau_t
            self._ctrl[:, self._act_index] = tau
            self._torque += tau
            if self.record_controls is not None:
                self.record_controls.append(self._ctrl.copy())
            t1 = perf()
            failed = None
            try:
                b.step()
            except mujoco.batch.SimulationError as exc:
                failed = np.asarray(exc.ids, dtype=int)
            t2 = perf()
            self._expected_time += self.physics_dt
            # MuJoCo resets a simulation itself on a bad state: its warning counter rises and
            # its clock restarts; NaN or huge speeds are caught before that happens
            bad = np.abs(self._time - self._expected_time) > 0.5 * self.physics_dt
            warnings = self._warnings[:, _BAD_STATE_WARNINGS, 1]  # [N, 3] counts so far
            bad |= (warnings > self._warnings_seen).any(axis=1)
            self._warnings_seen[:] = warnings
            speed = np.abs(self._qvel).max(axis=1)
            bad |= ~(speed <= MAX_QVEL)  # also catches NaN
            if failed is not None and failed.size:
                bad[failed] = True
            if bad.any():
                ids = np.flatnonzero(bad)
                diverged[ids] = True
                self.divergence_count += ids.size
                self._reset_rows(ids)
            timings["actuation"] += t1 - t0
            timings["physics"] += t2 - t1
        self._torque /= self.decimation
        self._torque[diverged] = 0.0
        self._diverged = diverged
        t3 = perf()
        self._state = self._build_state()
        timings["state"] += perf() - t3
        return self._state

    def get_state(self) -> SimState:
        if self._state is None:
            self._state = self._build_state()
        return self._state

    # -- state -----------------------------------------------------------------------------
    def _build_state(self) -> SimState:
        import torch

        n = self._n
        order = self._row  # row-order arrays below are gathered into environment order
        qpos, qvel = self._qpos[order], self._qvel[order]
        if self.fixed_base:
            base_pos = self._xpos[order, self._ref.base_body_id]
            base_quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
            lin_vel = np.zeros((n, 3))
            ang_vel = np.zeros((n, 3))
        else:
            base_pos = qpos[:, 0:3]
            base_quat = qpos[:, 3:7]
            lin_vel = qvel[:, 0:3]  # free joint: linear velocity in the world frame
            ang_vel = quat_rotate(base_quat, qvel[:, 3:6])  # free joint: angular in the body frame
        sd = self._sensordata[order]
        found = np.stack([sd[:, a] for a in self._sensor_adr], axis=1)  # [N, L] number of contacts
        force = np.stack(
            [sd[:, a + 1 : a + CONTACT_SENSOR_DIM] for a in self._sensor_adr], axis=1
        )  # [N, L, 3]
        normal_force = np.abs(force @ self._normal)  # [N, L]
        terrain_h = self.terrain_model.height_at(base_pos[:, :2])  # [N]

        def f32(x: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))

        state = SimState(
            base_pos=f32(base_pos),
            base_quat=f32(base_quat),
            base_lin_vel=f32(lin_vel),
            base_ang_vel=f32(ang_vel),
            joint_pos=f32(qpos[:, self._q_index]),
            joint_vel=f32(qvel[:, self._dq_index]),
            joint_torque=f32(self._torque[order]),
            foot_pos=f32(self._foot_positions()[order]),
            foot_contact=torch.from_numpy(found > 0),
            foot_contact_force=f32(normal_force),
            terrain_height=f32(terrain_h),
            diverged=torch.from_numpy(self._diverged[order]),
        )
        if str(self.device) != "cpu":
            state = state.to(self.device)
        return state

    def _foot_positions(self) -> np.ndarray:
        """[N, L, 3] foot body origins at the current state.

        Derived fields (xpos, cdof) describe the state before the last physics step, as
        with mj_step. Recomputing the position stage would cost half a physics step (it
        includes collision detection). Instead each origin moves by dt times its velocity
        under the new joint velocities (MuJoCo's Euler step moves positions with the new
        velocities), which is exact to first order, impacts included (tests check < 2 mm).
        """
        qvel = self._qvel
        out = np.empty((self._n, len(self._foot_dofs), 3))
        for leg, (body, dofs) in enumerate(
            zip(self._ref.foot_body_ids, self._foot_dofs, strict=True)
        ):
            twist = np.einsum("nds,nd->ns", self._cdof[:, dofs], qvel[:, dofs])  # [N, 6]
            pos = self._xpos[:, body]  # [N, 3]
            lever = pos - self._subtree_com[:, self._foot_root[leg]]
            out[:, leg] = pos + self.physics_dt * (twist[:, 3:] + np.cross(twist[:, :3], lever))
        return out

    def close(self) -> None:
        """Join the batch's threads and free its memory: the bound arrays keep the batch
        alive, so they go too."""
        self._batch = None
        for name in _BOUND:
            setattr(self, name, None)
        self._q_view = self._dq_view = None
        self._expanded = {}
        self.record_controls = None
