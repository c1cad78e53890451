"""PPO and training settings, one documented dataclass (each field maps onto a CLI option
or a config key). Defaults are those meant for the long GPU run (walking-notes.md, legged_gym
practice); a CPU smoke run overrides the sizes."""

from __future__ import annotations

from dataclasses import asdict
from typing import TYPE_CHECKING, Any, Literal

from coadapt_core.settings import Float, Int, Ints, setting, settings

if TYPE_CHECKING:  # torch loads only when a precision is resolved: the CLI starts without it
    import torch

PRECISIONS = ("auto", "float32", "bf16")


def resolve_precision(precision: str, device: str | torch.device) -> str:
    """ "float32" or "bf16" for a configured precision on `device` ("auto": bf16 where the
    device computes bfloat16 natively)."""
    if precision != "auto":
        return precision
    import torch

    device = torch.device(device)
    if device.type == "cuda":
        return "bf16" if torch.cuda.is_available() and torch.cuda.is_bf16_supported() else "float32"
    if device.type == "cpu":
        return (
            "bf16"
            if torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported()
            else "float32"
        )
    return "float32"


@settings(prefix="train")
class TrainConfig:
    # -- batch ------------------------------------------------------------------------------
    num_designs: Int = setting(
        128, "K designs sampled from the current range per training phase.", ge=1
    )
    agents_per_design: Int = setting(32, "Environments per design; num_envs = K x agents.", ge=1)
    steps_per_env: Int = setting(24, "Rollout length per PPO update.", ge=1)
    design_resample_every: Int = setting(
        0, "Iterations between new design draws (0: fixed designs, Algorithm 1).", ge=0
    )
    # -- PPO --------------------------------------------------------------------------------
    epochs: Int = setting(5, "PPO epochs per update.", ge=1)
    minibatches: Int = setting(4, "Minibatches per epoch.", ge=1)
    learning_rate: Float = setting(1.0e-3, "Initial learning rate.", gt=0, lt=1)
    schedule: Literal["adaptive", "fixed"] = setting(
        "adaptive", "Learning-rate schedule: adaptive (KL-based, rsl_rl) or fixed."
    )
    desired_kl: Float = setting(0.01, "KL divergence the adaptive schedule aims at.", gt=0)
    gamma: Float = setting(0.99, "Discount factor.", gt=0, lt=1)
    lam: Float = setting(0.95, "GAE lambda.", ge=0, le=1)
    clip_param: Float = setting(0.2, "PPO clip range.", gt=0)
    entropy_coef: Float = setting(0.005, "Entropy bonus coefficient.", ge=0)
    value_loss_coef: Float = setting(1.0, "Value loss coefficient.", ge=0)
    max_grad_norm: Float = setting(1.0, "Gradient norm clip.", gt=0)
    symmetry: bool = setting(
        False,
        "Join each PPO minibatch by its left-right mirror image (the robot's mirror map; "
        "refused for a robot without one).",
    )
    init_noise_std: Float = setting(
        1.0, "Initial std of the Gaussian policy (state-independent, learned).", gt=0
    )
    # -- networks (paper section 4: MLP [512, 256, 128] for policy, critic, pseudo-critics) --
    hidden: Ints = setting(
        (512, 256, 128), "Hidden layer sizes of policy, critic and pseudo-critics."
    )
    activation: Literal["elu", "relu", "tanh"] = setting("elu", "Activation of the hidden layers.")
    # -- pseudo-critics (section 3.2.2) ----------------------------------------------------
    pseudo_learning_rate: Float = setting(1.0e-3, "Learning rate of the pseudo-critics.", gt=0)
    pseudo_lam: Float = setting(
        0.95, "TD(lambda) of the pseudo-critics' discounted-average metric target.", ge=0, le=1
    )
    # epochs of pseudo-critic regression per update (0: as many as PPO's). One epoch: the
    # three [512, 256, 128] pseudo-critics are 1.5x the multiply-adds of actor + critic, so at
    # PPO's 5 epochs they were 0.55 of the update on a CPU (the paper: 3 % of training time);
    # at 1 they are about 0.2 and still see every sample of every rollout once. The surrogate
    # is fitted to each real round's labelled designs from them anyway (learning/surrogate.py).
    # docs/training.md (Throughput) has the measurements
    pseudo_epochs: Int = setting(
        1, "Epochs of pseudo-critic regression per update (0: as many as PPO's).", ge=0
    )
    # numerics of the forward passes of the PPO loss (precision) and of the pseudo-critic
    # regression (pseudo_precision): "float32", "bf16" (autocast to bfloat16; parameters,
    # optimizer states and losses stay float32) or "auto" (bf16 where the device computes it
    # natively: a CUDA GPU with bf16, a CPU with avx512_bf16/AMX; float32 elsewhere).
    # docs/training.md (Throughput) has the measurements behind the defaults: with bf16
    # pseudo-critics the policy's curve is float32's exactly (they never touch the policy) and
    # their loss stays within 0.5 % of float32's on the same data; with a bf16 PPO loss three
    # seeds' rewards stayed within the float32 seeds' spread
    precision: Literal[PRECISIONS] = setting(
        "auto", "Numerics of the PPO loss's forward passes (auto: bf16 where native)."
    )
    pseudo_precision: Literal[PRECISIONS] = setting(
        "auto", "Numerics of the pseudo-critic regression."
    )
    # -- bookkeeping ------------------------------------------------------------------------
    checkpoint_every: Int = setting(50, "Iterations between checkpoints (coadapt train).", ge=1)
    device: str = setting("cpu", "Torch device of the learner.", cli=False)
    # earlier versions' learner threads, still in their checkpoints (the six shipped policies
    # record 1): read and kept, never used. The thread budget decides (`coadapt_core.threads`:
    # --threads, else the CPUs the process may use), for the update and the physics alike
    torch_threads: Int = setting(
        0, "Not used (earlier versions' learner threads; --threads decides now).", ge=0, cli=False
    )
    seed: Int = setting(0, "Random seed.", ge=0, cli=False)
    extra: dict[str, Any] = setting(
        default_factory=dict, help="Free-form notes kept with a checkpoint.", cli=False
    )

    @property
    def num_envs(self) -> int:
        return self.num_designs * self.agents_per_design

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None) -> TrainConfig:
        """A recorded training config (a checkpoint's); unknown keys are one-line errors."""
        return cls(**dict(data or {}))


