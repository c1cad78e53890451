"""The learning curves of `benchmarks/time_to_walk.py` runs, side by side: the mean reward
and the walking gate's worst figures (the highest tracking ratio and the lowest survival of
the nominal design and the four corners) against interactions and against training wall
clock, one line per run, and a Markdown table of when each run first walked.

Each input is a check log (the JSON lines time_to_walk.py prints on stderr), named
ARM-sSEED.log; the arm is the file name before the seed.

    python benchmarks/time_to_walk_curves.py runs/ttw/*.log --plot docs/results/time-to-walk.png
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any


def read_curve(path: Path) -> dict[str, Any]:
    """One run's checks: arm, seed and per check interactions, seconds, reward, worst gate."""
    match = re.fullmatch(r"(.+)-s(\d+)", path.stem)
    if match is None:
        raise ValueError(f"{path.name}: expected a name ARM-sSEED.log")
    rows = []
    for line in path.read_text().splitlines():
        if not line.startswith("{"):
            continue
        row = json.loads(line)
        gate = row["designs"].values()
        rows.append(
            {
                "interactions": int(row["interactions"]),
                "seconds": float(row["train_seconds"]),
                "reward": float(row["mean_reward"]),
                "worst_tracking": max(float(g["tracking_ratio"]) for g in gate),
                "worst_survival": min(float(g["survival"]) for g in gate),
                "walking": bool(row["walking"]),
            }
        )
    walked = next((r for r in rows if r["walking"]), None)
    return {"arm": match.group(1), "seed": int(match.group(2)), "rows": rows, "walked": walked}


def table(curves: list[dict[str, Any]]) -> str:
    lines = [
        "| arm | seed | walked | interactions | training seconds | last check (interactions, "
        "s, worst tracking ratio, lowest survival) |",
        "|---|---|---|---|---|---|",
    ]
    for c in curves:
        w, last = c["walked"], c["rows"][-1]
        steps = format(w["interactions"], ",") if w else "-"
        seconds = format(w["seconds"], ".0f") if w else "-"
        lines.append(
            f"| {c['arm']} | {c['seed']} | {'yes' if w else 'no'} | {steps} | {seconds} "
            f"| {last['interactions']:,}, {last['seconds']:.0f}, "
            f"{last['worst_tracking']:.2f}, {last['worst_survival']:.2f} |"
        )
    return "\n".join(lines)


def plot(curves: list[dict[str, Any]], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 2, figsize=(11, 10), sharex="col")
    arms = sorted({c["arm"] for c in curves})
    colours = {a: f"C{i}" for i, a in enumerate(arms)}
    styles = ["-", "--", ":", "-."]
    for c in curves:
        for col, key, unit in ((0, "interactions", 1e6), (1, "seconds", 60.0)):
            x = [r[key] / unit for r in c["rows"]]
            kw = {"color": colours[c["arm"]], "ls": styles[c["seed"] % 4]}
            label = f"{c['arm']} s{c['seed']}"
            axes[0, col].plot(x, [r["reward"] for r in c["rows"]], label=label, **kw)
            axes[1, col].plot(x, [r["worst_tracking"] for r in c["rows"]], **kw)
            axes[2, col].plot(x, [r["worst_survival"] for r in c["rows"]], **kw)
    for col, name in ((0, "interactions (M)"), (1, "training wall clock (min)")):
        axes[2, col].set_xlabel(name)
        axes[1, col].axhline(0.5, color="grey", lw=0.8)  # the gate: tracking ratio <= 0.5
        axes[2, col].axhline(0.8, color="grey", lw=0.8)  # and survival >= 0.8
    axes[0, 0].set_ylabel("mean reward")
    axes[1, 0].set_ylabel("worst tracking ratio (gate <= 0.5)")
    axes[2, 0].set_ylabel("lowest survival (gate >= 0.8)")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("time to walk: nominal design and four corners, 16 agents x 5 s at 0.5 m/s")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("logs", nargs="+", type=Path)
    p.add_argument("--plot", type=Path, default=None, help="write the curves here (PNG)")
    args = p.parse_args(argv)
    try:
        curves = [read_curve(path) for path in args.logs]
    except (OSError, ValueError, KeyError) as exc:
        print(f"time_to_walk_curves: {exc}", file=sys.stderr)
        return 2
    curves.sort(key=lambda c: (c["arm"], c["seed"]))
    print(table(curves))
    if args.plot is not None:
        plot(curves, args.plot)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
