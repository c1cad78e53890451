"""`PyBulletSimulator`: the `Simulator` interface on PyBullet, for sim-to-sim transfer.

Same semantics as the MuJoCo backend from the same robot model: torque control through
`coadapt_core.physics.actuation`, Table 2 randomization drawn by
`coadapt_core.physics.randomization` from the simulator's seed, terrains from
`coadapt_core.physics.terrain`. Small batches run in this
process; larger ones in worker processes (see `workers.py`), with identical numbers.
"""

from __future__ import annotations

import contextlib
import importlib.util
from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_core import threads
from coadapt_core.errors import DesignError, UserError
from coadapt_core.physics.simulator import SimState, Simulator

if TYPE_CHECKING:
    import numpy as np
    import torch
    from coadapt_plugins.simulators.pybullet.spec import EnvSpec

    from coadapt_core.robot import Robot

MISSING_PYBULLET = (
    "the pybullet simulator needs the pybullet package: pip install 'coadapt[pybullet]'"
)
#: batches up to this size run in-process (worker start-up and pipe traffic cost more
#: than they save below it; see docs/sim-to-sim.md)
IN_PROCESS_MAX_ENVS = 8
ARMATURE_MODES = ("foot_link", "joint_space", "link_inertia", "none")


class PyBulletMissing(UserError, ImportError):
    """PyBullet is not installed: a user error (one line, exit 2) that code guarding an
    optional backend with `except ImportError` also catches."""


def require_pybullet() -> None:
    """Raise the one-line `PyBulletMissing` naming the extra to install."""
    if importlib.util.find_spec("pybullet") is None:
        raise PyBulletMissing(MISSING_PYBULLET, field="simulator")


