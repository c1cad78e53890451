"""Pareto fronts: one non-dominated filter (pymoo's non-dominated sorting) used by the
NSGA-II optimizer, the loop's final front and the report, so a front printed, stored and
plotted is the same set of designs."""

from __future__ import annotations

import numpy as np


def pareto_mask(costs: np.ndarray) -> np.ndarray:
    """[n] True where no other row of costs [n, M] dominates the row (all <=, one <); rows
    with a non-finite cost are never on the front (unless every row has one)."""
    costs = np.asarray(costs, dtype=float)
    n = costs.shape[0]
    mask = np.zeros(n, dtype=bool)
    if n == 0:
        return mask
    costs = costs.reshape(n, -1)
    finite = np.isfinite(costs).all(axis=1)
    rows = np.flatnonzero(finite) if finite.any() else np.arange(n)
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    sub = np.nan_to_num(costs[rows], nan=np.inf)
    front = NonDominatedSorting().do(sub, only_non_dominated_front=True)
    mask[rows[np.asarray(front, dtype=int)]] = True
    return mask


def pareto_front(designs: np.ndarray, costs: np.ndarray, *, decimals: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """(designs [F, dim], costs [F, M]) of the non-dominated rows, one row per distinct
    design (first occurrence), sorted by the first cost."""
    designs = np.asarray(designs, dtype=float)
    costs = np.asarray(costs, dtype=float).reshape(len(designs), -1)
    keep = np.flatnonzero(pareto_mask(costs))
    if len(keep) == 0:
        return designs[:0], costs[:0]
    _, first = np.unique(np.round(designs[keep], decimals), axis=0, return_index=True)
    keep = keep[np.sort(first)]
    order = np.lexsort(costs[keep].T[::-1])  # by the first cost, ties by the next
    keep = keep[order]
    return designs[keep], costs[keep]


def is_dominated(point: np.ndarray, others: np.ndarray) -> bool:
    """Whether any row of others [n, M] dominates point [M]."""
    others = np.asarray(others, dtype=float).reshape(-1, len(point))
    return bool((np.all(others <= point, axis=1) & np.any(others < point, axis=1)).any())


__all__ = ["is_dominated", "pareto_front", "pareto_mask"]
