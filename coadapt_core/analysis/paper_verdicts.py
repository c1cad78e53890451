"""How a figure of ours is judged against the paper's (Du et al. 2025): the direction of a
design variable, a value within or outside the paper's, and the SE of a row's mean.

- design direction: each of thigh and shank is longer than nominal (scale above
  1 + `NOMINAL_BAND`), shorter (below 1 - `NOMINAL_BAND`) or at nominal; a cell *agrees* when
  every variable has the paper's direction, *disagrees* when one is longer where the paper's
  is shorter or the other way round, and is *undecided* when the only differences involve a
  value at nominal.
- improvement: *within* when the paper's figure lies within 2 standard errors of our mean
  (SE over seeds: sample standard deviation / sqrt(n); one run: the SE its final check
  recorded), widened by the paper's rounding (0.05 percentage points); else *above* or
  *below* the paper's.
"""

from __future__ import annotations

import math
from typing import Any

from coadapt_core.analysis.paper_cost import Z

#: a design scale within this of 1.0 is "at nominal" (the paper prints two decimals: 0.98-1.02)
NOMINAL_BAND = 0.025
#: half the paper's last printed digit of a percentage (5.8 %: 5.75-5.85 %)
PAPER_ROUNDING = 0.0005

#: the improvements the method order is judged on, and how the tables name them
MEASURES = {
    "improvement": "run's cost",
    "improvement_plain": "plain mean",
    "common_improvement": "common scenarios",
    "common_improvement_plain": "common scenarios, plain mean",
}


def se_of(row: dict[str, Any], name: str) -> float | None:
    """Standard error of a table6 row's mean `name`: std / sqrt(n) over seeds; one run: the
    SE it recorded (`<name>_se`), else None."""
    n = int(row.get(f"{name}_n") or 0)
    std = row.get(f"{name}_std")
    if n >= 2 and std is not None:
        return float(std) / math.sqrt(n)
    if n == 1 and row.get(f"{name}_se") is not None:
        return float(row[f"{name}_se"])
    return None


def direction(scale: float | None) -> str | None:
    """'longer', 'shorter' or 'nominal' (within `NOMINAL_BAND` of 1.0); None when unknown."""
    if scale is None or not math.isfinite(scale):
        return None
    if scale > 1.0 + NOMINAL_BAND:
        return "longer"
    if scale < 1.0 - NOMINAL_BAND:
        return "shorter"
    return "nominal"


def direction_verdict(ours: dict[str, float | None], paper: dict[str, float]) -> str:
    """'agrees', 'disagrees (thigh)' (the variables whose direction is the opposite of the
    paper's), 'undecided (shank at nominal)' or 'n/a'."""
    opposite, undecided = [], []
    for name, value in paper.items():
        a, b = direction(ours.get(name)), direction(value)
        if a is None:
            return "n/a"
        if a != b:
            (undecided if "nominal" in (a, b) else opposite).append(name)
    if opposite:
        return f"disagrees ({', '.join(opposite)})"
    if undecided:
        return f"undecided ({', '.join(undecided)} at nominal)"
    return "agrees"


def value_verdict(mean: float | None, se: float | None, paper: float | None) -> str:
    """'within' (the paper's figure within Z SE of our mean, plus its rounding), 'above' or
    'below' (ours against the paper's), 'above (no SE)' when our spread is unknown, 'n/a'."""
    if mean is None or paper is None:
        return "n/a"
    diff = mean - paper
    if se is None:
        return (
            ("above" if diff > 0 else "below") + " (no SE)"
            if abs(diff) > PAPER_ROUNDING
            else "within (no SE)"
        )
    if abs(diff) <= Z * se + PAPER_ROUNDING:
        return "within"
    return "above" if diff > 0 else "below"
