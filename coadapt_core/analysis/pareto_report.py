"""The report's Pareto fronts compared across seeds (docs/results.md): per multi-objective run
its front's size and hypervolume +- SE, per group of runs that differ only in the seed the
mean hypervolume +- its SE over the seeds (`pareto.md`, `pareto.csv`), and `pareto_seeds.png`,
each seed's front in costs relative to its own nominal design."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.analysis.facts import RunFacts
from coadapt_core.analysis.figures import PANEL_H, panel_grid, pyplot, save_figure, tidy_axes
from coadapt_core.analysis.pareto_figure import hv_text, pareto_points
from coadapt_core.pareto import HV_REFERENCE, relative_costs


def _group(f: RunFacts) -> tuple[str, ...]:
    """What runs of one comparison share: all but the seed."""
    return (*f.setting, f.method, f.optimizer, f.objective, f.terrain)


def _multi(facts: Sequence[RunFacts]) -> list[RunFacts]:
    return [
        f
        for f in facts
        if len(f.run["objectives"]) >= 2 and isinstance(f.summary.get("pareto_front"), dict)
    ]


def pareto_rows(facts: Sequence[RunFacts]) -> list[dict[str, Any]]:
    """One row per multi-objective run with a stored front, then one per group of seeds
    ("seeds" > 1): the mean hypervolume and its SE over the seeds (sample SD / sqrt(n))."""
    rows, groups = [], defaultdict(list)
    for f in _multi(facts):
        front = f.summary["pareto_front"]
        robot, sim, preset, method, optimizer, objective, terrain = _group(f)
        row = {
            "robot": robot,
            "simulator": sim,
            "preset": preset,
            "method": method,
            "optimizer": optimizer,
            "objectives": objective,
            "terrain": terrain,
            "run": f.run["id"],
            "seed": f.run.get("seed"),
            "front_designs": len(front.get("designs") or []),
            "hypervolume": front.get("hypervolume"),
            "hypervolume_se": front.get("hypervolume_se"),
        }
        rows.append(row)
        if isinstance(row["hypervolume"], int | float) and math.isfinite(row["hypervolume"]):
            groups[_group(f)].append(row)
    for members in groups.values():
        if len(members) < 2:
            continue
        values = np.array([m["hypervolume"] for m in members], dtype=float)
        rows.append(
            {
                **{
                    k: members[0][k]
                    for k in (
                        "robot",
                        "simulator",
                        "preset",
                        "method",
                        "optimizer",
                        "objectives",
                        "terrain",
                    )
                },
                "run": f"{len(members)} seeds",
                "seed": None,
                "front_designs": None,
                "hypervolume": float(values.mean()),
                "hypervolume_se": float(values.std(ddof=1) / math.sqrt(len(values))),
            }
        )
    return rows


def pareto_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """pareto.md: the rows as a Markdown table, with what the numbers are."""
    lines = [
        "# Pareto fronts: hypervolume",
        "",
        "Hypervolume of each run's final front in costs relative to its nominal design (1 + (cost "
        f"- nominal) / |nominal|, up to {HV_REFERENCE:g} in each objective; the nominal design "
        "alone has 1), +- its paired bootstrap SE over the final check's scenarios; a row of "
        "several seeds gives their mean +- its SE over the seeds (docs/results.md).",
        "",
        "| robot | simulator | preset | method | optimizer | objectives | terrain | run | front "
        "designs | hypervolume |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        hv = hv_text(r["hypervolume"], r["hypervolume_se"]).removeprefix("hypervolume ") or "-"
        lines.append(
            f"| {r['robot']} | {r['simulator']} | {r['preset']} | {r['method']} | "
            f"{r['optimizer']} | {r['objectives']} | {r['terrain']} | {r['run']} | "
            f"{r['front_designs'] or ''} | {hv} |"
        )
    return "\n".join(lines) + "\n"


def figure_pareto_seeds(facts: Sequence[RunFacts], out: Path) -> list[tuple[Path, str]]:
    """pareto_seeds.png: per group of runs that differ only in the seed (two or more), each
    seed's front in nominal-relative costs with its error bars and hypervolume +- SE."""
    groups: dict[tuple[str, ...], list[RunFacts]] = defaultdict(list)
    for f in _multi(facts):
        groups[_group(f)].append(f)
    panels = [(key, runs) for key, runs in groups.items() if len(runs) >= 2][:6]
    if not panels:
        return []
    plt = pyplot()
    fig, axes = panel_grid(plt, len(panels), height=PANEL_H + 0.4)
    for ax, (key, runs) in zip(axes, panels, strict=True):
        for f in runs:
            d = pareto_points(f)
            if d["nominal"] is None or not len(d["front"]):
                continue
            nominal = np.array(d["nominal"], dtype=float)
            z = relative_costs(d["front"], nominal)
            err = (
                None
                if d["front_se"] is None
                else d["front_se"] / np.where(nominal != 0, np.abs(nominal), 1.0)
            )
            ax.errorbar(
                z[:, 0],
                z[:, 1],
                xerr=None if err is None else err[:, 0],
                yerr=None if err is None else err[:, 1],
                fmt="o-",
                capsize=2,
                markersize=4,
                label=f"seed {f.run.get('seed')}: "
                f"{hv_text(d['hypervolume'], d['hypervolume_se']) or 'no front'}",
            )
        ax.plot(
            [1.0],
            [1.0],
            marker="x",
            color="black",
            markersize=9,
            linestyle="none",
            label="nominal design",
        )
        o1, o2 = runs[0].run["objectives"][:2]
        ax.set_xlabel(f"{o1} cost / nominal's")
        ax.set_ylabel(f"{o2} cost / nominal's")
        ax.set_title(
            f"{key[3]} {key[4]}, {key[5]} on {key[6]}\n{key[0]}, {key[1]}, {key[2]}", fontsize=8
        )
        ax.legend(fontsize=7)
        tidy_axes(ax)
    return save_figure(
        plt,
        fig,
        out / "pareto_seeds.png",
        "Pareto fronts compared across seeds: per group of runs that differ only in the seed, "
        "each seed's final front in costs relative to its own nominal design (1 = the nominal "
        "design's cost in the same final check; the cross), error bars +- SE, and its hypervolume "
        "+- SE in the legend (pareto.md gives the mean over seeds).",
    )


__all__ = ["figure_pareto_seeds", "pareto_markdown", "pareto_rows"]
