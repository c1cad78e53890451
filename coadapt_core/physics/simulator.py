"""The `Simulator` plugin kind: a batched physics backend.

A simulator moves `num_envs` robots, each built from its own design, on one terrain. It
steps them with joint position targets (turned into torques by
`coadapt_core.physics.actuation`, including motor limits, randomized PD factor, motor
strength and system delay) and reports state as batched torch tensors. It knows nothing of
commands, observations or rewards: that is the locomotion task's room, which runs unchanged
on every backend.

The base class owns everything sim-to-sim honesty rests on, so that two backends cannot
drift apart in it: the option rules (`coadapt_core.physics.options`), the named random
streams and their `reseed`, Table 2 parameter draws (`draw_env_params`, through
`randomization.sample_env_params`), spawn points and spawn height (`draw_spawn_xy`,
`spawn_base_height`), environment-id parsing (`parse_env_ids`) and the paired-evaluation
scenarios (`fix_scenarios`). A backend fills in building its worlds, applying parameters,
stepping and reading state (docs/plugins.md, "Simulators").

Importing this module does not import torch (the functions that compute with it import it,
and `dtype` is resolved when read), so the registry lists a simulator plugin without torch
(docs/architecture.md, "Start-up").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

from coadapt_core.physics.dtype import TorchDtype
from coadapt_core.physics.frames import quat_rotate_inverse
from coadapt_core.physics.options import (
    NominalGains,
    check_offered,
    check_options,
    design_array,
    env_id_array,
    new_design_array,
)
from coadapt_core.physics.randomization import (
    EnvParams,
    RandomizationConfig,
    nominal_env_params,
    sample_env_params,
)
from coadapt_core.physics.terrain import TERRAINS, Terrain, make_terrain

if TYPE_CHECKING:
    import numpy as np
    import torch

    from coadapt_core.robot import Robot

#: spawn clearance between the lowest sole point and the highest ground near it, m
SPAWN_CLEARANCE = 0.002
#: random terrain: spawn points stay this far inside the height field's edge, m
SPAWN_MARGIN = 3.0
#: fixed-base robots hang this far above their standing spawn height, m (contact-free tests)
FIXED_BASE_LIFT = 0.5
#: entropy key of the spawn stream at construction (`default_rng([seed, SPAWN_STREAM_KEY])`)
SPAWN_STREAM_KEY = 0x5A


@dataclass
class SimState:
    """Batched state after a step or reset. N = num_envs, J = actuated joints, L = legs.

    Quaternions are (w, x, y, z). Velocities of the base are in the world frame;
    `base_frame()` expresses them (and gravity) in the base frame. Every tensor is finite:
    an environment whose physics diverged has been reset and is flagged in `diverged`.
    """

    base_pos: torch.Tensor  # [N, 3] world
    base_quat: torch.Tensor  # [N, 4] (w, x, y, z), base to world
    base_lin_vel: torch.Tensor  # [N, 3] world frame
    base_ang_vel: torch.Tensor  # [N, 3] world frame
    joint_pos: torch.Tensor  # [N, J]
    joint_vel: torch.Tensor  # [N, J]
    joint_torque: (
        torch.Tensor
    )  # [N, J] applied torque, mean over the physics steps of the last policy step
    foot_pos: torch.Tensor  # [N, L, 3] world position of each foot body's origin
    foot_contact: torch.Tensor  # [N, L] bool, foot touches the terrain
    foot_contact_force: torch.Tensor  # [N, L] normal contact force, N
    terrain_height: torch.Tensor  # [N] terrain height under the base
    diverged: torch.Tensor  # [N] bool, physics blew up during the last step and the env was reset

    def to(self, device: str | torch.device) -> SimState:
        return SimState(**{f.name: getattr(self, f.name).to(device) for f in fields(self)})

    def base_frame(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(linear velocity, angular velocity, gravity's direction), each [N, 3] float32 in
        the base frame: what the robot's IMU reads."""
        import torch

        quat = self.base_quat.float()
        gravity = torch.zeros_like(self.base_lin_vel, dtype=torch.float32)
        gravity[:, 2] = -1.0
        return tuple(
            quat_rotate_inverse(quat, v)
            for v in (self.base_lin_vel.float(), self.base_ang_vel.float(), gravity)
        )


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v [N, 3] by unit quaternions q [N, 4] (w, x, y, z)."""
    import numpy as np

    w = q[:, :1]
    u = q[:, 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def spawn_base_height(
    terrain: Terrain,
    xy: np.ndarray,  # [n, 2] base spawn points
    foot_xy: np.ndarray,  # [n, L, 2] each foot's offset from the base in the default pose
    foot_radius: np.ndarray,  # [n] reach of each sole around its foot's origin
    standing_height: np.ndarray,  # [n] the design's standing base height over flat ground
    fixed_base: bool = False,
) -> np.ndarray:
    """[n] base height at spawn: the standing height above the highest ground within reach
    of either sole, plus SPAWN_CLEARANCE (plus FIXED_BASE_LIFT for a welded base), so no
    foot starts inside the ground on the slope or the bumps."""
    import numpy as np

    feet = np.asarray(xy, dtype=float)[:, None, :] + foot_xy  # [n, L, 2]
    ground = np.empty(feet.shape[:2])  # [n, L] highest ground within each sole's reach
    radii = np.asarray(foot_radius, dtype=float)
    for radius in np.unique(radii):  # one value unless designs change the foot
        rows = radii == radius
        ground[rows] = terrain.max_height_near(feet[rows], float(radius))
    z = standing_height + ground.max(axis=1) + SPAWN_CLEARANCE
    return z + FIXED_BASE_LIFT if fixed_base else z


class Simulator(ABC):
    """A batched physics backend. Construct, `reset()`, then `step(targets)` repeatedly.

    A backend calls `super().__init__` first (it checks every option and the designs, and
    sets up the random streams, the nominal parameters and the terrain), then builds its
    worlds. At each reset of some environments it takes their parameters from
    `draw_env_params(ids)` and their spawn points from `draw_spawn_xy(ids)` (in the order of
    the ids asked for) and applies them; it implements `step`, `get_state`, `set_designs`,
    `num_joints` and `default_joint_pos`.
    """

    #: user-facing key (`--sim mujoco`)
    name: ClassVar[str]
    #: rank as the default of its kind: with no name given, a command takes the installed
    #: plugin of highest rank (ties: the first name in alphabetical order; docs/plugins.md)
    default_rank: ClassVar[int] = 0
    description: ClassVar[str] = ""
    #: the Python distribution (pip name) of the physics engine behind the backend, whose
    #: installed version each run records with its numerics (`coadapt_core.numerics`); ""
    #: when it has none to name
    engine: ClassVar[str] = ""
    #: modules the backend imports that print at import time (at the C level, past Python's
    #: streams); a command showing a progress line imports them first with the output closed
    quiet_imports: ClassVar[tuple[str, ...]] = ()
    #: terrains this backend supports
    terrains: ClassVar[tuple[str, ...]] = TERRAINS
    #: the robot model formats this backend reads (`RobotModel.formats` keys, e.g. "mjcf")
    model_formats: ClassVar[tuple[str, ...]] = ()
    #: the module (dotted path) of the backend's offscreen renderer, "" for none: pictures and
    #: videos (`coadapt_core.viz.video`) are drawn by it (docs/plugins.md section 7)
    renderer: ClassVar[str] = ""
    #: the module (dotted path) of the backend's model tools, "" for none: facts of a robot
    #: model outside a batched simulation (links, feet at a pose, actuated joints) and the
    #: handoff folder's standalone check (`coadapt_core.physics.model_tools`)
    model_tools: ClassVar[str] = ""
    #: dtype of the backend's actuation and of `env_params` (the state stays float32); read as
    #: `torch.float64`, resolved when read so that defining a backend imports no torch
    dtype: ClassVar[torch.dtype] = TorchDtype("float64")
    #: the motor speed limits the backend's actuation honours (`set_speed_limit`): "soft" (the
    #: torque-speed envelope) always; "binding" when it passes `binding` to `pd_torque`
    speed_limit_modes: ClassVar[tuple[str, ...]] = ("soft",)
    #: the PD gain laws it honours (`set_gain_law`): "robot" (each design's own gains, as the
    #: robot builds them) always; "nominal" (the nominal design's gains for every design) when
    #: it builds its models through `self.robot.build` and rebuilds them in `set_designs`
    gain_laws: ClassVar[tuple[str, ...]] = ("robot",)

    def __init__(
        self,
        robot: Robot,
        designs: np.ndarray,  # [num_envs, design_dim]
        *,
        terrain: str = "flat",
        randomization: RandomizationConfig | None = None,
        physics_dt: float = 0.005,
        decimation: int = 4,
        seed: int = 0,
        device: str = "cpu",
        num_threads: int | None = None,
        fixed_base: bool = False,
    ):
        """`fixed_base=True` welds the base where it spawns, raised clear of the terrain
        (contact-free swing tests, sim-to-sim checks). Bad options are one-line `UserError`s
        naming the field."""
        import numpy as np

        torch_device = check_options(
            self.name,
            self.terrains,
            terrain=terrain,
            physics_dt=physics_dt,
            decimation=decimation,
            seed=seed,
            device=device,
            num_threads=num_threads,
        )
        designs = design_array(designs)
        self.robot = robot
        self._check_designs(designs)
        self.fixed_base = bool(fixed_base)
        self.terrain = terrain
        self.randomization = randomization if randomization is not None else RandomizationConfig()
        self.physics_dt = float(physics_dt)
        self.decimation = int(decimation)
        self.seed = int(seed)
        self.device = device
        self.torch_device = torch_device
        self.num_threads = None if num_threads is None else int(num_threads)
        self.terrain_model: Terrain = make_terrain(terrain, seed=self.seed)
        self._designs = designs.copy()
        #: named random streams, restarted together by `reseed` (see `add_random_stream`)
        self._streams: dict[str, np.random.Generator] = {}
        # "params" (Table 2) and "spawn" are two streams, so the parameter draws stay
        # aligned between backends whatever the terrain
        self.add_random_stream("params", np.random.SeedSequence(self.seed))
        self.add_random_stream("spawn", np.random.SeedSequence([self.seed, SPAWN_STREAM_KEY]))
        # construction draws nothing: nominal parameters until the first reset
        self._params: EnvParams = nominal_env_params(
            len(designs), device=torch_device, dtype=self.dtype
        )
        #: the motor speed limit in force (`set_speed_limit`)
        self.speed_limit = "soft"
        #: the PD gain law in force (`set_gain_law`) and the robot as given
        self.gain_law = "robot"
        self._own_robot = robot
        self._scenario: tuple[EnvParams, np.ndarray | None] | None = None

    def set_speed_limit(self, mode: str) -> None:
        """The motor speed limit of the shared actuation from now on: "soft" (the torque-speed
        envelope alone) or "binding" (also no torque beyond the no-load speed; see
        `coadapt_core.physics.actuation`), one of the backend's `speed_limit_modes`. A backend
        that keeps its actuation elsewhere (worker processes) extends this to reach it."""
        self.speed_limit = check_offered(
            mode, self.speed_limit_modes, self.name, "motor_speed_limit"
        )

    def set_gain_law(self, law: str) -> None:
        """The PD gains of every design from now on: "robot" (each design's own) or "nominal"
        (the nominal design's, `NominalGains`), one of the backend's `gain_laws`; every
        environment is rebuilt (and restarts) when the law changes."""
        import numpy as np

        if check_offered(law, self.gain_laws, self.name, "gain_law") == self.gain_law:
            return
        self.gain_law = law
        self.robot = NominalGains(self._own_robot) if law == "nominal" else self._own_robot
        self.set_designs(np.arange(self.num_envs), self.designs)

    # -- sizes ---------------------------------------------------------------------------
    @property
    def num_envs(self) -> int:
        return int(self._designs.shape[0])

    @property
    @abstractmethod
    def num_joints(self) -> int: ...

    @property
    def control_dt(self) -> float:
        """Seconds of simulated time per `step` (policy period)."""
        return self.physics_dt * self.decimation

    @property
    def designs(self) -> np.ndarray:
        """[num_envs, design_dim] the design each environment currently simulates (a copy)."""
        return self._designs.copy()

    @property
    def env_params(self) -> EnvParams:
        """The randomized physical parameters currently in force, per environment: tensors
        on the simulator's device in `dtype` (a copy)."""
        import torch

        return self._params.take(torch.arange(self.num_envs, device=self._params.device))

    @property
    @abstractmethod
    def default_joint_pos(self) -> torch.Tensor:
        """[num_envs, J] standing pose of each environment's design."""

    # -- control -------------------------------------------------------------------------
    @abstractmethod
    def reset(self, env_ids: torch.Tensor | np.ndarray | None = None) -> SimState:
        """Reset the given environments (all when None) to the standing pose above the
        terrain, drawing new randomized parameters (`draw_env_params`) and spawn points
        (`draw_spawn_xy`); others are untouched."""

    @abstractmethod
    def step(self, joint_targets: torch.Tensor) -> SimState:
        """Advance every environment by `decimation` physics steps holding joint position
        targets [num_envs, J]."""

    @abstractmethod
    def set_designs(self, env_ids: torch.Tensor | np.ndarray, designs: np.ndarray) -> None:
        """Rebuild the given environments for new designs [len(env_ids), design_dim] (they
        are reset); the rest keep running. Check the arguments with `parse_new_designs`."""

    @abstractmethod
    def get_state(self) -> SimState:
        """The current state without stepping."""

    def terrain_height_at(self, xy: torch.Tensor) -> torch.Tensor:
        """Terrain height [...] at world points xy [..., 2] (see `coadapt_core.physics.terrain`)."""
        import torch

        heights = self.terrain_model.height_at(xy.detach().cpu().numpy())
        return torch.as_tensor(heights, dtype=xy.dtype, device=xy.device)

    def max_delay_steps(self) -> int:
        """Physics steps of the longest delay the randomization can draw (a delay line's
        length; 0 with randomization off)."""
        cfg = self.randomization
        longest = max(cfg.delay[1], RandomizationConfig.NOMINAL["delay"]) if cfg.enabled else 0.0
        return int(round(longest / self.physics_dt))  # half to even, as numpy's rint

    # -- arguments -------------------------------------------------------------------------
    def parse_env_ids(self, env_ids: torch.Tensor | np.ndarray | None) -> np.ndarray:
        """Environment ids [n] (int numpy) from None (all), an index tensor or array, or a
        boolean mask; ids outside [0, num_envs) are a `UserError`."""
        return env_id_array(env_ids, self.num_envs)

    def parse_new_designs(
        self, env_ids: torch.Tensor | np.ndarray, designs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(ids [n], designs [n, design_dim]) for `set_designs`, checked: one design of the
        simulator's length per id, each inside the robot's design space (`DesignError`
        otherwise, before any environment changes)."""
        ids = self.parse_env_ids(env_ids)
        designs = new_design_array(designs, ids.size, self._designs.shape[1])
        return ids, self._check_designs(designs)

    def _check_designs(self, designs: np.ndarray) -> np.ndarray:
        """`designs` [n, design_dim], each inside the robot's design space of its arity
        (`DesignError` naming the variable and its bounds otherwise): the one check every
        design passes before it becomes a world, at construction and in `set_designs`
        (through `parse_new_designs`), whoever asks for it."""
        import numpy as np

        rows = np.unique(designs, axis=0)
        self.robot.design_space_for(rows[0]).validate_batch(rows)
        return designs

    # -- randomness ------------------------------------------------------------------------
    def add_random_stream(
        self, name: str, entropy: np.random.SeedSequence | None = None
    ) -> np.random.Generator:
        """Register a named random stream of this backend and return it. Every draw a
        backend makes must come from a registered stream, so that `reseed` restarts it.
        Default seeding: SeedSequence([seed, k]) for the k-th stream."""
        import numpy as np

        if name in self._streams:
            raise ValueError(f"random stream '{name}' exists already")
        if entropy is None:
            entropy = np.random.SeedSequence([self.seed, len(self._streams)])
        self._streams[name] = np.random.Generator(np.random.PCG64(entropy))
        return self._streams[name]

    def random_stream(self, name: str) -> np.random.Generator:
        """The named random stream ("params": Table 2 draws, "spawn": spawn points, or one
        the backend added)."""
        return self._streams[name]

    def reseed(self, seed: int) -> None:
        """Restart every named random stream from `seed` (the next `reset` then draws
        randomization and spawn points from it): the k-th stream in order of registration
        from SeedSequence([seed, k]), in place. Exact resume of a co-adaptation run relies
        on it."""
        import numpy as np

        for k, gen in enumerate(self._streams.values()):
            gen.bit_generator.state = type(gen.bit_generator)(
                np.random.SeedSequence([int(seed), k])
            ).state

    # -- per-reset draws (paired evaluation: common random numbers) --------------------------
    def fix_scenarios(self, params: EnvParams | None, spawn: np.ndarray | None = None) -> None:
        """Hold each environment's randomized parameters (`params` over all `num_envs`) and,
        on the random terrain, its spawn point (`spawn` [num_envs, 2], fractions in [0, 1) of
        the spawn square) at every later reset, including restarts after a fall; None draws
        them again. Real evaluation (`learning.evaluate.apply_scenarios`) uses this hook to
        give agent i of every design the same draw in real fitness (docs/coadaptation.md,
        "Evaluation protocol"); `draw_env_params` and `draw_spawn_xy` honour it."""
        import numpy as np

        if params is None:
            self._scenario = None
            return
        frac = None if spawn is None else np.asarray(spawn, dtype=float).reshape(-1, 2)
        self._scenario = (params.to(self._params.device, self.dtype), frac)

    def draw_env_params(self, env_ids: np.ndarray) -> EnvParams:
        """New randomized parameters for environments `env_ids` at their reset, recorded as
        the ones in force (`env_params`) and returned (tensors on the simulator's device):
        the fixed scenario's when `fix_scenarios` set one (consuming no randomness), else a
        draw from the "params" stream, in the order of the ids."""
        import numpy as np

        ids = np.asarray(env_ids, dtype=int)
        if self._scenario is not None:
            params = self._scenario[0].take(ids)
        else:
            params = sample_env_params(
                self.randomization,
                len(ids),
                self._streams["params"],
                device=self._params.device,
                dtype=self.dtype,
            )
        self._params.put(ids, params)
        return params

    def draw_spawn_xy(self, env_ids: np.ndarray) -> np.ndarray:
        """[n, 2] base spawn points (x, y) for `env_ids`: the origin, except on the random
        terrain a point at least SPAWN_MARGIN inside the height field's edge, the fixed
        scenario's when set, else drawn from the "spawn" stream."""
        import numpy as np

        ids = np.asarray(env_ids, dtype=int)
        if self.terrain_model.name != "random":
            return np.zeros((ids.size, 2))
        half = self.terrain_model.size / 2 - SPAWN_MARGIN
        if self._scenario is not None and self._scenario[1] is not None:
            return -half + 2.0 * half * self._scenario[1][ids]
        return self._streams["spawn"].uniform(-half, half, size=(ids.size, 2))

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release processes, threads or native resources."""

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
