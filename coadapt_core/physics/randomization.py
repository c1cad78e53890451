"""Domain randomization (paper Table 2): ranges, and the per-environment draw at reset.

Every simulator backend applies the same `EnvParams` with the same meaning, so the same
seed gives the same physical parameters on MuJoCo and PyBullet.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np
import torch

from coadapt_core.errors import UserError


@dataclass
class RandomizationConfig:
    """Ranges drawn uniformly per environment at each reset. `enabled=False` (or a range
    with equal ends) turns a parameter off; the nominal value is then used."""

    enabled: bool = True
    friction: tuple[float, float] = (0.5, 1.25)  # sliding friction coefficient
    restitution: tuple[float, float] = (0.0, 0.4)
    com_shift: tuple[float, float] = (-0.025, 0.025)  # m, base CoM offset per axis x, y, z
    pd_factor: tuple[float, float] = (0.9, 1.1)  # scales kp and kd
    motor_strength: tuple[float, float] = (0.9, 1.1)  # scales the commanded torque
    delay: tuple[float, float] = (0.0, 0.020)  # s, system delay of the joint targets
    # -- engine robustness (ours, not the paper's Table 2): what differs between MuJoCo and
    # PyBullet. Off by default (each range is its nominal point, and a point range draws
    # nothing, so default configurations keep their random streams); `engine_robust()`
    # turns them on. Applied by the MuJoCo backend; other backends run them at nominal.
    contact_timeconst: tuple[float, float] = (0.02, 0.02)  # s, contact softness (MuJoCo solref[0])
    joint_damping: tuple[float, float] = (0.0, 0.0)  # N m s/rad added to every joint's damping
    armature: tuple[float, float] = (1.0, 1.0)  # scales every joint's armature (reflected rotor inertia)

    NOMINAL = {
        "friction": 1.0,
        "restitution": 0.0,
        "com_shift": 0.0,
        "pd_factor": 1.0,
        "motor_strength": 1.0,
        "delay": 0.0,
        "contact_timeconst": 0.02,
        "joint_damping": 0.0,
        "armature": 1.0,
    }
    #: parameters drawn only when their range is not a single point (added after Table 2's:
    #: a configuration that leaves them at a point consumes the randomness it always did)
    OPTIONAL = ("contact_timeconst", "joint_damping", "armature")

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "enabled":
                continue
            lo, hi = getattr(self, f.name)
            if lo > hi:
                raise UserError(
                    f"randomization.{f.name}: inverted range [{lo}, {hi}]", field=f"randomization.{f.name}"
                )
            if f.name in ("friction", "pd_factor", "motor_strength", "contact_timeconst", "armature") and lo <= 0:
                raise UserError(
                    f"randomization.{f.name}: range must be positive, got [{lo}, {hi}]",
                    field=f"randomization.{f.name}",
                )
            if f.name in ("delay", "restitution", "joint_damping") and lo < 0:
                raise UserError(
                    f"randomization.{f.name}: range must be >= 0, got [{lo}, {hi}]",
                    field=f"randomization.{f.name}",
                )
            setattr(self, f.name, (float(lo), float(hi)))

    @classmethod
    def off(cls) -> RandomizationConfig:
        return cls(enabled=False)

    @classmethod
    def engine_robust(cls) -> RandomizationConfig:
        """Table 2 plus what differs between the engines (docs/training.md): contacts from
        twice as stiff to twice as soft as MuJoCo's default (Bullet's are rigid), up to
        1 N m s/rad of extra joint damping, armature +-25 %, and system delay to 25 ms."""
        return cls(
            delay=(0.0, 0.025), contact_timeconst=(0.01, 0.04), joint_damping=(0.0, 1.0), armature=(0.75, 1.25)
        )

    @classmethod
    def preset(cls, name: str) -> RandomizationConfig:
        """A named configuration: "table2" (the paper's, the default), "engine" (table2 plus
        engine robustness, `engine_robust`) or "off"."""
        presets = {"table2": cls, "engine": cls.engine_robust, "off": cls.off}
        if name not in presets:
            raise UserError(
                f"randomization preset '{name}' is not one of: {', '.join(presets)}", field="randomization"
            )
        return presets[name]()

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class EnvParams:
    """Physical parameters of a batch of environments, each array [num_envs] (com_shift
    [num_envs, 3]). Produced by `sample_env_params`, applied by the simulator at reset."""

    friction: np.ndarray
    restitution: np.ndarray
    com_shift: np.ndarray
    pd_factor: np.ndarray
    motor_strength: np.ndarray
    delay: np.ndarray  # s
    contact_timeconst: np.ndarray  # s
    joint_damping: np.ndarray  # N m s/rad, added to each joint's own
    armature: np.ndarray  # factor on each joint's armature

    def delay_steps(self, physics_dt: float) -> np.ndarray:
        """[num_envs] int: the delay in whole physics steps (rounded)."""
        return np.rint(self.delay / physics_dt).astype(int)

    def privileged(self, device: str | torch.device = "cpu") -> torch.Tensor:
        """[num_envs, 8] float32 tensor on `device`: friction, restitution, PD factor, motor
        strength, delay (s), CoM shift (3), the critic state's randomized parameters (the
        engine-robustness ones are not in it: the critic input keeps its size)."""
        columns = np.column_stack(
            [self.friction, self.restitution, self.pd_factor, self.motor_strength, self.delay,
             np.reshape(self.com_shift, (-1, 3))]
        )
        return torch.from_numpy(columns.astype(np.float32)).to(device)

    def take(self, env_ids: np.ndarray) -> EnvParams:
        return EnvParams(**{k: v[env_ids] for k, v in asdict(self).items()})

    def put(self, env_ids: np.ndarray, other: EnvParams) -> None:
        for k, v in asdict(other).items():
            getattr(self, k)[env_ids] = v


def nominal_env_params(num_envs: int) -> EnvParams:
    return sample_env_params(RandomizationConfig.off(), num_envs, np.random.default_rng(0))


def sample_env_params(config: RandomizationConfig, num_envs: int, rng: np.random.Generator) -> EnvParams:
    """Draw parameters for `num_envs` environments (always consumes the same amount of
    randomness whether or not randomization is enabled, so seeds stay aligned; the
    engine-robustness parameters draw only when their range is not a point, after Table 2's)."""

    def draw(name: str, shape: tuple[int, ...]) -> np.ndarray:
        lo, hi = getattr(config, name)
        if name in RandomizationConfig.OPTIONAL and lo == hi:
            value = np.full(shape, lo, dtype=float)
        else:
            value = rng.uniform(lo, hi, size=shape)
        if not config.enabled:
            value = np.full(shape, RandomizationConfig.NOMINAL[name], dtype=float)
        return value

    return EnvParams(
        friction=draw("friction", (num_envs,)),
        restitution=draw("restitution", (num_envs,)),
        com_shift=draw("com_shift", (num_envs, 3)),
        pd_factor=draw("pd_factor", (num_envs,)),
        motor_strength=draw("motor_strength", (num_envs,)),
        delay=draw("delay", (num_envs,)),
        contact_timeconst=draw("contact_timeconst", (num_envs,)),
        joint_damping=draw("joint_damping", (num_envs,)),
        armature=draw("armature", (num_envs,)),
    )
