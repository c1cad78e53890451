"""Pseudo-critics fitted to the current design range (issue 16; docs/coadaptation.md, "The
surrogate").

The paper's surrogate (Algorithm 3) is the mean of V_pseudo(s, xi) over states s drawn from
the evaluation buffer with the candidate's xi substituted. Trained only through PPO's
TD targets, the pseudo-critics barely depend on xi (the state already tells them how the
robot moves), so substituting xi changes little and the estimate does not rank designs.

A real round measures each of its designs' cost exactly on one scenario set. `fit_ensemble`
uses those labels: it copies the trained pseudo-critics of the run's objectives into
`members` heads (one `CriticBank`, so all members cost one batched pass) and regresses each
on pairs (s, xi_j) -> cost_j, s drawn uniformly from the buffer and j from that member's
bootstrap resample of the labelled designs. The state is drawn independently of the design
on purpose: the regression target is then E_s[V(s, xi_j)] = cost_j, exactly the quantity
Algorithm 3 computes, and the only way to fit it is through xi. The estimator stays the
paper's (mean of V over buffer states), averaged over the members; the members' spread is
the ensemble's uncertainty (`--evaluation-policy uncertainty`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import torch

from coadapt_core.learning.networks import CriticBank
from coadapt_core.learning.pseudo_critics import PseudoCritics

#: defaults of the fit (measured on flat with the shipped policy; docs/coadaptation.md)
MEMBERS = 5
FIT_STEPS = 100
BATCH = 64
#: the members read designs in the frame of the labelled designs' box (False: the full space's)
LOCAL_FRAME = True
#: at most this half-width of the box (in the full space's [-1, 1] units) is stretched to 1
MIN_HALF_WIDTH = 0.05
#: the loss's unit: the labelled costs' spread, at least this share of their mean
SPREAD_FLOOR = 0.001
#: buffer states behind the fit's final level correction (members average 1/E of them each)
CHECK_STATES = 1024
LEARNING_RATE = 3e-3


@dataclass
class FittedEnsemble:
    bank: CriticBank  # members x M heads, member-major (head e * M + j)
    members: int
    scale: torch.Tensor  # [M] member e's output = raw * scale + offset[e] (in cost units)
    offset: torch.Tensor  # [E, M]
    labels: int  # labelled designs it was fitted on
    center: torch.Tensor | None = (
        None  # [D] the members read (xi - center) / half (local design frame)
    )
    half: torch.Tensor | None = None  # [D]

    def frame(self, xi: torch.Tensor) -> torch.Tensor:
        return xi if self.center is None else (xi - self.center) / self.half

    @torch.no_grad()
    def predict(self, states: torch.Tensor, xi: torch.Tensor, chunk: int = 8) -> torch.Tensor:
        """[E, K, M]: each member's mean prediction for each design xi [K, D] (normalised)
        over its share of `states` [S, C] (normalised): member e averages states e, e + E,
        e + 2 E, ..., so the ensemble costs what one pass of the paper's surrogate over S
        states costs, and the members' spread includes the sampling of states.

        The first layer is linear in (s, xi), so its state part is computed once per head
        and each design only adds its own part: the same sums as the concatenated input's,
        in another order (equal to float rounding)."""
        m, e = self.scale.shape[0], self.members
        xi = self.frame(xi)
        per = max(1, states.shape[0] // e)
        shares = (
            states[: per * e].reshape(per, e, -1).transpose(0, 1)
            if states.shape[0] >= e
            else states.expand(e, -1, -1)
        )
        c = shares.shape[-1]
        weight, bias = self.bank.layer(0)  # [E M, H, C + D], [E M, H]
        state_part = torch.bmm(
            shares.repeat_interleave(m, dim=0), weight[..., :c].transpose(1, 2)
        )  # [E M, S/E, H]
        design_part = torch.einsum("kd,ghd->gkh", xi, weight[..., c:]) + bias.unsqueeze(
            1
        )  # [E M, K, H]
        out = []
        for k0 in range(0, xi.shape[0], chunk):
            part = design_part[:, k0 : k0 + chunk]  # [E M, b, H]
            b = part.shape[1]
            h = state_part.unsqueeze(1) + part.unsqueeze(2)  # [E M, b, S/E, H]
            raw = _per_head(self.bank, h.reshape(e * m, -1, h.shape[-1]), first=1)  # [E M, b S/E]
            raw = raw.reshape(e, m, b, -1).mean(dim=-1).transpose(1, 2)  # [E, b, M]
            out.append(raw * self.scale + self.offset.unsqueeze(1))
        return torch.cat(out, dim=1)  # [E, K, M]


def paper_estimate(
    critics: PseudoCritics, columns: list[int], states: torch.Tensor, xi: torch.Tensor
) -> np.ndarray:
    """[K, n] Algorithm 3: the mean over `states` [S, C] (normalised) of the pseudo-critics
    `columns` (n of them) at each design of `xi` [K, D] (normalised), in cost units.

    Only the heads of `columns` are computed (each head is its own MLP: the same values, to
    the bit, as computing every head and keeping these columns; one head alone is computed
    twice, because a batch of one takes another matrix-product path, 1e-6 apart)."""
    bank = critics.bank
    idx = torch.as_tensor(
        columns * 2 if len(columns) == 1 and bank.num_heads > 1 else columns, dtype=torch.long
    )
    layers = [(w[idx], b[idx]) for w, b in (bank.layer(k) for k in range(bank.num_layers))]
    scale, offset = critics.scale[idx], critics.offset[idx]
    out = []
    for k in range(xi.shape[0]):  # one candidate at a time keeps memory at [S, C]
        h = torch.cat([states, xi[k].expand(states.shape[0], -1)], dim=-1)
        h = h.unsqueeze(0).expand(layers[0][0].shape[0], -1, -1)
        for j, (weight, bias) in enumerate(layers):
            h = torch.baddbmm(bias.unsqueeze(1), h, weight.transpose(1, 2))
            if j < len(layers) - 1:
                h = bank.act(h)
        values = h.squeeze(-1).transpose(0, 1) * scale + offset  # [S, M]
        out.append(values.mean(dim=0)[: len(columns)])
    return torch.stack(out).cpu().numpy()


def fit_ensemble(
    pseudo: CriticBank,
    columns: list[int],
    pseudo_scale: torch.Tensor,
    pseudo_offset: torch.Tensor,
    states: torch.Tensor,
    xi: torch.Tensor,
    costs: torch.Tensor,
    *,
    members: int = MEMBERS,
    steps: int = FIT_STEPS,
    batch: int = BATCH,
    lr: float = LEARNING_RATE,
    seed: int = 0,
    local: bool = LOCAL_FRAME,
    floor: float = SPREAD_FLOOR,
    check_states: int = CHECK_STATES,
) -> FittedEnsemble:
    """Fit `members` copies of the pseudo-critics `columns` of `pseudo` (whose output in cost
    units is raw * pseudo_scale + pseudo_offset, per column) to labelled designs: xi [N, D]
    (normalised) with costs [N, M], on normalised buffer states [S, C]. Deterministic for a
    seed (its own generator)."""
    m = len(columns)
    n = xi.shape[0]
    device = states.device
    gen = torch.Generator(device="cpu")
    gen.manual_seed(int(seed))
    idx = torch.as_tensor(columns, dtype=torch.long)
    bank = _member_bank(pseudo, idx, members)
    scale = pseudo_scale[idx].to(device).float()
    offset = pseudo_offset[idx].to(device).float()
    costs = costs.to(device).float()
    # the loss in units of the labelled costs' spread (at least 5 % of their mean), per
    # objective, so every objective and every cost scale weighs alike
    spread = torch.maximum(
        costs.std(dim=0, unbiased=False) if n > 1 else torch.zeros(m, device=device),
        floor * costs.abs().mean(dim=0),
    ).clamp(min=1e-9)
    center = half = None
    if (
        local
    ):  # the labelled designs' box as [-1, 1]: a narrowed range is as easy to fit as the full one
        lo, hi = xi.min(dim=0).values, xi.max(dim=0).values
        center, half = 0.5 * (lo + hi), (0.5 * (hi - lo)).clamp(min=MIN_HALF_WIDTH)
        xi = (xi - center) / half
    # each member sees its own bootstrap resample of the labelled designs (member 0: all)
    picks = [torch.arange(n)] + [torch.randint(n, (n,), generator=gen) for _ in range(members - 1)]
    picks = torch.stack(picks)  # [E, N]
    labelled = (xi, costs, picks, spread)
    _regress(bank, scale, offset, states, labelled, steps, batch, lr, gen)
    for p in bank.parameters():
        p.requires_grad_(False)
    fitted = FittedEnsemble(
        bank=bank,
        members=members,
        scale=scale,
        offset=offset.expand(members, m).clone(),
        labels=n,
        center=center,
        half=half,
    )
    xi = xi if center is None else xi * half + center  # predict() applies the frame itself
    # a short fit starts from the pseudo-critic's level and stops short of the labels' mean:
    # each member's remaining mean residual over its own labelled designs is removed
    check = states[torch.randperm(states.shape[0], generator=gen)[: int(check_states)].to(device)]
    with torch.no_grad():
        residual = fitted.predict(check, xi) - costs.unsqueeze(0)  # [E, N, M]
        own = torch.stack(
            [residual[e, picks[e].to(device)].mean(dim=0) for e in range(members)]
        )  # [E, M]
        fitted.offset -= own
    return fitted


def _regress(
    bank: CriticBank,
    scale: torch.Tensor,
    offset: torch.Tensor,
    states: torch.Tensor,
    labelled: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
    steps: int,
    batch: int,
    lr: float,
    gen: torch.Generator,
) -> None:
    """`steps` Adam steps of the members of `bank` (member-major heads, output raw * scale +
    offset) on pairs (state, labelled design): `labelled` holds the designs xi [N, D] (in
    the members' frame), their costs [N, M], each member's bootstrap picks [E, N] and the
    loss's unit per objective [M]. Leaves `bank` in eval mode."""
    xi, costs, picks, spread = labelled
    members, n = picks.shape
    m = costs.shape[1]
    device = states.device
    optimizer = torch.optim.Adam(bank.parameters(), lr=lr, foreach=True)
    bank.train()
    for _ in range(int(steps)):
        rows = torch.randint(states.shape[0], (batch,), generator=gen)
        which = torch.randint(n, (members, batch), generator=gen)
        labels = torch.gather(picks, 1, which)  # [E, B] labelled design per member and sample
        # each member's heads read that member's own batch of (state, design) rows
        s = states[rows.to(device)]  # [B, C], shared by the members
        x = xi[labels.to(device)]  # [E, B, D]
        inputs = torch.cat([s.unsqueeze(0).expand(members, -1, -1), x], dim=-1)  # [E, B, C + D]
        raw = _per_head(bank, inputs.repeat_interleave(m, dim=0))  # [E M, B]
        own = raw.reshape(members, m, batch).transpose(1, 2)  # [E, B, M]
        pred = own * scale + offset
        target = costs[labels.reshape(-1).to(device)].reshape(members, batch, m)
        loss = (((pred - target) / spread) ** 2).mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    bank.eval()


def _member_bank(pseudo: CriticBank, idx: torch.Tensor, members: int) -> CriticBank:
    """A copy of the heads `idx` of `pseudo`, `members` times over (member-major)."""
    bank = copy.deepcopy(pseudo)
    with torch.no_grad():
        for k in range(bank.num_layers):
            weight, bias = bank.layer(k)
            setattr(
                bank, f"weight_{k}", torch.nn.Parameter(weight[idx].repeat(members, 1, 1).clone())
            )
            setattr(bank, f"bias_{k}", torch.nn.Parameter(bias[idx].repeat(members, 1).clone()))
    bank.num_heads = members * idx.numel()
    return bank


def _per_head(bank: CriticBank, h: torch.Tensor, first: int = 0) -> torch.Tensor:
    """[H, B] outputs of each head of `bank` on its own rows h [H, B, in]; from layer
    `first` on, h then being layer first - 1's output before its activation."""
    if first > 0:
        h = bank.act(h)
    for k in range(first, bank.num_layers):
        weight, bias = bank.layer(k)
        h = torch.baddbmm(bias.unsqueeze(1), h, weight.transpose(1, 2))
        if k < bank.num_layers - 1:
            h = bank.act(h)
    return h.squeeze(-1)
