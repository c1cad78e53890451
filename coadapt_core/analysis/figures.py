"""What every figure of the report shares: matplotlib without a display, the panel grid
(at most two panels a row), axis ticks and when an axis goes logarithmic."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

#: figure width per panel (inches) and resolution: at most two panels a row keeps a figure
#: under ~1000 px, shown at its own size in report.html (no shrinking of its labels)
PANEL_W, PANEL_H, DPI, MAX_COLS = 4.8, 4.0, 100, 2


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend: files only, no display on CI or cluster nodes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def spans_decades(values: Any, decades: float = 3.0) -> bool:
    """True when positive finite values spread over more than `decades` orders of magnitude:
    one diverged rollout (cost 1e10 next to 1e3) would flatten a linear axis, so such axes
    go logarithmic."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return v.size > 1 and bool((v > 0).all()) and float(v.max() / v.min()) > 10**decades


def panel_grid(plt: Any, n: int, height: float = PANEL_H) -> tuple[Any, Any]:
    """(figure, the first n axes) of a grid of n panels, at most MAX_COLS a row."""
    cols = min(MAX_COLS, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(PANEL_W * cols, height * rows), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    return fig, axes.ravel()[:n]


def tidy_axes(ax: Any) -> None:
    """At most five ticks on a linear axis: cost labels like 12000 would run into each other."""
    from matplotlib.ticker import MaxNLocator

    for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
        if scale == "linear":
            axis.set_major_locator(MaxNLocator(5))


def cost_unit(objective: str, summaries: Any = ()) -> str:
    """' [unit]' of an objective's cost per step: as a run's summary records it, else as the
    installed objective declares it ('' when neither says)."""
    for summary in summaries:
        unit = ((summary or {}).get("cost_units") or {}).get(objective)
        if unit:
            return f" [{unit}]"
    from coadapt_core.analysis.measures import objective_named

    unit = getattr(objective_named(objective), "unit", "")
    return f" [{unit}]" if unit else ""


def save_figure(
    plt: Any, fig: Any, path: Path, caption: str, *, layout: bool = True
) -> list[tuple[Path, str]]:
    """Write `fig` as a PNG at DPI (laid out tight unless `layout` is False: the caller did)
    and close it; returns the report's entry for it, [(path, caption)]."""
    if layout:
        fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return [(path, caption)]


__all__ = [
    "DPI",
    "MAX_COLS",
    "PANEL_H",
    "PANEL_W",
    "cost_unit",
    "panel_grid",
    "pyplot",
    "save_figure",
    "spans_decades",
    "tidy_axes",
]
