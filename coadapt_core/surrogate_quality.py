"""How well a surrogate ranks designs: Spearman and Kendall correlation, mean relative error,
bias and top-k regret between surrogate and real costs of the same designs (issue 16).

Sign conventions (docs/coadaptation.md, "The surrogate"):

- relative error of design k: (surrogate_k - real_k) / |real_k|, so a positive bias means
  the surrogate over-predicts the cost;
- mean_relative_error: the mean of |relative error|; bias: the mean of the signed one;
- top_k_regret of a round: (min real cost among the k designs the surrogate ranks cheapest -
  min real cost of the round) / |min real cost of the round|: 0 when the surrogate's top k
  holds the round's best design, the relative cost of trusting it otherwise.

Pooled figures concatenate the (surrogate, real) pairs of the rounds given (regret: the mean
over rounds). Designs whose real or surrogate cost is not finite are left out and counted.

The noise ceiling (issue 52, `noise_ceiling`): a round's real costs are noisy (each design's
standard error over its scenarios), so even a perfect surrogate, one that knew each design's
true cost, would not rank them perfectly against them. Its expected Spearman is estimated by
Monte Carlo from the per-design SEs: in each draw the true costs are the real ones shrunk
towards their mean to a true variance drawn from what the real costs say of it (their
variance is the true one plus mean(SE^2), estimated from n - 1 degrees of freedom; at least
0: then the draw's perfect ranking is one at chance), and fresh noise of the designs' SEs is
added. `ceiling` is the
mean Spearman between the true costs and one noisy evaluation (what a perfect surrogate
would score), `ceiling_sd` its spread over draws (a round's own sampling spread), `repeat` the
mean Spearman between two independent noisy evaluations (rank agreement of the real costs
with themselves). A surrogate is `near` its ceiling when its Spearman is at least
`ceiling - 2 ceiling_sd`, else `below`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: k of the top-k regret (the surrogate's k cheapest designs of a round)
TOP_K = 3
METRICS = ("spearman", "kendall", "mean_relative_error", "bias", "top_k_regret")


def _ranks(x: np.ndarray) -> np.ndarray:
    """Average ranks (ties share the mean of their ranks), 0-based."""
    order = np.argsort(x, kind="mergesort")
    ranks = np.empty(len(x), dtype=float)
    ranks[order] = np.arange(len(x), dtype=float)
    values = x[order]
    i = 0
    while i < len(x):
        j = i
        while j + 1 < len(x) and values[j + 1] == values[i]:
            j += 1
        if j > i:
            ranks[order[i : j + 1]] = 0.5 * (i + j)
        i = j + 1
    return ranks


def spearman(a: Sequence[float], b: Sequence[float]) -> float:
    """Spearman's rank correlation (Pearson correlation of average ranks); NaN below 3
    pairs or when either side is constant."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if len(a) < 3:
        return float("nan")
    ra, rb = _ranks(a), _ranks(b)
    sa, sb = ra.std(), rb.std()
    if sa == 0 or sb == 0:
        return float("nan")
    return float(((ra - ra.mean()) * (rb - rb.mean())).mean() / (sa * sb))


