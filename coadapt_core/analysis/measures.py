"""Every improvement restated in one measure: the cost reduction 1 - c / c0 of the mean cost
(the paper's improvement, Du et al. 2025 Tables 6 and 9), whatever the objective's own
`Objective.improvement` is.

An objective may define its improvement otherwise: command tracking reports the reduction of
the RMS error, 1 - sqrt(c / c0), because its cost is a mean squared error. Its improvement is
then about half the cost reduction of the same two designs, and a comparison with the paper's
P_cmd figures must restate it. The objective's own `improvement(c, c0)` is a function of the
ratio c / c0 alone (every built-in's is, and the report assumes it of a plugin's), decreasing
in it; `cost_ratio` inverts it numerically at c0 = 1, so no plugin declares anything new.

Standard errors follow by the delta method: the reduction is g(i) = 1 - r(i) of the own
improvement i, so its SE is |g'(i)| x SE(i) (tracking: 2 (1 - i) SE(i)); for the mean over
seeds, each seed's value is restated first and the spread is taken over them, as for any
other column. tests/core/test_measures.py checks the delta-method SE against a paired
bootstrap of 1 - c / c0 on the same scenarios.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

#: relative step of the numerical derivative of the restatement
_STEP = 1e-6


@lru_cache(maxsize=32)
def objective_named(name: str) -> Any | None:
    """The installed objective `name` (default options), or None: a comma list of several
    objectives, or a plugin not installed here (its improvement is then taken as a cost
    reduction already)."""
    if not name or "," in name:
        return None
    try:
        from coadapt_core.plugins import get_registry

        return get_registry().create("objective", name)
    except Exception:  # not installed, or it needs options: the default definition
        return None


def cost_ratio(objective: Any | None, improvement: float) -> float:
    """The cost ratio c / c0 that `objective.improvement` reports as `improvement`: the root of
    improvement(r, 1) = improvement by bisection (the default definition: 1 - improvement)."""
    if objective is None or type(objective).improvement is _default_improvement():
        return 1.0 - improvement

    def own(r: float) -> float:
        return float(objective.improvement(r, 1.0))

    lo, hi = 0.0, 2.0
    while own(hi) > improvement and hi < 1e6:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if own(mid) > improvement:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-15:
            break
    return 0.5 * (lo + hi)


def _default_improvement():
    from coadapt_core.objective import Objective

    return Objective.improvement


def as_cost_reduction(
    objective: Any | None, improvement: float | None, se: float | None = None
) -> tuple[float | None, float | None]:
    """(1 - c / c0, its standard error) for an improvement reported by `objective` with
    standard error `se` (either None or not finite: None)."""
    if improvement is None or not math.isfinite(improvement):
        return None, None
    value = 1.0 - cost_ratio(objective, improvement)
    if se is None or not math.isfinite(se):
        return value, None
    h = _STEP * max(1.0, abs(improvement))
    slope = (cost_ratio(objective, improvement - h) - cost_ratio(objective, improvement + h)) / (
        2 * h
    )
    return value, abs(slope) * se


def improvement_measure(objective: Any | None) -> str:
    """What an objective's improvement measures, in words, where it is not the cost reduction
    1 - c / c0 ('' where it is): "RMS error reduction 1 - √(c/c0)" for an objective whose cost
    is a mean squared error (command tracking's P_cmd), else "its own measure"."""
    if not differs(objective):
        return ""
    if math.isclose(float(objective.improvement(0.25, 1.0)), 0.5, abs_tol=1e-9):
        return "RMS error reduction 1 - √(c/c0)"
    return "its own measure"


def differs(objective: Any | None) -> bool:
    """Whether the objective's own improvement is not the cost reduction itself."""
    return objective is not None and type(objective).improvement is not _default_improvement()
