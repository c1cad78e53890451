"""Settings of the locomotion task: commands and their curriculum, gait clock, reward
weights (paper Table 1 plus the terms we add), observation noise (Table 3), termination.

Every field is documented in place and listed in docs/training.md; a `TaskConfig` is stored
in each checkpoint so a policy is always evaluated on the task it was trained on.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

from coadapt_core.errors import UserError

#: Paper Table 1 (weights as printed; multiplied by the policy period dt when summed,
#: the legged_gym convention the paper's code base [40] follows).
PAPER_REWARD_WEIGHTS: dict[str, float] = {
    "tracking_lin_vel": 2.0,  # exp(-4 |v_xy_cmd - v_xy|^2)
    "tracking_ang_vel": 1.5,  # exp(-4 (w_yaw_cmd - w_yaw)^2)
    "lin_vel_z": -1.25,  # v_z^2
    "ang_vel_xy": -0.1,  # |w_xy|^2
    "torques": -5.0e-6,  # sum tau^2
    "orientation": -10.0,  # |g_xy|^2 (projected gravity)
    "dof_acc": -2.0e-7,  # sum qdd^2
    "action_rate": -0.025,  # sum (a_t - a_t-1)^2
    "default_pos": -0.2,  # sum (q - q_stand)^2
    "raibert": -0.75,  # sum (q - q*)^2, q* from Raibert placement + von Mises swing height
}

#: Terms we add (not the paper's) to escape the standing optimum (shared/walking-notes.md).
EXTRA_REWARD_WEIGHTS: dict[str, float] = {
    "contact_match": 1.0,  # feet contacts that match the clock's stance schedule (+1 / -0.3 per foot)
    "feet_air_time": 1.0,  # sum over touchdowns of (t_air - offset), zero under a zero command
    "termination": -200.0,  # on a fall (not on a timeout); x dt like every weight
}


@dataclass
class CommandConfig:
    """Velocity commands (vx, vy, yaw rate), drawn per episode and optionally mid-episode."""

    vx_range: tuple[float, float] = (-0.5, 1.25)  # m/s, paper section 4
    vy_range: tuple[float, float] = (0.0, 0.0)  # m/s
    # rad/s; the paper's policies follow yaw-rate commands. Checkpoints store their own range
    # (flat.pt and flat-mixed.pt were trained with (0, 0): they hold the heading)
    yaw_range: tuple[float, float] = (-1.0, 1.0)
    zero_share: float = 0.05  # share of commands set exactly to zero
    zero_threshold: float = 0.1  # a planar command slower than this becomes zero (m/s)
    resample_seconds: float = 10.0  # redraw mid-episode every so often; 0 = once per episode
    # curriculum (walking-notes remedy 6): the command box starts at +-curriculum_start
    # (clipped to the ranges above) and widens by curriculum_step whenever, over a window of
    # finished episodes, the mean unweighted linear tracking term on steps with a moving
    # command exceeds curriculum_threshold and those episodes fell at most
    # curriculum_max_fall_rate times per second of episode time. (A share of fallen episodes
    # is no gate: with 20 s episodes a policy falling once a minute loses ~27 % of them, which
    # held the box at +-0.3 m/s for 6 M steps of a run that tracked it well.)
    curriculum: bool = True
    curriculum_start: float = 0.3
    curriculum_step: float = 0.1
    curriculum_threshold: float = 0.8
    curriculum_max_fall_rate: float = 0.03  # falls per second of episode time
    curriculum_window: int = 64  # finished episodes per curriculum decision

    def __post_init__(self) -> None:
        for name in ("vx_range", "vy_range", "yaw_range"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise UserError(f"task.commands.{name}: inverted range [{lo}, {hi}]", field=f"commands.{name}")
            setattr(self, name, (float(lo), float(hi)))
        if not 0.0 <= self.zero_share <= 1.0:
            raise UserError("task.commands.zero_share must lie in [0, 1]", field="commands.zero_share")


@dataclass
class RewardConfig:
    """Reward weights by term name; a weight of 0 switches a term off."""

    weights: dict[str, float] = field(
        default_factory=lambda: {**PAPER_REWARD_WEIGHTS, **EXTRA_REWARD_WEIGHTS}
    )
    tracking_sigma: float = 0.25  # exp(-e^2 / sigma): 0.25 is the paper's exp(-4 e^2)
    clip_at_zero: bool = True  # ours: clip the per-step sum (before termination) at 0
    scale_by_dt: bool = True  # multiply every weight by the policy period
    air_time_offset: float = 0.25  # s, feet_air_time pays t_air - offset at touchdown
    contact_mismatch: float = -0.3  # contact_match value of a foot out of its schedule

    def __post_init__(self) -> None:
        known = set(PAPER_REWARD_WEIGHTS) | set(EXTRA_REWARD_WEIGHTS)
        unknown = sorted(set(self.weights) - known)
        if unknown:
            raise UserError(
                f"task.rewards.weights: unknown term(s) {unknown}; known: {sorted(known)}",
                field="rewards.weights",
            )
        self.weights = {**{k: 0.0 for k in known}, **{k: float(v) for k, v in self.weights.items()}}


@dataclass
class GaitConfig:
    """The gait clock and the Raibert/von Mises reference behind the `raibert` term."""

    frequency: float = 1.5  # Hz, one full cycle = two steps
    swing_height: float = 0.08  # m, apex of the von Mises swing profile
    von_mises_kappa: float = 4.0  # concentration of the swing-height bump around mid-swing
    raibert_gain: float = 0.05  # k in foot = hip + v T_stance / 2 + k (v - v_cmd), s
    raibert_max_offset: float = 0.15  # m, clip of the x-y placement offset
    command_full_scale: float = 0.3  # m/s: reference offsets grow linearly up to this |command|
    freeze_on_zero_command: bool = True  # both feet stance under a zero command (remedy 7)


@dataclass
class NoiseConfig:
    """Observation noise, paper Table 3 (uniform in [-s, s] or gaussian with std s)."""

    enabled: bool = True
    kind: str = "uniform"  # "uniform" | "gaussian"
    joint_pos: float = 0.01  # rad
    joint_vel: float = 1.5  # rad/s
    base_lin_vel: float = 0.01  # m/s
    base_ang_vel: float = 0.2  # rad/s
    projected_gravity: float = 0.05

    def __post_init__(self) -> None:
        if self.kind not in ("uniform", "gaussian"):
            raise UserError(
                f"task.noise.kind '{self.kind}' is not one of: uniform, gaussian", field="noise.kind"
            )


@dataclass
class TaskConfig:
    """The whole locomotion task."""

    commands: CommandConfig = field(default_factory=CommandConfig)
    rewards: RewardConfig = field(default_factory=RewardConfig)
    gait: GaitConfig = field(default_factory=GaitConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    action_scale: float = 0.25  # rad per unit action around the default pose
    action_clip: float = 10.0  # raw actions clipped to +-action_clip before scaling
    history: int = 5  # past actions in the observation (5 x 8 = 40 of the 70)
    episode_seconds: float = 20.0  # timeout (bootstrapped, not a failure)
    min_base_height: float = 0.5  # fall: base above terrain below this share of standing height
    max_tilt_cos: float = 0.5  # fall: projected gravity z above -this (tilt beyond 60 deg)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None) -> TaskConfig:
        data = dict(data or {})
        parts = {"commands": CommandConfig, "rewards": RewardConfig, "gait": GaitConfig, "noise": NoiseConfig}
        kwargs: dict[str, Any] = {}
        names = {f.name for f in fields(cls)}
        for key, value in data.items():
            if key not in names:
                raise UserError(f"task config: unknown field '{key}'; known: {sorted(names)}", field=key)
            if key in parts:
                sub = parts[key]
                sub_names = {f.name for f in fields(sub)}
                if key == "commands":  # replaced by curriculum_max_fall_rate (older checkpoints)
                    value = {k: v for k, v in value.items() if k != "curriculum_max_fall_share"}
                bad = sorted(set(value) - sub_names)
                if bad:
                    raise UserError(f"task config '{key}': unknown field(s) {bad}", field=key)
                value = sub(**{k: tuple(v) if isinstance(v, list) else v for k, v in value.items()})
            kwargs[key] = value
        return cls(**kwargs)
