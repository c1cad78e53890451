"""PPO and training settings, one documented dataclass (each field maps onto a CLI option
or a config key). Defaults are those meant for the long GPU run (walking-notes.md, legged_gym
practice); a CPU smoke run overrides the sizes."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

import torch

from coadapt_core.errors import UserError

PRECISIONS = ("auto", "float32", "bf16")


def resolve_precision(precision: str, device: str | torch.device) -> str:
    """"float32" or "bf16" for a configured precision on `device` ("auto": bf16 where the
    device computes bfloat16 natively)."""
    if precision != "auto":
        return precision
    device = torch.device(device)
    if device.type == "cuda":
        return "bf16" if torch.cuda.is_available() and torch.cuda.is_bf16_supported() else "float32"
    if device.type == "cpu":
        return "bf16" if torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported() else "float32"
    return "float32"


@dataclass
class TrainConfig:
    # -- batch ------------------------------------------------------------------------------
    num_designs: int = 128  # K designs sampled from the current range per training phase
    agents_per_design: int = 32  # environments per design; num_envs = K x agents (4096)
    steps_per_env: int = 24  # rollout length per update (4096 x 24 = 98 304 samples)
    design_resample_every: int = 0  # iterations between new design draws (0: fixed, Alg. 1)
    # -- PPO --------------------------------------------------------------------------------
    epochs: int = 5
    minibatches: int = 4
    learning_rate: float = 1.0e-3
    schedule: str = "adaptive"  # "adaptive" (KL-based, rsl_rl) | "fixed"
    desired_kl: float = 0.01
    gamma: float = 0.99
    lam: float = 0.95
    clip_param: float = 0.2
    entropy_coef: float = 0.005
    value_loss_coef: float = 1.0
    max_grad_norm: float = 1.0
    init_noise_std: float = 1.0  # Gaussian policy, state-independent learned log-std
    # -- networks (paper section 4: MLP [512, 256, 128] for policy, critic, pseudo-critics) --
    hidden: tuple[int, ...] = (512, 256, 128)
    activation: str = "elu"
    # -- pseudo-critics (section 3.2.2) ----------------------------------------------------
    pseudo_learning_rate: float = 1.0e-3
    pseudo_lam: float = 0.95  # TD(lambda) of the discounted-average metric target
    # epochs of pseudo-critic regression per update (0: as many as PPO's). One epoch: the
    # three [512, 256, 128] pseudo-critics are 1.5x the multiply-adds of actor + critic, so at
    # PPO's 5 epochs they were 0.55 of the update on a CPU (the paper: 3 % of training time);
    # at 1 they are about 0.2 and still see every sample of every rollout once. The surrogate
    # is fitted to each real round's labelled designs from them anyway (learning/surrogate.py).
    # docs/training.md (Throughput) has the measurements
    pseudo_epochs: int = 1
    # numerics of the forward passes of the PPO loss (precision) and of the pseudo-critic
    # regression (pseudo_precision): "float32", "bf16" (autocast to bfloat16; parameters,
    # optimizer states and losses stay float32) or "auto" (bf16 where the device computes it
    # natively: a CUDA GPU with bf16, a CPU with avx512_bf16/AMX; float32 elsewhere).
    # docs/training.md (Throughput) has the measurements behind the defaults: with bf16
    # pseudo-critics the policy's curve is float32's exactly (they never touch the policy) and
    # their loss stays within 0.5 % of float32's on the same data; with a bf16 PPO loss three
    # seeds' rewards stayed within the float32 seeds' spread
    precision: str = "auto"
    pseudo_precision: str = "auto"
    # -- bookkeeping ------------------------------------------------------------------------
    checkpoint_every: int = 100  # iterations
    device: str = "cpu"
    # CPU threads of the learner's update (compute_returns + PPO epochs); 0 = every core the
    # process may use. Collection always runs torch on one thread: the physics backend's
    # threads own the cores then (torch's spin-waiting OpenMP threads beside them cost a
    # third of the collection rate on a 2-core machine)
    torch_threads: int = 0
    seed: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        positive = ("num_designs", "agents_per_design", "steps_per_env", "epochs", "minibatches")
        for name in positive:
            if int(getattr(self, name)) < 1:
                raise UserError(f"train.{name} must be >= 1, got {getattr(self, name)}", field=name)
        if self.schedule not in ("adaptive", "fixed"):
            raise UserError(f"train.schedule '{self.schedule}' is not one of: adaptive, fixed", field="schedule")
        if not (0.0 < self.gamma < 1.0) or not (0.0 <= self.lam <= 1.0):
            raise UserError("train.gamma must lie in (0, 1) and train.lam in [0, 1]", field="gamma")
        for name in ("precision", "pseudo_precision"):
            if getattr(self, name) not in PRECISIONS:
                raise UserError(f"train.{name} '{getattr(self, name)}' is not one of: {', '.join(PRECISIONS)}", field=name)
        if self.activation not in ("elu", "relu", "tanh"):
            raise UserError(f"train.activation '{self.activation}' is not one of: elu, relu, tanh", field="activation")
        self.hidden = tuple(int(h) for h in self.hidden)

    @property
    def num_envs(self) -> int:
        return self.num_designs * self.agents_per_design

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None) -> TrainConfig:
        data = dict(data or {})
        names = {f.name for f in fields(cls)}
        bad = sorted(set(data) - names)
        if bad:
            raise UserError(f"train config: unknown field(s) {bad}; known: {sorted(names)}", field="train")
        return cls(**data)
