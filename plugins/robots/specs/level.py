"""A standing pose solved per design that stays inside the joint ranges with its soles level.

`standing_pose.solve` puts each foot under its hip at a share of its leg's length; at some
designs the leg IK's answer for that height leaves a joint outside its range (the pose is
then clipped at the limit) or, for a leg with an ankle, the foot tilted (a humanoid with a
long thigh and a short shank: its ankle at its limit, the foot toe-down, and it tips over).
There the foot's height is searched instead: the share of SHARES nearest the spec's at which
every leg's joints lie MARGIN inside their ranges, every sole with an ankle is level within
TILT and every foot reaches its target (still under its hip). A design whose answer needs
no search keeps the spec's targets exactly, and one no share fits keeps them too.
"""

from __future__ import annotations

import torch

#: the shares of the leg's length tried, and what a share must give: each leg joint this
#: far (rad) inside its range, each sole with an ankle within TILT (rad) of its standing
#: orientation, each foot within REACH x its leg's length of its target
SHARES = tuple(round(0.3 + 0.01 * k, 2) for k in range(69))  # 0.30 .. 0.98
MARGIN = 0.05
TILT = 0.05
REACH = 1e-4
#: shares tried at once per design, and the designs whose answers are kept
WAVE = 8
CACHE_SIZE = 65536


def _fits(kin, designs, targets, lower, upper, margin: float, legs=None) -> torch.Tensor:
    """[n] whether the IK's answer for targets [n, L, 3] at designs [n, P] keeps each leg's
    joints `margin` inside [lower, upper] ([J] each) and each sole with an ankle (a leg of
    more than three joints) level within TILT; with the legs' lengths `legs` [n, L], also
    each foot within REACH of them of its target."""
    q = kin.inverse(designs, targets)  # [n, J]
    c = kin.chain
    valid = c.joint_index >= 0  # [L, M]
    index = c.joint_index.clamp(min=0)
    angles = q[:, index]  # [n, L, M]
    inside = (angles >= lower[index] + margin - 1e-9) & (angles <= upper[index] - margin + 1e-9)
    ok = (inside | ~valid).all(dim=-1)  # [n, L]
    foot, rot, hip, _, _ = kin.forward(kin.scales(designs), kin.leg_angles(q))
    want = kin.standing(designs)[1]
    cos = 0.5 * ((rot * want).sum(dim=(-1, -2)) - 1.0)  # the turn between them, as trace
    tilt = torch.arccos(cos.clamp(-1.0, 1.0))  # [n, L]
    ankle = valid.sum(dim=-1) > 3
    ok &= ~ankle | (tilt <= TILT)
    if legs is not None:
        ok &= torch.linalg.norm(foot - hip - targets, dim=-1) <= REACH * legs
    return ok.all(dim=-1)


def level_targets(kin, designs, targets, share: float, lower, upper, cache=None) -> torch.Tensor:
    """`targets` [n, L, 3] (each foot `share` of its leg's length under its hip at designs
    [n, P]) with the foot height of each design whose IK answer leaves a joint outside
    [lower, upper] or a sole tilted searched over SHARES (`_fits`, MARGIN inside the
    ranges): the share nearest `share` that fits, the deeper on a tie. `cache`: a dict of
    each design's answer (None for the targets as given), kept between calls."""
    cache = {} if cache is None else cache
    if len(cache) > CACHE_SIZE:
        cache.clear()
    unique, inverse = torch.unique(designs, dim=0, return_inverse=True)
    first = torch.zeros(unique.shape[0], dtype=torch.long)
    first[inverse] = torch.arange(designs.shape[0])  # a row of each unique design
    keys = [tuple(row) for row in unique.tolist()]
    new = [k for k, key in enumerate(keys) if key not in cache]
    if new:
        rows = torch.tensor(new, dtype=torch.long)
        found = _search(kin, unique[rows], targets[first[rows]], share, lower, upper)
        for k, answer in zip(new, found, strict=True):
            cache[keys[k]] = answer
    if all(cache[key] is None for key in keys):
        return targets
    fixed = targets[first].clone()
    for k, key in enumerate(keys):
        if cache[key] is not None:
            fixed[k] = cache[key]
    return fixed[inverse]


def _search(kin, designs, targets, share, lower, upper) -> list[torch.Tensor | None]:
    """Per design of designs [m, P] (each unique), None when the IK's answer for targets
    [m, L, 3] fits the ranges (no margin) with level soles, else the targets [L, 3] at the
    share SHARES nearest `share` that fits with MARGIN, tried WAVE at a time (None when none
    does)."""
    lower = torch.as_tensor(lower, dtype=torch.float64)
    upper = torch.as_tensor(upper, dtype=torch.float64)
    out: list[torch.Tensor | None] = [None] * designs.shape[0]
    todo = torch.nonzero(~_fits(kin, designs, targets, lower, upper, 0.0))[:, 0]
    legs = targets[..., 2] / -share  # [m, L] each leg's length
    order = sorted(SHARES, key=lambda s: (round(abs(s - share), 6), -s))
    for start in range(0, len(order), WAVE):
        if todo.numel() == 0:
            break
        tries = torch.tensor(order[start : start + WAVE], dtype=torch.float64)  # [K]
        many = targets[todo][:, None].repeat(1, len(tries), 1, 1)  # [t, K, L, 3]
        many[..., 2] = -tries[None, :, None] * legs[todo][:, None, :]
        t, k = many.shape[:2]
        again = designs[todo].repeat_interleave(k, dim=0)
        lengths = legs[todo].repeat_interleave(k, dim=0)
        fits = _fits(kin, again, many.flatten(0, 1), lower, upper, MARGIN, lengths).reshape(t, k)
        for row, ok, tried in zip(todo.tolist(), fits, many, strict=True):
            if bool(ok.any()):
                out[row] = tried[int(torch.nonzero(ok)[0, 0])]
        todo = todo[~fits.any(dim=1)]
    return out
