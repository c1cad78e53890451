"""Pareto fronts: one non-dominated filter (pymoo's non-dominated sorting) used by the
NSGA-II optimizer, the loop's final front and the report, so a front printed, stored and
plotted is the same set of designs; the front's hypervolume (pymoo's indicator) with its
standard error over the final check's paired scenarios; the rules `coadapt handoff --pick`
picks a front design by."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np


def pareto_mask(costs: np.ndarray) -> np.ndarray:
    """[n] True where no other row of costs [n, M] dominates the row (all <=, one <); rows
    with a non-finite cost are never on the front (unless every row has one)."""
    import numpy as np

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


def front_rows(designs: np.ndarray, costs: np.ndarray, *, decimals: int = 12) -> np.ndarray:
    """[F] the row indices of the non-dominated rows, one per distinct design (first
    occurrence), sorted by the first cost (ties by the next)."""
    import numpy as np

    designs = np.asarray(designs, dtype=float)
    costs = np.asarray(costs, dtype=float).reshape(len(designs), -1)
    keep = np.flatnonzero(pareto_mask(costs))
    if len(keep) == 0:
        return keep
    _, first = np.unique(np.round(designs[keep], decimals), axis=0, return_index=True)
    keep = keep[np.sort(first)]
    return keep[np.lexsort(costs[keep].T[::-1])]


def pareto_front(
    designs: np.ndarray, costs: np.ndarray, *, decimals: int = 12
) -> tuple[np.ndarray, np.ndarray]:
    """(designs [F, dim], costs [F, M]) of the non-dominated rows, one row per distinct
    design (first occurrence), sorted by the first cost."""
    import numpy as np

    designs = np.asarray(designs, dtype=float)
    costs = np.asarray(costs, dtype=float).reshape(len(designs), -1)
    keep = front_rows(designs, costs, decimals=decimals)
    return designs[keep], costs[keep]


#: where the hypervolume is measured from, in costs relative to the nominal design's
#: (`relative_costs`: the nominal design at 1 in every objective): twice its cost in each.
#: The nominal design alone has hypervolume 1; a front that beats it somewhere has more.
HV_REFERENCE = 2.0
#: how the summary and the report describe the hypervolume, in one clause
HV_DEFINITION = (
    "hypervolume of the front in costs relative to the nominal design's (1 + (cost - nominal) / "
    "|nominal| per objective), up to 2 in each: the nominal design alone has 1"
)


def relative_costs(costs: np.ndarray, nominal: np.ndarray) -> np.ndarray:
    """[..., M] costs as 1 + (cost - nominal) / |nominal| per objective: the nominal design at
    1, half its cost at 0.5, whatever the objective's units or sign (a zero nominal cost
    counts as 1)."""
    import numpy as np

    nominal = np.asarray(nominal, dtype=float)
    scale = np.where(np.abs(nominal) > 0, np.abs(nominal), 1.0)
    return 1.0 + (np.asarray(costs, dtype=float) - nominal) / scale


def hypervolume(costs: np.ndarray, nominal: np.ndarray) -> float:
    """The hypervolume (pymoo's indicator) the designs' costs [n, M] dominate, in costs
    relative to `nominal` [M] (`relative_costs`), bounded by `HV_REFERENCE` in every
    objective; a dominated or non-finite row adds nothing."""
    import numpy as np
    from pymoo.indicators.hv import HV

    z = relative_costs(np.asarray(costs, dtype=float).reshape(-1, len(nominal)), nominal)
    z = z[np.isfinite(z).all(axis=1) & (z < HV_REFERENCE).all(axis=1)]
    if len(z) == 0:
        return 0.0
    return float(HV(ref_point=np.full(z.shape[1], HV_REFERENCE))(z))


def hypervolume_se(
    values: np.ndarray, aggregate: Callable[[np.ndarray], np.ndarray]
) -> tuple[float, float]:
    """(hypervolume, standard error) of the candidates' front from their scenario values
    [C + 1, A, M] (the nominal design last; a cost rule's `scenario_values`) and the rule's
    `aggregate` ([K, A, M] -> [K, M]). The error is the bootstrap's over the A scenarios,
    resampled together for every design (paired: the same scenarios for the candidates and
    the nominal design, as the final check's other standard errors), the front and the
    nominal cost recomputed in each resample; 0 with one scenario."""
    import numpy as np

    from coadapt_core.costs import _resamples

    x = np.asarray(values, dtype=float)
    costs = aggregate(x)
    value = hypervolume(costs[:-1], costs[-1])
    if x.shape[1] < 2:
        return value, 0.0
    boot = [
        hypervolume(c[:-1], c[-1])
        for c in (aggregate(x[:, idx, :]) for idx in _resamples(x.shape[1]))
    ]
    return value, float(np.std(boot, ddof=1))


def pick_index(pick: str | int, costs: np.ndarray) -> int:
    """The front index `coadapt handoff --pick` means: a whole number N (0-based, in the
    order of the stored front: by the first cost), or "knee": the design nearest the ideal
    point once each objective is scaled to the front's own range (0 its best design's cost,
    1 its worst's), ties to the lower index. ValueError naming what is accepted otherwise."""
    import numpy as np

    costs = np.asarray(costs, dtype=float)
    n = len(costs)
    text = str(pick).strip().lower()
    if text == "knee":
        low, high = costs.min(axis=0), costs.max(axis=0)
        span = np.where(high > low, high - low, 1.0)
        return int(np.argmin(np.linalg.norm((costs - low) / span, axis=1)))
    try:
        index = int(text)
    except ValueError:
        raise ValueError(f"'{pick}' is neither a front index (0 to {n - 1}) nor 'knee'") from None
    if not 0 <= index < n:
        raise ValueError(
            f"{index} is not a front index: the front holds {n} design{'' if n == 1 else 's'} "
            f"(0 to {n - 1})"
        )
    return index


def is_dominated(point: np.ndarray, others: np.ndarray) -> bool:
    """Whether any row of others [n, M] dominates point [M]."""
    import numpy as np

    others = np.asarray(others, dtype=float).reshape(-1, len(point))
    return bool((np.all(others <= point, axis=1) & np.any(others < point, axis=1)).any())


__all__ = [
    "HV_DEFINITION",
    "HV_REFERENCE",
    "front_rows",
    "hypervolume",
    "hypervolume_se",
    "is_dominated",
    "pareto_front",
    "pareto_mask",
    "pick_index",
    "relative_costs",
]
