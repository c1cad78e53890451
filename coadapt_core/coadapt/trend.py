"""A linear trend of the cost in the design, fitted to the current policy's real rounds
(`surrogate_trend`, issue 52; docs/coadaptation.md "Against its noise ceiling").

Inside a narrowed range the fitted pseudo-critic ensemble's members disagree by one to five
times the spread of the round's designs (its spread ratio on the judged rounds of the quick
preset), so its ranking there is mostly its own noise. The labels it is fitted to, the real
costs of this policy's earlier rounds, hold the trend the round needs: a plane through them
(one intercept and one slope per design variable, least squares) has D + 1 numbers to fit
to 16-48 labels, where the ensemble has a network per member. Beyond the paper; off by
default. Plain numpy on designs and costs: it needs nothing of a backend."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class LinearTrend:
    center: np.ndarray  # [D] the labelled designs' box centre
    half: np.ndarray  # [D] its half-widths (a variable that never moved: 1)
    coef: np.ndarray  # [D + 1, M] intercept, then one slope per variable (in the box's units)
    labels: int

    def predict(self, designs: np.ndarray) -> np.ndarray:
        """[K, M] the plane's costs at `designs` [K, D]."""
        x = (np.atleast_2d(np.asarray(designs, dtype=float)) - self.center) / self.half
        return np.hstack([np.ones((len(x), 1)), x]) @ self.coef

    def slope(self) -> np.ndarray:
        """[M, D] the plane's slope in design units (the same at every design)."""
        return (self.coef[1:] / self.half[:, None]).T


def fit_trend(designs: np.ndarray, costs: np.ndarray) -> LinearTrend | None:
    """The least-squares plane through labelled designs [N, D] and their costs [N, M] (or
    [N]); None when the labels cannot fix one (fewer than D + 1 designs, or costs that are
    not all finite). Designs are read in their box's [-1, 1] frame, so the fit is as well
    conditioned in a narrowed range as in the full one."""
    x = np.atleast_2d(np.asarray(designs, dtype=float))
    y = np.asarray(costs, dtype=float).reshape(len(x), -1)
    if len(x) < x.shape[1] + 1 or not np.all(np.isfinite(y)) or not np.all(np.isfinite(x)):
        return None
    lo, hi = x.min(axis=0), x.max(axis=0)
    center, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    half = np.where(half > 1e-12, half, 1.0)
    a = np.hstack([np.ones((len(x), 1)), (x - center) / half])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return LinearTrend(center=center, half=half, coef=coef, labels=len(x))


def trend_of_labels(labels: Sequence[dict[str, Any]]) -> LinearTrend | None:
    """The plane through a run's labels (`LoopState.labels`: this policy's real rounds)."""
    if not labels:
        return None
    designs = np.concatenate([np.asarray(item["designs"], dtype=float) for item in labels])
    costs = np.concatenate(
        [
            np.asarray(item["costs"], dtype=float).reshape(len(item["designs"]), -1)
            for item in labels
        ]
    )
    return fit_trend(designs, costs)
