"""The report's surrogate-quality figure (issue 16): per objective and terrain, the rank
correlation between surrogate and real cost on each eligible real round of every run, from
the runs' `surrogate_quality` (docs/coadaptation.md, "The surrogate")."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.figures import panel_grid, pyplot, save_figure, tidy_axes


def quality_series(facts: Sequence[Any]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    """(objective, terrain) -> one entry per run: its label, the Spearman of each eligible
    round in order, and its pooled figures."""
    series: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for f in facts:
        q = (f.run.get("summary") or {}).get("surrogate_quality")
        if not isinstance(q, dict):
            continue
        for name, pooled in (q.get("by_objective") or {}).items():
            rounds = [r for r in q.get("rounds") or [] if r.get("eligible")]
            figures = [(r.get("objectives") or {}).get(name, {}) for r in rounds]
            values = [q.get("spearman") for q in figures]
            series[(name, f.terrain)].append(
                {
                    "label": f"{f.method} s{f.run.get('seed', '?')}",
                    "run": f.run,
                    "spearman": [
                        float(v) if isinstance(v, int | float) else math.nan for v in values
                    ],
                    # the real costs' noise ceiling of each round (issue 52), where recorded
                    "ceiling": [
                        float(q["ceiling"])
                        if isinstance(q.get("ceiling"), int | float)
                        else math.nan
                        for q in figures
                    ],
                    "pooled": pooled or {},
                }
            )
    for entries in series.values():
        _distinct_labels(entries)
    return series


def _distinct_labels(entries: list[dict[str, Any]]) -> None:
    """Runs sharing a label (method and seed) are told apart by what differs: the optimizer,
    then the preset, then the end of the run id."""
    for key in ("optimizer", "preset", "id"):
        labels = [e["label"] for e in entries]
        for e in entries:
            if labels.count(e["label"]) > 1:
                value = str(e["run"].get(key) or "?")
                e["label"] += f" {value[-6:] if key == 'id' else value}"
    for e in entries:
        e.pop("run", None)


def figure_surrogate_quality(facts: Sequence[Any], out: Path) -> list[tuple[Path, str]]:
    series = quality_series(facts)
    if not series:
        return []
    plt = pyplot()
    from matplotlib.ticker import MaxNLocator

    keys = sorted(series)
    fig, axes = panel_grid(plt, len(keys))
    for ax, key in zip(axes, keys, strict=True):
        lines = []
        for entry in series[key]:
            y = entry["spearman"]
            (line,) = ax.plot(
                range(1, len(y) + 1), y, marker="o", linewidth=1.2, label=entry["label"]
            )
            if any(math.isfinite(c) for c in entry["ceiling"]):
                ax.plot(
                    range(1, len(y) + 1),
                    entry["ceiling"],
                    marker="_",
                    markersize=12,
                    linestyle="--",
                    linewidth=0.8,
                    color=line.get_color(),
                )
            p = entry["pooled"]
            if isinstance(p.get("spearman"), int | float):
                ceiling = p.get("ceiling")
                lines.append(
                    f"{entry['label']}: pooled {p['spearman']:.2f}, bias "
                    f"{100 * (p.get('bias') or 0):+.1f} %"
                    + (f", ceiling {ceiling:.2f}" if isinstance(ceiling, int | float) else "")
                )
        ax.axhline(0.0, color="grey", linewidth=0.8)
        ax.axhline(0.7, color="grey", linewidth=0.8, linestyle=":")
        ax.set_ylim(-1.05, 1.05)
        ax.set_xlabel("eligible real round")
        ax.set_ylabel("Spearman (surrogate, real cost)")
        ax.set_title(f"{key[0]} on {key[1]}\n" + "; ".join(lines[:2]), fontsize=8)
        ax.legend(fontsize=7)
        tidy_axes(ax)
        rounds = max((len(e["spearman"]) for e in series[key]), default=0)
        ax.set_xlim(
            0.5, max(rounds, 1) + 0.5
        )  # rounds are whole: ticks 1, 2, ... (not 1.25, nor -0.05)
        ax.xaxis.set_major_locator(MaxNLocator(5, integer=True, min_n_ticks=1))
        if rounds == 0:
            ax.text(
                0.5,
                0.5,
                "no real round judged",
                transform=ax.transAxes,
                ha="center",
                fontsize=8,
                color="grey",
            )
    return save_figure(
        plt,
        fig,
        out / "surrogate_quality.png",
        "Surrogate quality per objective and terrain: Spearman rank correlation between the "
        "surrogate's prediction (made before the round's real costs were known) and the real cost "
        "of the same designs, on every real round where a surrogate round was allowed; the title "
        "gives each run's pooled Spearman and bias ((surrogate − real) / |real|). Dashed, in "
        "the run's colour where it recorded one: the real costs' noise ceiling, the Spearman a "
        "perfect surrogate would reach against those noisy costs (from the designs' paired "
        "SEs). Dotted: 0.7.",
    )
