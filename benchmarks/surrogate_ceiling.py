"""The surrogate's ranking against its noise ceiling, per judged round (issue 52): for each
finished run folder given, every real round where both the surrogate's prediction and the
real costs exist, its Spearman beside the Spearman the real costs' own noise allows
(`coadapt_core.surrogate_quality.noise_ceiling`, Monte Carlo from each design's cost SE) and
whether the surrogate is near that ceiling or below it; then the run's pooled figures.
Beside the surrogate's, the Spearman a plane through the same policy's earlier real rounds
would have had on the round (`coadapt_core.coadapt.trend`, the estimator of
`--surrogate-trend`), replayed from the run's `evaluations.jsonl`: the same designs, the same
real costs, the labels the run had then.

Reads each run's `state.json` (JSON; nothing is unpickled). The SE is each design's paired SE
(`cost_paired_se` in its batches), as a run computes it; a run recorded before that was kept
is read with its unpaired SE (`cost_se`) or, older still, the round's median relative SE
times each cost, and marked `unpaired SE`: its ceiling is then a lower bound (common
scenarios move the designs' costs together, which the unpaired SE counts as noise).

    python benchmarks/surrogate_ceiling.py runs/*/            # a Markdown table
    python benchmarks/surrogate_ceiling.py RUN_DIR ... --json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from coadapt_core import surrogate_quality as sq  # noqa: E402
from coadapt_core.coadapt.trend import fit_trend  # noqa: E402


def replayed_trend(run_dir: Path, objective: str) -> dict[tuple[int, int], float | None]:
    """(outer, inner) -> the Spearman of the plane through the real rounds of the same outer
    iteration before it (None where fewer labels than a plane needs)."""
    path = run_dir / "evaluations.jsonl"
    if not path.is_file():
        return {}
    rounds: dict[tuple[int, int], list[tuple[list[float], float]]] = {}
    for line in path.read_text().splitlines():
        row = json.loads(line)
        if row.get("kind") == "real" and objective in (row.get("costs") or {}):
            key = (int(row["outer"]), int(row["inner"]))
            rounds.setdefault(key, []).append((row["design"], float(row["costs"][objective])))
    out: dict[tuple[int, int], float | None] = {}
    for (outer, inner), here in rounds.items():
        before = [x for (o, i), v in rounds.items() if o == outer and i < inner for x in v]
        trend = fit_trend([d for d, _ in before], [c for _, c in before]) if before else None
        out[(outer, inner)] = (
            None
            if trend is None
            else sq.spearman(trend.predict([d for d, _ in here])[:, 0], [c for _, c in here])
        )
    return out


def _floats(values: list[Any]) -> list[float]:
    return [float("nan") if v is None else float(v) for v in values]


def run_rounds(run_dir: Path) -> dict[str, Any]:
    """The run's judged rounds with their ceilings, and the pooled figures over the eligible
    ones (the rounds the run's own pooled Spearman covers)."""
    state = json.loads((run_dir / "state.json").read_text())
    config = state["config"]
    batches = {(b["outer"], b["inner"]): b for b in state["batches"] if b["kind"] == "real"}
    objective = str(config["objective"]).split(",")[0]
    rows, approx = [], False
    trend = replayed_trend(run_dir, objective)
    for q in state["quality_rounds"]:
        entry = (q.get("objectives") or {}).get(objective)
        batch = batches.get((q["outer"], q["inner"]))
        if entry is None or batch is None:
            continue
        real, surrogate = _floats(entry["real"]), _floats(entry["surrogate"])
        # the paired SE (the noise of the ranking on common scenarios), as the run does
        se, kind = batch.get("cost_paired_se"), "paired"
        if se is None and batch.get("cost_se") is not None:
            se, kind = batch["cost_se"], "unpaired"
        if se is None:  # recorded before the designs' SEs were kept
            se, kind = (
                [batch.get("median_relative_se", float("nan")) * abs(r) for r in real],
                "approx",
            )
        approx = approx or kind != "paired"
        paired = [x for x in _floats(se) if np.isfinite(x)]
        figures = sq.with_ceiling(sq.quality(surrogate, real), real, se)
        rows.append(
            {
                "outer": q["outer"],
                "inner": q["inner"],
                "eligible": q["eligible"],
                "designs": len(real),
                "spread": float(np.nanstd(real) / abs(np.nanmean(real))),
                "median_relative_se": batch.get("median_relative_se"),
                "se_kind": kind,
                "median_relative_paired_se": float(
                    np.median(np.array(paired) / np.abs(np.nanmean(real)))
                )
                if paired
                else None,
                **{k: figures.get(k) for k in ("spearman", *sq.CEILING_FIGURES)},
                "trend_spearman": trend.get((q["outer"], q["inner"])),
                "real": real,
                "surrogate": surrogate,
                "se": _floats(se),
            }
        )
    used = [r for r in rows if r["eligible"]]
    real = [x for r in used for x in r["real"]]
    pooled = sq.with_ceiling(
        sq.quality([x for r in used for x in r["surrogate"]], real),
        real,
        [x for r in used for x in r["se"]],
    )
    return {
        "run": run_dir.name,
        "robot": config.get("robot"),
        "objective": objective,
        "seed": config.get("seed"),
        "se_approx": approx,
        "rounds": [
            {k: v for k, v in r.items() if k not in ("real", "surrogate", "se")} for r in rows
        ],
        "pooled": {k: pooled.get(k) for k in ("spearman", "n", *sq.CEILING_FIGURES)},
    }


def _f(x: Any, spec: str = ".2f") -> str:
    return "-" if x is None else format(x, spec)


def markdown(runs: list[dict[str, Any]]) -> str:
    lines = [
        "| run | round (outer, inner) | judged | designs | real spread | median rel. SE "
        "(paired) | surrogate Spearman | plane (replayed) | noise ceiling +- sd | repeat "
        "| verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for run in runs:
        name = f"{run['robot']} {run['objective']} s{run['seed']}" + (
            " (unpaired SE)" if run["se_approx"] else ""
        )
        for r in run["rounds"]:
            lines.append(
                f"| {name} | ({r['outer']}, {r['inner']}) | {'yes' if r['eligible'] else 'no'} "
                f"| {r['designs']} | {_f(100 * r['spread'], '.1f')} % "
                f"| {_f(100 * (r['median_relative_se'] or float('nan')), '.1f')} % "
                f"({_f(100 * (r['median_relative_paired_se'] or float('nan')), '.1f')} %) "
                f"| {_f(r['spearman'])} | {_f(r['trend_spearman'])} "
                f"| {_f(r['ceiling'])} +- {_f(r['ceiling_sd'])} "
                f"| {_f(r['repeat'])} | {r['against_ceiling'] or '-'} |"
            )
        p = run["pooled"]
        lines.append(
            f"| {name} | pooled (judged) | | {p['n']} | | | {_f(p['spearman'])} | "
            f"| {_f(p['ceiling'])} +- {_f(p['ceiling_sd'])} | {_f(p['repeat'])} "
            f"| {p['against_ceiling'] or '-'} |"
        )
    lines += ["", across(runs)]
    return "\n".join(lines)


def across(runs: list[dict[str, Any]]) -> str:
    """Over the judged rounds of the runs read with paired SEs: the surrogate's Spearman, the
    ceiling and their difference, mean +- standard error over rounds."""
    rounds = [
        r
        for run in runs
        if not run["se_approx"]
        for r in run["rounds"]
        if r["eligible"] and r["spearman"] is not None and r["ceiling"] is not None
    ]
    if len(rounds) < 2:
        return "fewer than 2 judged rounds with paired SEs: no mean over rounds"

    def stat(values: list[float]) -> str:
        v = np.asarray(values, dtype=float)
        return f"{v.mean():.2f} +- {v.std(ddof=1) / np.sqrt(len(v)):.2f}"

    rho = [r["spearman"] for r in rounds]
    ceiling = [r["ceiling"] for r in rounds]
    below = sum(1 for r in rounds if r["against_ceiling"] == "below")
    text = (
        f"over {len(rounds)} judged rounds with paired SEs (mean +- SE over rounds): surrogate "
        f"Spearman {stat(rho)}, noise ceiling {stat(ceiling)}, surrogate - ceiling "
        f"{stat([a - b for a, b in zip(rho, ceiling, strict=True)])}; {below} round(s) below"
    )
    planes = [r for r in rounds if r.get("trend_spearman") is not None]
    if len(planes) >= 2:
        plane = [r["trend_spearman"] for r in planes]
        text += (
            f"; the plane (replayed, {len(planes)} rounds): {stat(plane)}, plane - ceiling "
            f"{stat([a - r['ceiling'] for a, r in zip(plane, planes, strict=True)])}, plane - "
            f"surrogate {stat([a - r['spearman'] for a, r in zip(plane, planes, strict=True)])}"
        )
    return text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", type=Path, help="run folders (each with state.json)")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    runs = [run_rounds(d) for d in args.runs if (d / "state.json").is_file()]
    print(json.dumps(runs, indent=1) if args.json else markdown(runs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
