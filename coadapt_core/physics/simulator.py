"""The `Simulator` plugin kind: a batched physics backend.

A simulator moves `num_envs` robots, each built from its own design, on one terrain. It
steps them with joint position targets (turned into torques by `coadapt_core.physics.actuation`,
including motor limits, randomized PD factor, motor strength and system delay) and reports
state as batched torch tensors. It knows nothing of commands, observations or rewards: that
is the locomotion task's room, which runs unchanged on every backend.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from coadapt_core.physics.randomization import EnvParams, RandomizationConfig, sample_env_params

if TYPE_CHECKING:
    import torch

    from coadapt_core.robot import Robot

#: terrain names every backend understands (paper section 4.4)
TERRAINS: tuple[str, ...] = ("flat", "slope", "random")
#: slope terrain inclination, degrees (rising along +x)
SLOPE_DEGREES = 10.0
#: random terrain: uniform height noise in [0, RANDOM_MAX_HEIGHT] m
RANDOM_MAX_HEIGHT = 0.05


@dataclass
class SimState:
    """Batched state after a step or reset. N = num_envs, J = actuated joints, L = legs.

    Quaternions are (w, x, y, z). Velocities of the base are in the world frame; the task
    rotates them into the base frame. Every tensor is finite: an environment whose physics
    diverged has been reset and is flagged in `diverged`.
    """

    base_pos: torch.Tensor  # [N, 3] world
    base_quat: torch.Tensor  # [N, 4] (w, x, y, z), base to world
    base_lin_vel: torch.Tensor  # [N, 3] world frame
    base_ang_vel: torch.Tensor  # [N, 3] world frame
    joint_pos: torch.Tensor  # [N, J]
    joint_vel: torch.Tensor  # [N, J]
    joint_torque: torch.Tensor  # [N, J] applied torque, mean over the physics steps of the last policy step
    foot_pos: torch.Tensor  # [N, L, 3] world position of each foot body's origin
    foot_contact: torch.Tensor  # [N, L] bool, foot touches the terrain
    foot_contact_force: torch.Tensor  # [N, L] normal contact force, N
    terrain_height: torch.Tensor  # [N] terrain height under the base
    diverged: torch.Tensor  # [N] bool, physics blew up during the last step and the env was reset

    def to(self, device: str | torch.device) -> SimState:
        return SimState(**{f.name: getattr(self, f.name).to(device) for f in fields(self)})


class Simulator(ABC):
    """A batched physics backend. Construct, `reset()`, then `step(targets)` repeatedly."""

    #: user-facing key (`--sim mujoco`)
    name: ClassVar[str]
    description: ClassVar[str] = ""
    #: terrains this backend supports
    terrains: ClassVar[tuple[str, ...]] = TERRAINS

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
        (contact-free swing tests, sim-to-sim checks)."""
        self.robot = robot
        self.fixed_base = fixed_base
        self.terrain = terrain
        self.randomization = randomization if randomization is not None else RandomizationConfig()
        self.physics_dt = physics_dt
        self.decimation = decimation
        self.seed = seed
        self.device = device
        self.num_threads = num_threads

    # -- sizes ---------------------------------------------------------------------------
    @property
    @abstractmethod
    def num_envs(self) -> int: ...

    @property
    @abstractmethod
    def num_joints(self) -> int: ...

    @property
    def control_dt(self) -> float:
        """Seconds of simulated time per `step` (policy period)."""
        return self.physics_dt * self.decimation

    @property
    @abstractmethod
    def designs(self) -> np.ndarray:
        """[num_envs, design_dim] the design each environment currently simulates."""

    @property
    @abstractmethod
    def env_params(self) -> EnvParams:
        """The randomized physical parameters currently in force, per environment."""

    @property
    @abstractmethod
    def default_joint_pos(self) -> torch.Tensor:
        """[num_envs, J] standing pose of each environment's design."""

    # -- control -------------------------------------------------------------------------
    @abstractmethod
    def reset(self, env_ids: torch.Tensor | np.ndarray | None = None) -> SimState:
        """Reset the given environments (all when None) to the standing pose above the
        terrain, drawing new randomized parameters; others are untouched."""

    @abstractmethod
    def step(self, joint_targets: torch.Tensor) -> SimState:
        """Advance every environment by `decimation` physics steps holding joint position
        targets [num_envs, J]."""

    @abstractmethod
    def set_designs(self, env_ids: torch.Tensor | np.ndarray, designs: np.ndarray) -> None:
        """Rebuild the given environments for new designs [len(env_ids), design_dim] (they
        are reset); the rest keep running."""

    @abstractmethod
    def get_state(self) -> SimState:
        """The current state without stepping."""

    def terrain_height_at(self, xy: torch.Tensor) -> torch.Tensor:
        """Terrain height [...] at world points xy [..., 2] (see `coadapt_core.physics.terrain`)."""
        import torch

        from coadapt_core.physics.terrain import make_terrain

        heights = make_terrain(self.terrain, seed=self.seed).height_at(xy.detach().cpu().numpy())
        return torch.as_tensor(heights, dtype=xy.dtype, device=xy.device)

    def reseed(self, seed: int) -> None:
        """Restart every random stream of the backend from `seed` (the next `reset` then
        draws randomization and spawn points from it). Exact resume of a co-adaptation run
        relies on it. Default: each `numpy.random.Generator` attribute, sorted by name, is
        restarted in place from SeedSequence([seed, k]); a backend that keeps randomness
        elsewhere overrides this."""
        names = sorted(k for k, v in vars(self).items() if isinstance(v, np.random.Generator))
        for k, name in enumerate(names):
            gen = getattr(self, name)
            gen.bit_generator.state = type(gen.bit_generator)(np.random.SeedSequence([int(seed), k])).state

    # -- paired evaluation (common random numbers) -----------------------------------------
    def fix_scenarios(self, params: EnvParams | None, spawn: np.ndarray | None = None) -> None:
        """Hold each environment's randomized parameters (`params` over all `num_envs`) and,
        on the random terrain, its spawn point (`spawn` [num_envs, 2], fractions in [0, 1) of
        the spawn square) at every later reset, including restarts after a fall; None draws
        them again. Real fitness uses this to give agent i of every design the same draw
        (docs/coadaptation.md, "Evaluation protocol"). A backend honours it by drawing through
        `draw_env_params` and `draw_spawn_xy`; one that does not still runs, unpaired."""
        if params is None:
            self._scenario = None
            return
        frac = None if spawn is None else np.asarray(spawn, dtype=float).reshape(-1, 2)
        self._scenario = (params, frac)

    def draw_env_params(self, env_ids: np.ndarray, rng: np.random.Generator) -> EnvParams:
        """Randomized parameters for environments `env_ids` at a reset: the fixed scenario's
        when `fix_scenarios` set one (consuming no randomness), else a fresh draw from `rng`."""
        scenario = getattr(self, "_scenario", None)
        if scenario is not None:
            return scenario[0].take(np.asarray(env_ids, dtype=int))
        return sample_env_params(self.randomization, len(env_ids), rng)

    def draw_spawn_xy(self, env_ids: np.ndarray, rng: np.random.Generator, half: float) -> np.ndarray:
        """[n, 2] spawn points in [-half, half]^2 for `env_ids` (random terrain): the fixed
        scenario's when set, else drawn from `rng`."""
        scenario = getattr(self, "_scenario", None)
        if scenario is not None and scenario[1] is not None:
            return -half + 2.0 * half * scenario[1][np.asarray(env_ids, dtype=int)]
        return rng.uniform(-half, half, size=(len(env_ids), 2))

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release processes, threads or native resources."""

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
