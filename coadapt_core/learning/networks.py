"""Networks of the universal policy: MLP trunks, the Gaussian actor pi(a | o, xi) and its
mean on its own (`MeanActor`), the critic V(s, xi), the pseudo-critics V_pseudo(s, xi) and
running observation normalisers."""

from __future__ import annotations

import re

import torch
from torch import nn

_ACTIVATIONS = {"elu": nn.ELU, "relu": nn.ReLU, "tanh": nn.Tanh}


def mlp(
    inputs: int, outputs: int, hidden: tuple[int, ...], activation: str = "elu"
) -> nn.Sequential:
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

    def __init__(
        self,
        num_obs: int,
        num_design: int,
        num_actions: int,
        hidden,
        activation: str,
        init_std: float,
    ):
        super().__init__()
        self.body = mlp(num_obs + num_design, num_actions, hidden, activation)
        self.log_std = nn.Parameter(
            torch.full((num_actions,), float(torch.log(torch.tensor(init_std))))
        )

    def forward(self, obs: torch.Tensor, design: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        loc = self.body(torch.cat([obs, design], dim=-1))
        scale = self.log_std.clamp(-5.0, 2.0).exp().expand_as(loc)
        return loc, scale


class MeanActor(nn.Module):
    """The mean of pi(a | o, xi) on its own, for inference and export: raw observations
    [B, num_obs] and normalised designs [B, num_design] -> mean actions [B, num_actions].
    The observation normaliser's statistics are constants here (buffers, never updated), so
    a tracer writes them into the graph. Eval mode from the start; `PPO.mean_actor` builds it.
    """

    def __init__(self, body: nn.Module, norm: EmpiricalNormalization):
        super().__init__()
        self.body = body
        # what EmpiricalNormalization.forward computes: (obs - mean) / sqrt(var + eps), clipped
        self.register_buffer("obs_mean", norm.mean.detach().float().clone())
        self.register_buffer("obs_std", torch.sqrt(norm.var.detach().float() + norm.eps))
        self.obs_clip = float(norm.clip)
        self.eval()

    def forward(self, obs: torch.Tensor, design: torch.Tensor) -> torch.Tensor:
        normed = ((obs - self.obs_mean) / self.obs_std).clamp(-self.obs_clip, self.obs_clip)
        return self.body(torch.cat([normed, design], dim=-1))

    def normalisation(self) -> tuple[list[float], list[float], float]:
        """(mean [num_obs], std [num_obs], clip) of the observation normalisation it applies:
        clip((obs - mean) / std, -clip, clip)."""
        return self.obs_mean.tolist(), self.obs_std.tolist(), self.obs_clip


class ValueNet(nn.Module):
    """V(s, xi): the critic, one MLP (`heads.0`)."""

    def __init__(
        self, num_critic_obs: int, num_design: int, hidden, activation: str, outputs: int = 1
    ):
        super().__init__()
        self.heads = nn.ModuleList(
            mlp(num_critic_obs + num_design, 1, hidden, activation) for _ in range(outputs)
        )

    def forward(self, critic_obs: torch.Tensor, design: torch.Tensor) -> torch.Tensor:
        x = torch.cat([critic_obs, design], dim=-1)
        return torch.cat([head(x) for head in self.heads], dim=-1)  # [*, outputs]


#: state-dict keys of the per-head layout that `CriticBank` replaced: heads.<h>.<2 k>.<weight|bias>
_PER_HEAD_KEY = re.compile(r"^heads\.(\d+)\.(\d+)\.(weight|bias)$")


class CriticBank(nn.Module):
    """H independent MLPs (the pseudo-critics, one per objective) on the same input (s, xi),
    computed as one ensemble: layer k's weights of all heads are stacked into `weight_k`
    [H, out, in] and `bias_k` [H, out], and each layer is one batched matrix product
    (`torch.baddbmm`) instead of H small ones in a Python loop. Head h is still its own MLP
    (hidden sizes, activation, initialisation as `mlp`): nothing is shared between heads, so
    outputs, gradients and Adam updates equal those of H separate `mlp`s (tested).

    Checkpoints of the per-head layout (`heads.<h>.<layer>.weight`) are converted on load
    (`convert_state_dict`)."""

    def __init__(self, num_critic_obs: int, num_design: int, hidden, activation: str, outputs: int):
        super().__init__()
        if outputs < 1:
            raise ValueError("a critic bank needs at least one head")
        self.num_heads = int(outputs)
        self.act = _ACTIVATIONS[activation]()
        # initialised head by head as separate MLPs would be (same random draws, same order)
        heads = [mlp(num_critic_obs + num_design, 1, hidden, activation) for _ in range(outputs)]
        linears = [[m for m in head if isinstance(m, nn.Linear)] for head in heads]
        self.num_layers = len(linears[0])
        for k in range(self.num_layers):
            weight = torch.stack([layers[k].weight.detach() for layers in linears])  # [H, out, in]
            bias = torch.stack([layers[k].bias.detach() for layers in linears])  # [H, out]
            self.register_parameter(f"weight_{k}", nn.Parameter(weight.clone()))
            self.register_parameter(f"bias_{k}", nn.Parameter(bias.clone()))

    def layer(self, k: int) -> tuple[torch.Tensor, torch.Tensor]:
        return getattr(self, f"weight_{k}"), getattr(self, f"bias_{k}")

    def forward(self, critic_obs: torch.Tensor, design: torch.Tensor) -> torch.Tensor:
        x = torch.cat([critic_obs, design], dim=-1)
        lead = x.shape[:-1]
        h = x.reshape(1, -1, x.shape[-1]).expand(self.num_heads, -1, -1)  # [H, B, in], no copy
        for k in range(self.num_layers):
            weight, bias = self.layer(k)
            # [H, B, out] = bias + h @ W^T, one batched product for all heads
            h = torch.baddbmm(bias.unsqueeze(1), h, weight.transpose(1, 2))
            if k < self.num_layers - 1:
                h = self.act(h)
        return h.squeeze(-1).transpose(0, 1).reshape(*lead, self.num_heads)  # [*, H]

    @staticmethod
    def convert_state_dict(state: dict | None) -> dict | None:
        """A per-head state dict (`heads.<h>.<2 k>.weight|bias`, written before the bank was
        batched) in the stacked layout; a stacked one is returned as it is."""
        if state is None or not any(_PER_HEAD_KEY.match(key) for key in state):
            return state
        parts: dict[tuple[int, str], dict[int, torch.Tensor]] = {}
        for key, tensor in state.items():
            match = _PER_HEAD_KEY.match(key)
            if match is None:
                raise ValueError(f"unexpected key '{key}' in a per-head pseudo-critic state")
            head, index, kind = int(match[1]), int(match[2]), match[3]
            parts.setdefault((index // 2, kind), {})[head] = tensor
        out = {}
        for (k, kind), by_head in sorted(parts.items()):
            out[f"{kind}_{k}"] = torch.stack([by_head[h] for h in sorted(by_head)])
        return out

    @staticmethod
    def convert_optimizer_state(state: dict | None, num_heads: int, num_layers: int) -> dict | None:
        """An Adam state of the per-head layout (parameters ordered head by head, weight then
        bias per layer) for the stacked parameters (`weight_0, bias_0, weight_1, ...`); None
        when it cannot be converted (then the optimizer starts fresh)."""
        if state is None:
            return None
        group = state["param_groups"]
        per_head = 2 * num_layers
        if len(group) != 1:
            return None
        ids = group[0]["params"]
        inner = state["state"]
        moments = [v["exp_avg"] for v in inner.values() if "exp_avg" in v]
        if moments and moments[0].dim() == 3:  # already stacked: weight_0's moment is [H, out, in]
            ok = len(ids) == per_head and all(m.shape[0] == num_heads for m in moments)
            return state if ok else None
        if len(ids) != num_heads * per_head:
            return None
        if not all(i in inner for i in ids):
            return None
        new_state = {}
        for j in range(per_head):  # j = 2 k (weight) or 2 k + 1 (bias): the bank's order
            rows = [inner[ids[h * per_head + j]] for h in range(num_heads)]
            new_state[j] = {
                "step": rows[0]["step"].clone()
                if torch.is_tensor(rows[0]["step"])
                else rows[0]["step"],
                "exp_avg": torch.stack([r["exp_avg"] for r in rows]),
                "exp_avg_sq": torch.stack([r["exp_avg_sq"] for r in rows]),
            }
        groups = [{**group[0], "params": list(range(per_head))}]
        return {"state": new_state, "param_groups": groups}
