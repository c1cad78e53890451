"""Left-right symmetry augmentation of the PPO update (`TrainConfig.symmetry`), as rsl_rl's
data augmentation: every minibatch is joined by its mirror image, so the policy learns both
sides from one sample.

The mirror is the robot's (`Robot.mirror`: joints and legs of the image, with signs, and the
design variables that trade places); here it becomes signed index maps over the layouts of
`coadapt_core.task.observations`. Base-frame vectors reflect through the x-z plane: a polar
vector (linear velocity, gravity, CoM shift) negates y, an axial one (angular velocity)
negates x and z, the command (vx, vy, yaw rate) negates vy and the yaw rate. The gait
clock's phase moves by the difference of the phase offsets of the legs that trade places
(a biped's 0.5: sin and cos negated). A mirrored sample keeps its original advantage, value
target and log-probability (the mirror image of the behaviour policy's Gaussian gives the
mirrored action that probability); the approximate KL that sets the adaptive learning rate
is the original half's, as in rsl_rl. The pseudo-critics regress on the original half only.

The rollout holds normalised observations: the image is taken of the raw values (the
normaliser's current statistics undone, then applied again), so a mirrored sample is what
the policy would have read in the mirrored state.
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from coadapt_core.errors import UserError
from coadapt_core.robot import Mirror

POLAR, AXIAL, COMMAND = (1.0, -1.0, 1.0), (-1.0, 1.0, -1.0), (1.0, -1.0, -1.0)
#: layout entries that are vectors in the base frame: their signs under the reflection
VECTORS = {
    "base_lin_vel": POLAR,
    "base_ang_vel": AXIAL,
    "projected_gravity": POLAR,
    "command": COMMAND,
    "com_shift": POLAR,
}
#: layout entries the reflection leaves as they are
SCALARS = {"base_height", "friction", "restitution", "pd_factor", "motor_strength", "delay"}
#: the PPO loss terms averaged over the two halves (the rest, KL included, are the original's)
LOSS_TERMS = ("loss_objective", "loss_critic", "loss_entropy", "entropy")


def _refuse(why: str) -> UserError:
    return UserError(f"symmetry: the robot's mirror map {why}", field="symmetry")


def _check_involution(perm: tuple[int, ...], size: int, what: str) -> None:
    if sorted(perm) != list(range(size)):
        raise _refuse(f"does not permute the {size} {what}: {list(perm)}")
    if any(perm[perm[k]] != k for k in range(size)):
        raise _refuse(f"is not its own inverse on the {what}: {list(perm)}")


def clock_sign(mirror: Mirror, offsets: list[float]) -> float:
    """+1 or -1: the gait clock features' sign in the mirror image. Leg l of the image does
    what leg legs[l] did, so the clock moves by offsets[legs[l]] - offsets[l], the same for
    every leg (0 or 0.5 for a map that is its own inverse) or there is no mirrored gait."""
    shifts = {round((offsets[m] - offsets[k]) % 1.0, 6) % 1.0 for k, m in enumerate(mirror.legs)}
    if shifts == {0.0}:
        return 1.0
    if shifts == {0.5}:
        return -1.0
    raise _refuse(
        f"does not carry the gait to itself: the legs' phase offsets {offsets} move by "
        f"{sorted(shifts)} (one shift, 0 or 0.5, is needed)"
    )


def layout_map(
    layout: list[tuple[str, int]], mirror: Mirror, clock: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """(index [n], sign [n]): entry i of an image is sign[i] * x[index[i]], over a layout."""
    joints, legs = list(mirror.joints), list(mirror.legs)
    index: list[int] = []
    sign: list[float] = []
    start = 0
    for name, size in layout:
        if name in VECTORS:
            local, signs = [0, 1, 2], list(VECTORS[name])
        elif name in SCALARS:
            local, signs = list(range(size)), [1.0] * size
        elif name in ("joint_pos", "joint_vel", "action_history"):
            blocks = size // len(joints)
            local = [b * len(joints) + k for b in range(blocks) for k in joints]
            signs = list(mirror.joint_signs) * blocks
        elif name in ("foot_contact", "foot_height"):
            local, signs = legs, [1.0] * size
        elif name == "clock":
            local, signs = [0, 1], [clock, clock]
        else:
            raise ValueError(f"symmetry: no mirror rule for the observation entry '{name}'")
        if len(local) != size:
            raise _refuse(f"does not fit the observation entry '{name}' ({size} values)")
        index += [start + i for i in local]
        sign += signs
        start += size
    return torch.tensor(index), torch.tensor(sign)


class MirrorMaps:
    """The signed index maps of one environment's layouts, and the mirror image of rollout
    rows. `for_env` builds them from the environment's robot."""

    def __init__(
        self,
        mirror: Mirror,
        policy_layout: list[tuple[str, int]],
        critic_layout: list[tuple[str, int]],
        offsets: list[float],
        design_names: list[str],
        norms: tuple,
    ):
        _check_involution(tuple(mirror.joints), len(mirror.joint_signs), "joints")
        _check_involution(tuple(mirror.legs), len(offsets), "legs")
        if any(s not in (1.0, -1.0) for s in mirror.joint_signs):
            raise _refuse(f"has joint signs other than +1 and -1: {list(mirror.joint_signs)}")
        if any(mirror.joint_signs[k] != mirror.joint_signs[m] for k, m in enumerate(mirror.joints)):
            raise _refuse("gives a joint and its image different signs")
        clock = clock_sign(mirror, offsets)
        unknown = sorted(set(mirror.designs) - set(design_names))
        swapped = [mirror.designs.get(n, n) for n in design_names]
        if unknown or sorted(swapped) != sorted(design_names):
            raise _refuse(f"trades design variables {dict(mirror.designs)} not in {design_names}")
        self.obs_norm, self.critic_norm = norms  # the learner's: their statistics at the update
        device = self.obs_norm.mean.device
        put = lambda pair: tuple(t.to(device) for t in pair)  # noqa: E731
        self.obs = put(layout_map(policy_layout, mirror, clock))
        self.critic = put(layout_map(critic_layout, mirror, clock))
        self.action = put((torch.tensor(mirror.joints), torch.tensor(mirror.joint_signs)))
        self.design = torch.tensor([design_names.index(n) for n in swapped], device=device)

    @classmethod
    def for_env(cls, robot, env, ppo) -> MirrorMaps:
        """The maps of `robot`'s mirror (a one-line `UserError` when it has none) over
        `env`'s layouts, legs and design variables, for the learner `ppo`."""
        mirror = robot.mirror()
        offsets = [float(leg.phase_offset) for leg in robot.legs()]
        names = list(robot.design_space_for(env.sim.designs[0]).names)
        norms = (ppo.obs_norm, ppo.critic_norm)
        return cls(mirror, env.policy_layout, env.critic_layout, offsets, names, norms)

    @staticmethod
    def apply(x: torch.Tensor, pair: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
        """The image of raw rows x [..., n] under an (index, sign) map."""
        return x[..., pair[0]] * pair[1].to(x.dtype)

    def _normed(self, x: torch.Tensor, norm, pair) -> torch.Tensor:
        std = torch.sqrt(norm.var + norm.eps)
        raw = self.apply(x * std + norm.mean, pair)
        return ((raw - norm.mean) / std).clamp(-norm.clip, norm.clip)

    @torch.no_grad()
    def image(self, rows: TensorDict) -> TensorDict:
        """The mirror image of rollout rows (normalised observations, as `PPO.act` stores
        them): observations, critic states, designs and actions mirrored; log-probabilities,
        advantages and targets as they were."""
        out = rows.clone(False)  # the unchanged entries shared, not copied
        out["obs"] = self._normed(rows["obs"], self.obs_norm, self.obs)
        out["critic_obs"] = self._normed(rows["critic_obs"], self.critic_norm, self.critic)
        out["design_obs"] = rows["design_obs"][..., self.design]
        out["action"] = self.apply(rows["action"], self.action)
        return out

    @staticmethod
    def joined(out, mirrored) -> dict:
        """The PPO loss's outputs over a minibatch and its image: the loss terms averaged
        (the minibatch extended by its image), the rest (the approximate KL) the original's."""
        joined = dict(out.items())
        joined.update({k: 0.5 * (out[k] + mirrored[k]) for k in LOSS_TERMS})
        return joined
