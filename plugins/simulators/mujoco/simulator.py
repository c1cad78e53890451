"""The batched MuJoCo backend: every environment its own design, stepped in C on a thread
pool by `mujoco.batch.Batch`, with the shared actuation law (torch, on zero-copy views of
the batch's state) applied per physics step.

One `Batch` holds all environments. Its model is the first design's compiled model; the
model fields in which other designs (and the per-environment randomization) differ are
*expanded* to per-simulation values, so a design change or a reset rewrites a few rows of a
few arrays and never rebuilds the batch. See docs/simulators.md for the measurements behind
this choice (expand vs `set_models` vs `mujoco.rollout`).

MuJoCo, torch and the shared actuation (torch) are imported by the methods that use them,
not with the module, so that listing the plugins imports neither (docs/architecture.md,
"Start-up").
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from coadapt_plugins.simulators.mujoco.compose import CompiledDesign, ModelCache, terrain_normal
from coadapt_plugins.simulators.mujoco.model_diff import diff_fields
from coadapt_plugins.simulators.mujoco.row_reset import RowResetMixin, bad_state_warnings
from coadapt_plugins.simulators.mujoco.state_read import (
    StateReadMixin,
    ancestor_dofs,
    as_slice,
)

from coadapt_core import threads
from coadapt_core.errors import UserError
from coadapt_core.physics.simulator import SimState, Simulator

if TYPE_CHECKING:
    import mujoco
    import mujoco.batch
    import numpy as np
    import torch

    from coadapt_core.robot import Robot

#: |qvel| above this (rad/s or m/s) counts as a blow-up: no walking robot gets near it
MAX_QVEL = 1e3
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

#: shared across simulator instances: a PSO iteration re-uses the compilations of the last.
#: A Kuafu model is about 0.03 MB (0.19 MB with the random terrain's height field).
_CACHE = ModelCache(capacity=256)


class MujocoSimulator(RowResetMixin, StateReadMixin, Simulator):
    """MuJoCo 4 batched backend (`mujoco.batch`), one compiled model per design."""

    name = "mujoco"
    default_rank = 10  # the default --sim (the reference backend)
    description = "MuJoCo 4 on a C thread pool (mujoco.batch), one model per design, CPU"
    engine = "mujoco"  # its version goes into each run's numerics
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
        device, num_threads, fixed_base),         checked by the base class."""
        import mujoco.batch
        import numpy as np
        import torch

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
        self._bind_batch(self._batch, ref)
        self._init_design_arrays(n, self._j, ref)
        self._write_designs(self._row, compiled)
        self._init_actuation(n, self._j)
        self._reset_rows(self._row, draw=False)
        self._state = self._build_state()

    # -- construction helpers ------------------------------------------------------------
    def _bind_batch(self, b: mujoco.batch.Batch, ref: CompiledDesign) -> None:
        """Zero-copy views of the batch's live state, the rows of the contact sensors and the
        expanded (per-row) model fields."""
        import mujoco
        import numpy as np

        self._qpos = b.bind("qpos")  # [N, nq] live state rows
        self._qvel = b.bind("qvel")  # [N, nv]
        self._ctrl = b.bind("ctrl")  # [N, nu]
        self._time = b.bind("time")  # [N]
        self._warnings = b.warning  # [N, mjNWARNING, 2] live (last info, count)
        self._warnings_seen = self._warnings[:, bad_state_warnings(), 1].copy()  # [N, 3]
        self._xpos = b.bind("xpos")  # [N, nbody, 3], refreshed after each call
        self._sensordata = b.bind("sensordata")  # [N, nsensordata]
        self._cdof = b.bind(
            "cdof"
        )  # [N, nv, 6] motion axes (angular, linear) at the root subtree's CoM
        self._subtree_com = b.bind("subtree_com")  # [N, nbody, 3]
        self._foot_root = ref.model.body_rootid[
            ref.foot_body_ids
        ]  # [L] root body of each foot's tree
        self._foot_dofs = [ancestor_dofs(ref.model, body) for body in ref.foot_body_ids]
        self._sensor_adr = np.array(
            [
                ref.model.sensor_adr[
                    mujoco.mj_name2id(ref.model, mujoco.mjtObj.mjOBJ_SENSOR, "coadapt_contact_" + f)
                ]
                for f in ref.robot_model.foot_bodies
            ]
        )
        # contiguous joint blocks read as slices (no gather in the hot loop)
        self._q_index = as_slice(ref.qpos_adr)
        self._dq_index = as_slice(ref.dof_adr)
        self._act_index = as_slice(ref.actuator_ids)
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

    def _init_design_arrays(self, n: int, j: int, ref: CompiledDesign) -> None:
        """Per row the design's actuator facts, spawn facts and the model fields that
        randomization starts from (filled by `_write_designs`)."""
        import numpy as np
        import torch

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

    def _init_actuation(self, n: int, j: int) -> None:
        """The delay line, the randomized gain factors, torque buffers and the step's
        bookkeeping. The actuation runs where the physics state lives: on the CPU, in
        float64."""
        import numpy as np
        import torch

        from coadapt_core.physics.actuation import DelayLine

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

    @staticmethod
    def _joint_view(live: np.ndarray, index: slice | np.ndarray) -> torch.Tensor | None:
        import torch

        return torch.from_numpy(live[:, index]) if isinstance(index, slice) else None

    def _joint_state(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(q, dq) [N, J] of the actuated joints, row order, as float64 tensors."""
        import torch

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

    def _compile(self, design: np.ndarray) -> CompiledDesign:
        return _CACHE.get(
            self.robot,
            design,
            self.terrain_model,
            physics_dt=self.physics_dt,
            fixed_base=self.fixed_base,
        )

    def _diff_fields(self, item: CompiledDesign) -> list[str]:
        """`diff_fields` against the batch's reference model, once per compiled design."""
        key = id(item)
        cached = self._field_diff_cache.get(key)
        if cached is not None and cached[0] is item:
            return cached[1]
        out = [] if item is self._ref else diff_fields(self._ref, item)
        # holding `item` keeps its id from being reused by a later compilation
        self._field_diff_cache[key] = (item, out)
        return out

    def _write_designs(self, rows: np.ndarray, compiled: list[CompiledDesign]) -> None:
        """Copy each design's model fields and actuator facts into its batch rows."""
        import numpy as np

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
                value = np.asarray(getattr(m, name))
                target = self._expanded[name]
                if name == "bvh_aabb":  # the batch expands the bodies' volumes, not the meshes'
                    value = value[: target.shape[1]]
                target[ids] = value
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
        import mujoco.batch
        import numpy as np
        import torch

        from coadapt_core.physics.actuation import bind_speed, pd_torque

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
            warnings = self._warnings[:, bad_state_warnings(), 1]  # [N, 3] counts so far
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

    def close(self) -> None:
        """Join the batch's threads and free its memory: the bound arrays keep the batch
        alive, so they go too."""
        self._batch = None
        for name in _BOUND:
            setattr(self, name, None)
        self._q_view = self._dq_view = None
        self._expanded = {}
        self.record_controls = None
