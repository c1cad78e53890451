"""paper_table6.png: Table 6 beside the paper's as bars. One panel per terrain; per objective a
group of bars, one per method: our improvement on the common scenario set (mean ± SE over
seeds; a cell without common-scenario rows shows its runs' own final check, hatched), and the
paper's figure for the same cell as a black tick."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.analysis.facts import METHOD_COLORS, METHOD_LABELS, TERRAIN_ORDER, objective_order
from coadapt_core.analysis.figures import panel_grid, pyplot, save_figure, tidy_axes
from coadapt_core.analysis.tables import ordered
from coadapt_core.methods import METHOD_NAMES

FILE = "paper_table6.png"


def bars_of(rows6: Sequence[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Per terrain, one bar per (objective, method) row of the comparison: `value` and `se` in
    percent (common scenarios where the cell has them, else the runs' own improvement),
    `common` (which one it is) and the paper's figure in percent."""
    out: dict[str, list[dict[str, Any]]] = {}
    for r in rows6:
        common = r.get("common_improvement") is not None
        value = r["common_improvement"] if common else r.get("improvement")
        if value is None:
            continue
        se = r.get("common_improvement_se") if common else r.get("improvement_se")
        paper = r.get("paper_improvement")
        out.setdefault(r["terrain"], []).append(
            {
                "objective": r["objective"],
                "method": r["method"],
                "value": 100 * value,
                "se": None if se is None else 100 * se,
                "common": common,
                "paper": None if paper is None else 100 * paper,
                "runs": r.get("runs"),
            }
        )
    return out


def figure_beside_paper(
    rows6: Sequence[dict[str, Any]], out: Path, objectives: dict[str, str] | None = None
) -> list[tuple[Path, str]]:
    bars = bars_of(rows6)
    if not bars:
        return []
    plt = pyplot()
    terrains = ordered(set(bars), TERRAIN_ORDER)
    fig, axes = panel_grid(plt, len(terrains))
    seen: set[str] = set()
    for ax, terrain in zip(axes, terrains, strict=True):
        rows = bars[terrain]
        objs = ordered({b["objective"] for b in rows}, objective_order())
        methods = ordered({b["method"] for b in rows}, METHOD_NAMES)
        width = 0.8 / len(methods)
        for b in rows:
            x = objs.index(b["objective"]) - 0.4 + width * (methods.index(b["method"]) + 0.5)
            label = None if b["method"] in seen else METHOD_LABELS.get(b["method"], b["method"])
            seen.add(b["method"])
            ax.bar(
                x,
                b["value"],
                width * 0.9,
                color=METHOD_COLORS.get(b["method"], "grey"),
                label=label,
                hatch=None if b["common"] else "//",
                edgecolor="black",
                linewidth=0.5,
            )
            if b["se"] is not None:
                ax.errorbar(x, b["value"], yerr=b["se"], color="black", capsize=2, linewidth=0.8)
            if b["paper"] is not None:
                ax.plot(
                    [x - width * 0.45, x + width * 0.45],
                    [b["paper"]] * 2,
                    color="black",
                    linewidth=2.0,
                    label=None if "paper" in seen else "paper",
                )
                seen.add("paper")
        ax.axhline(0.0, color="grey", linewidth=0.8)
        tidy_axes(ax)
        ax.set_xticks(range(len(objs)))
        ax.set_xticklabels([(objectives or {}).get(o, o) for o in objs])
        ax.set_ylabel("improvement over nominal, 1 - c/c0 [%]")
        ax.set_title(f"{terrain}", fontsize=9)
    axes[0].legend(fontsize=7)
    return save_figure(
        plt,
        fig,
        out / FILE,
        "Table 6 beside the paper's: each method's improvement over the nominal design (the cost "
        "reduction 1 - c/c0, the paper's measure) on the common scenario set (mean ± SE over "
        "seeds; hatched: a cell without common-scenario rows, its runs' own final check) and the "
        "paper's figure for the same cell (black tick), one panel per terrain.",
    )