def kendall(a: Sequence[float], b: Sequence[float]) -> float:
    """Kendall's tau-b (ties corrected); NaN below 3 pairs or when either side is constant."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n = len(a)
    if n < 3:
        return float("nan")
    i, j = np.triu_indices(n, k=1)
    da, db = np.sign(a[i] - a[j]), np.sign(b[i] - b[j])
    concordant = float((da * db).sum())
    ta, tb = float((da != 0).sum()), float((db != 0).sum())
    if ta == 0 or tb == 0:
        return float("nan")
    return float(concordant / np.sqrt(ta * tb))


def top_k_regret(surrogate: Sequence[float], real: Sequence[float], k: int = TOP_K) -> float:
    """(best real cost among the surrogate's k cheapest - best real cost) / |best real cost|."""
    s, r = np.asarray(surrogate, dtype=float), np.asarray(real, dtype=float)
    if len(r) == 0:
        return float("nan")
    pick = np.argsort(s, kind="mergesort")[: max(1, min(int(k), len(s)))]
    best = float(r.min())
    return float((r[pick].min() - best) / max(abs(best), 1e-12))


def quality(surrogate: Sequence[float], real: Sequence[float], k: int = TOP_K) -> dict[str, Any]:
    """The five figures (module docstring) for one set of designs, plus `n` (pairs used) and
    `nonfinite` (pairs left out)."""
    s, r = np.asarray(surrogate, dtype=float).reshape(-1), np.asarray(real, dtype=float).reshape(-1)
    ok = np.isfinite(s) & np.isfinite(r)
    s, r = s[ok], r[ok]
    rel = (s - r) / np.maximum(np.abs(r), 1e-12)
    return {
        "spearman": spearman(s, r),
        "kendall": kendall(s, r),
        "mean_relative_error": float(np.abs(rel).mean()) if len(rel) else float("nan"),
        "bias": float(rel.mean()) if len(rel) else float("nan"),
        "top_k_regret": top_k_regret(s, r, k),
        "n": int(len(s)),
        "nonfinite": int((~ok).sum()),
    }


def pooled(rounds: Sequence[dict[str, Any]], k: int = TOP_K) -> dict[str, Any]:
    """Pooled figures over rounds, each a dict with `surrogate` and `real` lists: correlations
    and errors over all pairs together, top-k regret as the mean of the rounds' regrets."""
    if not rounds:
        return {name: float("nan") for name in METRICS} | {"n": 0, "nonfinite": 0, "rounds": 0}
    s = np.concatenate([np.asarray(r["surrogate"], dtype=float).reshape(-1) for r in rounds])
    r_ = np.concatenate([np.asarray(r["real"], dtype=float).reshape(-1) for r in rounds])
    out = quality(s, r_, k)
    regrets = [quality(r["surrogate"], r["real"], k)["top_k_regret"] for r in rounds]
    regrets = [x for x in regrets if np.isfinite(x)]
    out["top_k_regret"] = float(np.mean(regrets)) if regrets else float("nan")
    out["rounds"] = len(rounds)
    return out


#: Monte Carlo draws of the noise ceiling
CEILING_DRAWS = 400


def noise_ceiling(
    real: Sequence[float], se: Sequence[float], draws: int = CEILING_DRAWS, seed: int = 0
) -> dict[str, Any]:
    """The Spearman the real costs' own noise allows (module docstring): `ceiling`,
    `ceiling_sd`, `repeat` and `n` (designs with a finite cost and SE); NaN figures below 3
    such designs or when the costs do not differ."""
    r = np.asarray([np.nan if x is None else x for x in real], dtype=float).reshape(-1)
    e = np.asarray([np.nan if x is None else x for x in se], dtype=float).reshape(-1)
    ok = np.isfinite(r) & np.isfinite(e) & (e >= 0) if len(e) == len(r) else np.zeros(len(r), bool)
    r, e = r[ok], e[ok]
    out = {"ceiling": float("nan"), "ceiling_sd": float("nan"), "repeat": float("nan")}
    if len(r) < 3 or r.std() == 0:
        return out | {"n": int(len(r))}
    rng = np.random.default_rng(seed)
    n, noise, observed = len(r), float(np.mean(e**2)), float(r.var(ddof=1))
    # the true costs' variance, drawn from what one noisy draw of them says (observed
    # variance = true + noise, with n - 1 degrees of freedom), at least 0
    total = observed * (n - 1) / rng.chisquare(n - 1, size=draws)
    shrink = np.sqrt(np.maximum(total - noise, 0.0) / observed)
    perfect, repeat = np.empty(draws), np.empty(draws)
    for d in range(draws):
        true = r.mean() + shrink[d] * (r - r.mean())
        one = true + e * rng.standard_normal(n)
        two = true + e * rng.standard_normal(n)
        repeat[d] = spearman(one, two)
        # no true difference left: a perfect ranking is one at chance
        perfect[d] = spearman(true, one) if shrink[d] > 0 else spearman(one - true, two - true)
    perfect, repeat = perfect[np.isfinite(perfect)], repeat[np.isfinite(repeat)]
    return {
        "ceiling": float(perfect.mean()) if perfect.size else float("nan"),
        "ceiling_sd": float(perfect.std(ddof=1)) if perfect.size > 1 else float("nan"),
        "repeat": float(repeat.mean()) if repeat.size else float("nan"),
        "n": int(len(r)),
    }


def against_ceiling(rho: Any, ceiling: dict[str, Any]) -> str | None:
    """`near` when the surrogate's Spearman `rho` is at least ceiling - 2 ceiling_sd, else
    `below`; None when either is unknown."""
    c, sd = ceiling.get("ceiling"), ceiling.get("ceiling_sd")
    if not all(isinstance(x, int | float) and np.isfinite(x) for x in (rho, c, sd)):
        return None
    return "near" if rho >= c - 2.0 * sd else "below"


#: the ceiling's figures kept beside a round's (or the pooled) Spearman
CEILING_FIGURES = ("ceiling", "ceiling_sd", "repeat", "against_ceiling")


def with_ceiling(figures: dict[str, Any], real: Sequence[Any], se: Sequence[Any]) -> dict[str, Any]:
    """`figures` (with its `spearman`) and the noise ceiling of `real` with SEs `se`:
    `CEILING_FIGURES` added, NaN as None."""
    ceiling = noise_ceiling(real, se)
    verdict = against_ceiling(figures.get("spearman"), ceiling)
    return clean(
        {**figures, **{k: ceiling[k] for k in CEILING_FIGURES[:3]}, "against_ceiling": verdict}
    )


def clean(value: Any) -> Any:
    """NaN / inf as None, recursively (summary.json is strict JSON)."""
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value
