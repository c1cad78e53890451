"""Domain randomization (paper Table 2): the ranges (`RandomizationConfig`) and the record
of one batch's physical parameters (`EnvParams`).

Every simulator backend applies the same `EnvParams` with the same meaning, so the same
seed gives the same physical parameters on MuJoCo and PyBullet: the draw, `sample_env_params`,
is defined once here, beside the ranges it draws from; the simulator base calls it from the
random streams it owns (`Simulator.draw_env_params`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import TYPE_CHECKING, ClassVar

from coadapt_core.errors import UserError, did_you_mean
from coadapt_core.settings import (
    NonNegativeRange,
    PositiveRange,
    Range,
    apply_overrides,
    setting,
    settings,
)

if TYPE_CHECKING:  # the tensors' module loads with the first batch: the settings stay torch-free
    import numpy as np
    import torch


@settings(prefix="randomization")
class RandomizationConfig:
    """Ranges drawn uniformly per environment at each reset. `enabled=False` (or a range
    with equal ends) turns a parameter off; the nominal value is then used."""

    enabled: bool = setting(
        True, "Draw the ranges below at each reset (off: every parameter nominal)."
    )
    friction: PositiveRange = setting((0.5, 1.25), "Sliding friction coefficient (Table 2).")
    restitution: NonNegativeRange = setting((0.0, 0.4), "Restitution (Table 2).")
    com_shift: Range = setting(
        (-0.025, 0.025), "Base centre-of-mass offset per axis x, y, z, m (Table 2)."
    )
    pd_factor: PositiveRange = setting((0.9, 1.1), "Factor on kp and kd (Table 2).")
    motor_strength: PositiveRange = setting((0.9, 1.1), "Factor on the commanded torque (Table 2).")
    delay: NonNegativeRange = setting(
        (0.0, 0.020), "System delay of the joint targets, s (Table 2)."
    )
    # -- engine robustness (ours, not the paper's Table 2): what differs between MuJoCo and
    # PyBullet. Off by default (each range is its nominal point, and a point range draws
    # nothing, so default configurations keep their random streams); `engine_robust()`
    # turns them on. Applied by the MuJoCo backend; other backends run them at nominal.
    contact_timeconst: PositiveRange = setting(
        (0.02, 0.02), "Contact softness, s (MuJoCo solref[0]; engine robustness, not Table 2)."
    )
    joint_damping: NonNegativeRange = setting(
        (0.0, 0.0), "N m s/rad added to every joint's damping (engine robustness)."
    )
    armature: PositiveRange = setting(
        (1.0, 1.0), "Factor on every joint's armature (engine robustness)."
    )

    NOMINAL: ClassVar[dict[str, float]] = {
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
    OPTIONAL: ClassVar[tuple[str, ...]] = ("contact_timeconst", "joint_damping", "armature")

    @classmethod
    def off(cls) -> RandomizationConfig:
        return cls(enabled=False)

    @classmethod
    def engine_robust(cls) -> RandomizationConfig:
        """Table 2 plus what differs between the engines (docs/training.md): contacts from
        twice as stiff to twice as soft as MuJoCo's default (Bullet's are rigid), up to
        1 N m s/rad of extra joint damping, armature +-25 %, and system delay to 25 ms."""
        return cls(
            delay=(0.0, 0.025),
            contact_timeconst=(0.01, 0.04),
            joint_damping=(0.0, 1.0),
            armature=(0.75, 1.25),
        )

    @classmethod
    def preset(cls, name: str) -> RandomizationConfig:
        """A named configuration: "table2" (the paper's, the default), "engine" (table2 plus
        engine robustness, `engine_robust`) or "off"."""
        presets = {"table2": cls, "engine": cls.engine_robust, "off": cls.off}
        if name not in presets:
            raise UserError(
                f"randomization preset '{name}' is not one of: {', '.join(presets)}"
                f"{did_you_mean(name, list(presets))}",
                field="randomization",
            )
        return presets[name]()

    @classmethod
    def recorded(cls, extra: dict) -> RandomizationConfig:
        """The randomization a training configuration records in `TrainConfig.extra`: its
        preset (`randomization`, table2 when none) with the ranges it overrides
        (`randomization_ranges`, {name: [low, high]})."""
        base = cls.preset(str(extra.get("randomization", "table2")))
        return apply_overrides(base, extra.get("randomization_ranges") or {})

    def to_dict(self) -> dict:
        return asdict(self)


#: the named randomization configurations (`RandomizationConfig.preset`)
RANDOMIZATION_PRESETS = ("table2", "engine", "off")


@dataclass
class EnvParams:
    """Physical parameters of a batch of environments, each a tensor [num_envs] (com_shift
    [num_envs, 3]) on the simulator's device in its dtype (float64 on the built-in
    backends). Produced by `sample_env_params`, applied by the simulator at reset."""

    friction: torch.Tensor
    restitution: torch.Tensor
    com_shift: torch.Tensor
    pd_factor: torch.Tensor
    motor_strength: torch.Tensor
    delay: torch.Tensor  # s
    contact_timeconst: torch.Tensor  # s
    joint_damping: torch.Tensor  # N m s/rad, added to each joint's own
    armature: torch.Tensor  # factor on each joint's armature

    def _map(self, fn) -> EnvParams:
        return EnvParams(**{f.name: fn(getattr(self, f.name)) for f in fields(self)})

    @property
    def device(self) -> torch.device:
        return self.friction.device

    def __len__(self) -> int:
        return int(self.friction.shape[0])

    def delay_steps(self, physics_dt: float) -> torch.Tensor:
        """[num_envs] long: the delay in whole physics steps (rounded half to even)."""
        import torch

        return torch.round(self.delay / physics_dt).long()

    def privileged(self, device: str | torch.device | None = None) -> torch.Tensor:
        """[num_envs, 8] float32 tensor on `device` (default: the parameters' own): friction,
        restitution, PD factor, motor strength, delay (s), CoM shift (3), the critic state's
        randomized parameters (the engine-robustness ones are not in it: the critic input
        keeps its size)."""
        import torch

        columns = torch.cat(
            [
                torch.stack(
                    [
                        self.friction,
                        self.restitution,
                        self.pd_factor,
                        self.motor_strength,
                        self.delay,
                    ],
                    dim=1,
                ),
                self.com_shift.reshape(-1, 3),
            ],
            dim=1,
        )
        return columns.to(device=device if device is not None else self.device, dtype=torch.float32)

    def to(
        self, device: str | torch.device | None = None, dtype: torch.dtype | None = None
    ) -> EnvParams:
        return self._map(lambda v: v.to(device=device, dtype=dtype))

    def numpy(self) -> dict[str, np.ndarray]:
        """Every field as a float64 numpy array on the CPU (for engines that take numpy)."""
        import numpy as np

        return {
            f.name: getattr(self, f.name).detach().cpu().numpy().astype(np.float64, copy=False)
            for f in fields(self)
        }

    def take(self, env_ids) -> EnvParams:
        """The parameters of environments `env_ids` (tensor, numpy array or list), a copy."""
        import torch

        index = torch.as_tensor(env_ids, dtype=torch.long, device=self.device)
        return self._map(lambda v: v[index])

    def put(self, env_ids, other: EnvParams) -> None:
        """Write `other` (one row per id) into environments `env_ids`."""
        import torch

        index = torch.as_tensor(env_ids, dtype=torch.long, device=self.device)
        for f in fields(self):
            value = getattr(self, f.name)
            value[index] = getattr(other, f.name).to(device=value.device, dtype=value.dtype)

    def repeat(self, times: int) -> EnvParams:
        """The batch repeated `times` times end to end ([times * num_envs] rows)."""
        return self._map(lambda v: v.repeat((times,) + (1,) * (v.dim() - 1)))


def nominal_env_params(
    num_envs: int, *, device: str | torch.device = "cpu", dtype: torch.dtype | None = None
) -> EnvParams:
    import numpy as np

    return sample_env_params(
        RandomizationConfig.off(), num_envs, np.random.default_rng(0), device=device, dtype=dtype
    )


def sample_env_params(
    config: RandomizationConfig,
    num_envs: int,
    rng: np.random.Generator,
    *,
    device: str | torch.device = "cpu",
    dtype: torch.dtype | None = None,
) -> EnvParams:
    """Draw parameters for `num_envs` environments from numpy's `rng` (so one seed gives
    the same numbers on every backend and device; always consumes the same amount of
    randomness whether or not randomization is enabled, so seeds stay aligned; the
    engine-robustness parameters draw only when their range is not a point, after Table
    2's), returned as tensors on `device` in `dtype` (None: float64)."""
    import numpy as np
    import torch

    dtype = torch.float64 if dtype is None else dtype

    def draw(name: str, shape: tuple[int, ...]) -> torch.Tensor:
        lo, hi = getattr(config, name)
        if name in RandomizationConfig.OPTIONAL and lo == hi:
            value = np.full(shape, lo, dtype=float)
        else:
            value = rng.uniform(lo, hi, size=shape)
        if not config.enabled:
            value = np.full(shape, RandomizationConfig.NOMINAL[name], dtype=float)
        return torch.as_tensor(value, dtype=dtype, device=device)

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