#: what `coadapt train` starts from for a robot with no shipped policy for the terrain and
#: design space asked for (issue 53): 16 designs x 16 agents (256 environments, 6 144 samples
#: an update) and 2 PPO epochs, the rest TrainConfig's defaults. Qilin from scratch, walking
#: gate at the nominal design and the four corners (benchmarks/time_to_walk.py, two seeds):
#: docs/training.md ("Time to walk") has the study. Kuafu's shipped policies and the paper's
#: comparison keep TrainConfig's defaults (128 x 32, 5 epochs).
NEW_ROBOT_RECIPE: dict[str, Any] = {"num_designs": 16, "agents_per_design": 16, "epochs": 2}


#: what the new-robot recipe sets in the task (TaskConfig's nested settings) for a robot with
#: that many legs (issue 59); other leg counts keep TaskConfig's defaults. Two legs: feet
#: contacts that match the gait clock's stance schedule pay four times as much, and the
#: tracking kernel narrows from exp(-e^2 / 0.25) to exp(-e^2 / 0.05), so a biped standing
#: still under the curriculum's first +-0.3 m/s box earns about 0.46 of the tracking term,
#: not 0.85 (above the 0.8 that widens the box). nezha, which stood and never stepped
#: without them, walked from scratch with both at seeds 0 and 1 (9.66 M and 8.55 M
#: interactions): docs/training.md, "Time to walk".
NEW_ROBOT_TASK_RECIPE: dict[int, dict[str, Any]] = {
    2: {"rewards": {"weights": {"contact_match": 4.0}, "tracking_sigma": 0.05}},
}


#: what the new-robot recipe sets in the training config for a robot with that many legs
#: (issue 59), each where the robot supports it. Two legs: left-right symmetry (`symmetry`,
#: the robot's mirror map), kept off for a robot that declares none. With it nezha walked
#: from scratch after 4.13 M interactions against 7.37 M without (seed 0), and jingwei after
#: 2.36 M and 8.55 M (seeds 0 and 1) where without it seed 0 had not walked in 14.0 M and
#: seed 1 by 7.7 M: docs/training.md, "Time to walk". Its cost: the update's +24 %.
NEW_ROBOT_TRAIN_RECIPE: dict[int, dict[str, Any]] = {2: {"symmetry": True}}


def new_robot_config(**given: Any) -> TrainConfig:
    """TrainConfig with `NEW_ROBOT_RECIPE` over its defaults (and `given` over both)."""
    return TrainConfig(**{**NEW_ROBOT_RECIPE, **given})
