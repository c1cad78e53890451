"""How `coadapt run` prints a multi-objective run's Pareto front (docs/results.md)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


def front_lines(front: dict[str, Any], with_se: Callable[[float, float | None], str]) -> list[str]:
    """The Pareto front as printed: a title, one line per design (its index for `coadapt
    handoff RUN --pick N`, its values, its final-check costs +- SE, the returned one marked)
    and the front's hypervolume +- SE; `with_se(value, se)` writes a cost and its SE."""
    ses = front.get("costs_se") or [{}] * len(front["costs"])
    returned = front.get("returned", 0)
    n = len(front["designs"])
    lines = [
        f"Pareto front ({n} design{'' if n == 1 else 's'}, final check costs +- SE; the run "
        "returns the one of lowest first cost; N: `coadapt handoff RUN --pick N` hands off "
        "another):"
    ]
    for j, (design, costs, se) in enumerate(
        zip(front["designs"], front["costs"], ses, strict=True)
    ):
        lines.append(
            f"  {j}: "
            + ", ".join(f"{x:.3f}" for x in design)
            + "  ->  "
            + ", ".join(f"{k} {with_se(v, (se or {}).get(k))}" for k, v in costs.items())
            + ("  <- returned" if j == returned else "")
        )
    hv, hv_se = front.get("hypervolume"), front.get("hypervolume_se")
    if isinstance(hv, int | float):
        error = (
            f" +- {hv_se:.3f}"
            if isinstance(hv_se, int | float)
            else " (no SE: no per-scenario costs)"
        )
        lines.append(
            f"hypervolume {hv:.3f}{error} (costs relative to the nominal design's, up to 2 in "
            "each: the nominal design alone has 1; docs/results.md)"
        )
    return lines


__all__ = ["front_lines"]
