"""Networks of the universal policy: MLP trunks, the Gaussian actor pi(a | o, xi), the
critic V(s, xi), the pseudo-critics V_pseudo(s, xi) and running observation normalisers."""

from __future__ import annotations

import torch
from torch import nn

_ACTIVATIONS = {"elu": nn.ELU, "relu": nn.ReLU, "tanh": nn.Tanh}


def mlp(inputs: int, outputs: int, hidden: tuple[int, ...], activation: str = "elu") -> nn.Sequential:
    layers: list[nn.Module] = []
    size = inputs
    for h in hidden:
        layers += [nn.Linear(size, h), _ACTIVATIONS[activation]()]
        size = h
    layers.append(nn.Linear(size, outputs))
    return nn.Sequential(*layers)


class EmpiricalNormalization(nn.Module):
    """Running mean / std of inputs [*, n] (Chan's parallel update), frozen in eval mode.
    Its buffers travel in state dicts, hence in checkpoints and weight exports."""

    def __init__(self, size: int, eps: float = 1e-2, clip: float = 5.0):
        super().__init__()
        self.eps = eps
        self.clip = clip
        self.register_buffer("mean", torch.zeros(size))
        self.register_buffer("var", torch.ones(size))
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        x = x.reshape(-1, x.shape[-1]).float()
        n = x.shape[0]
        if n == 0:
            return
        batch_mean = x.mean(0)
        batch_var = x.var(0, unbiased=False)
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean += delta * (n / total).float()
        m_a = self.var * self.count.float()
        m_b = batch_var * n
        self.var.copy_((m_a + m_b + delta**2 * (self.count * n / total).float()) / total.float())
        self.count.copy_(total)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return ((x - self.mean) / torch.sqrt(self.var + self.eps)).clamp(-self.clip, self.clip)


class ActorNet(nn.Module):
    """Mean of pi(a | o, xi) from the normalised observation and design; the std is a learned
    state-independent parameter (log-std), as in rsl_rl."""

    def __init__(self, num_obs: int, num_design: int, num_actions: int, hidden, activation: str, init_std: float):
        super().__init__()
        self.body = mlp(num_obs + num_design, num_actions, hidden, activation)
        self.log_std = nn.Parameter(torch.full((num_actions,), float(torch.log(torch.tensor(init_std)))))

    def forward(self, obs: torch.Tensor, design: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        loc = self.body(torch.cat([obs, design], dim=-1))
        scale = self.log_std.clamp(-5.0, 2.0).exp().expand_as(loc)
        return loc, scale


class ValueNet(nn.Module):
    """V(s, xi) (outputs 1) or a bank of pseudo-critics (one MLP per objective)."""

    def __init__(self, num_critic_obs: int, num_design: int, hidden, activation: str, outputs: int = 1):
        super().__init__()
        self.heads = nn.ModuleList(mlp(num_critic_obs + num_design, 1, hidden, activation) for _ in range(outputs))

    def forward(self, critic_obs: torch.Tensor, design: torch.Tensor) -> torch.Tensor:
        x = torch.cat([critic_obs, design], dim=-1)
        return torch.cat([head(x) for head in self.heads], dim=-1)  # [*, outputs]