class PyBulletSimulator(Simulator):
    """PyBullet (Bullet 3 multibody), one DIRECT client per environment, CPU only."""

    name: ClassVar[str] = "pybullet"
    description: ClassVar[str] = (
        "PyBullet (Bullet) backend for sim-to-sim transfer; one process per CPU core for large "
        "batches"
    )
    engine: ClassVar[str] = "pybullet"  # its version goes into each run's numerics
    quiet_imports: ClassVar[tuple[str, ...]] = (
        "pybullet",
    )  # prints "pybullet build time" on import
    #: it loads the URDF and takes the joints' damping and armature from the MJCF
    model_formats: ClassVar[tuple[str, ...]] = ("urdf", "mjcf")
    speed_limit_modes: ClassVar[tuple[str, ...]] = ("soft", "binding")
    gain_laws: ClassVar[tuple[str, ...]] = ("robot", "nominal")

    def __init__(
        self,
        robot: Robot,
        designs: np.ndarray,  # [num_envs, design_dim]
        *,
        processes: int | None = None,
        armature: str = "foot_link",
        **options: Any,
    ):
        """The `Simulator` options (terrain, randomization, physics_dt, decimation, seed,
        device, num_threads, fixed_base), checked by the base class, and
        `processes`: worker processes (0 = in this process; None = in-process up to
        IN_PROCESS_MAX_ENVS environments, else `num_threads`, by default the process's
        thread budget, `coadapt_core.threads.budget()`).
        `armature`: how MJCF joint armature is carried over: "foot_link" (that of the last
        actuated joint above each foot in the link it turns, the rest as "joint_space", the
        coupling corrected), "joint_space" (taken off the motor torque as A ddq, ddq
        predicted from Bullet's mass matrix over every generalized velocity, the floating
        base's included), "link_inertia" (added to the child link's inertia) or "none"; see
        docs/sim-to-sim.md."""
        import numpy as np

        require_pybullet()
        super().__init__(robot, designs, **options)
        if armature not in ARMATURE_MODES:
            raise UserError(
                f"armature must be one of {', '.join(ARMATURE_MODES)}, got '{armature}'",
                field="armature",
            )
        self._spec_cache: dict[tuple[float, ...], EnvSpec] = {}
        specs = [self._spec(d) for d in self._designs]
        self._num_joints = len(specs[0].joint_names)
        self._default_joint_pos = np.stack([s.default_joint_pos for s in specs])  # [N, J]
        options = {
            "terrain": self.terrain,
            "terrain_seed": self.seed,
            "physics_dt": self.physics_dt,
            "decimation": self.decimation,
            "fixed_base": self.fixed_base,
            "max_delay_steps": self.max_delay_steps(),
            "armature": armature,
        }
        n = len(specs)
        if processes is None:
            processes = (
                0 if n <= IN_PROCESS_MAX_ENVS else min(self.num_threads or threads.budget(), n)
            )
        if processes < 0:
            raise UserError(f"processes must be >= 0, got {processes}", field="processes")
        self.processes = min(int(processes), n)
        self._engine = None
        self._pool = None
        self._slices = np.array_split(np.arange(n), max(self.processes, 1))
        if self.processes == 0:
            from coadapt_plugins.simulators.pybullet.engine import Engine

            self._engine = Engine(specs, **options)
        else:
            from coadapt_plugins.simulators.pybullet.workers import WorkerPool

            self._pool = WorkerPool(specs, self._slices, options)
        self._diverged = np.zeros(n, dtype=bool)
        # construction draws nothing (nominal parameters, spawn at the origin): the first
        # reset() makes the first draw, as in every backend, so one seed gives the same
        # parameters and spawn points on MuJoCo and PyBullet

    def _spec(self, design: np.ndarray) -> EnvSpec:
        import numpy as np
        from coadapt_plugins.simulators.pybullet.spec import EnvSpec

        key = tuple(float(x) for x in design)
        if key not in self._spec_cache:
            model = self.robot.build(np.asarray(design, dtype=float))
            self._spec_cache[key] = EnvSpec.from_model(model)
        return self._spec_cache[key]

    # -- sizes ---------------------------------------------------------------------------
    @property
    def num_joints(self) -> int:
        return self._num_joints

    @property
    def default_joint_pos(self) -> torch.Tensor:
        import torch

        return torch.as_tensor(self._default_joint_pos, dtype=torch.float32, device=self.device)

    # -- plumbing to the engines ---------------------------------------------------------
    def _split(self, env_ids: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """{worker: (positions in env_ids, local indices in that worker's slice)}."""
        import numpy as np

        out = {}
        for w, ids in enumerate(self._slices):
            mask = np.isin(env_ids, ids)
            if mask.any():
                out[w] = (np.nonzero(mask)[0], env_ids[mask] - ids[0])
        return out

    def _gather(self, parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
        import numpy as np

        return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}

    def _engine_params(self, env_ids: np.ndarray, spawn_xy: np.ndarray) -> dict[str, np.ndarray]:
        sub = self._params.take(env_ids)
        values = sub.numpy()
        return {
            "spawn_xy": spawn_xy,
            **{
                k: values[k]
                for k in ("friction", "restitution", "com_shift", "pd_factor", "motor_strength")
            },
            "delay_steps": sub.delay_steps(self.physics_dt).cpu().numpy(),
        }

    def _to_state(self, raw: dict[str, np.ndarray]) -> SimState:
        import numpy as np
        import torch

        def t(x: np.ndarray, dtype=torch.float32) -> torch.Tensor:
            return torch.as_tensor(np.ascontiguousarray(x), dtype=dtype, device=self.device)

        terrain_height = self.terrain_model.height_at(raw["base_pos"][:, :2])
        return SimState(
            base_pos=t(raw["base_pos"]),
            base_quat=t(raw["base_quat"]),
            base_lin_vel=t(raw["base_lin_vel"]),
            base_ang_vel=t(raw["base_ang_vel"]),
            joint_pos=t(raw["joint_pos"]),
            joint_vel=t(raw["joint_vel"]),
            joint_torque=t(raw["joint_torque"]),
            foot_pos=t(raw["foot_pos"]),
            foot_contact=t(raw["foot_contact"], torch.bool),
            foot_contact_force=t(raw["foot_contact_force"]),
            terrain_height=t(terrain_height),
            diverged=t(self._diverged, torch.bool),
        )

    def _raw_state(self) -> dict[str, np.ndarray]:
        if self._engine is not None:
            return self._engine.get_state()
        return self._gather(self._pool.call("get_state", [()] * len(self._slices)))

    # -- control -------------------------------------------------------------------------
    def _reset_engines(self, ids: np.ndarray) -> None:
        self.draw_env_params(ids)
        spawn_xy = self.draw_spawn_xy(ids)
        if self._engine is not None:
            self._engine.reset(ids, self._engine_params(ids, spawn_xy))
            return
        self._pool.call_some(
            "reset",
            {
                w: (local, self._engine_params(ids[pos], spawn_xy[pos]))
                for w, (pos, local) in self._split(ids).items()
            },
        )

    def reset(self, env_ids: torch.Tensor | np.ndarray | None = None) -> SimState:
        ids = self.parse_env_ids(env_ids)
        if ids.size:
            self._reset_engines(ids)
        self._diverged[ids] = False
        return self._to_state(self._raw_state())

    def set_gain_law(self, law: str) -> None:
        if law != self.gain_law:
            self._spec_cache.clear()  # the specs carry the gains
        super().set_gain_law(law)

    def set_speed_limit(self, mode: str) -> None:
        super().set_speed_limit(mode)
        binding = mode == "binding"
        if self._engine is not None:
            self._engine.set_binding(binding)
        else:
            self._pool.call("set_binding", [(binding,)] * len(self._slices))

    def step(self, joint_targets: torch.Tensor) -> SimState:
        import numpy as np

        if hasattr(joint_targets, "detach"):
            joint_targets = joint_targets.detach().cpu().numpy()
        targets = np.asarray(joint_targets, dtype=float)  # [N, J]
        if targets.shape != (self.num_envs, self.num_joints):
            raise UserError(
                f"joint_targets must have shape ({self.num_envs}, {self.num_joints}), got "
                f"{targets.shape}",
                field="joint_targets",
            )
        if self._engine is not None:
            raw = self._engine.step(targets)
        else:
            raw = self._gather(self._pool.call("step", [(targets[ids],) for ids in self._slices]))
        diverged = raw.pop("diverged")
        if diverged.any():
            # fresh parameters and pose for the broken environments, then the state again
            self._reset_engines(np.nonzero(diverged)[0])
            raw = self._raw_state()
        self._diverged = diverged
        return self._to_state(raw)

    def set_designs(self, env_ids: torch.Tensor | np.ndarray, designs: np.ndarray) -> None:
        import numpy as np

        ids, designs = self.parse_new_designs(env_ids, designs)
        specs = [self._spec(d) for d in designs]  # validates every design before touching any env
        if specs and len(specs[0].joint_names) != self._num_joints:
            raise DesignError(
                "set_designs: the new design has a different number of joints", field="designs"
            )
        if self._engine is not None:
            self._engine.set_specs(ids, specs)
        else:
            self._pool.call_some(
                "set_specs",
                {
                    w: (local, [specs[i] for i in pos])
                    for w, (pos, local) in self._split(ids).items()
                },
            )
        self._designs[ids] = designs
        self._default_joint_pos[ids] = np.stack([s.default_joint_pos for s in specs])
        self._reset_engines(ids)

    def get_state(self) -> SimState:
        return self._to_state(self._raw_state())

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None
        if self._engine is not None:
            self._engine.close()
            self._engine = None

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()

    # -- introspection for tests and the sim-to-sim check --------------------------------
    def dynamics_info(self, env_id: int) -> dict[str, object]:
        """Masses, contact and joint parameters of one environment as PyBullet holds them."""
        (w,) = [w for w, ids in enumerate(self._slices) if env_id in ids]
        local = int(env_id - self._slices[w][0])
        if self._engine is not None:
            return self._engine.dynamics_info(local)
        return self._pool.call_some("dynamics_info", {w: (local,)})[w]

    def worker_pids(self) -> list[int]:
        return [] if self._pool is None else self._pool.pids

    def _inject(self, env_ids: np.ndarray, base_velocity: float) -> None:
        """Test hook: kick bases to an absurd speed to exercise divergence handling."""
        ids = self.parse_env_ids(env_ids)
        if self._engine is not None:
            self._engine.inject(ids, base_velocity)
        else:
            self._pool.call_some(
                "inject",
                {w: (local, base_velocity) for w, (pos, local) in self._split(ids).items()},
            )
