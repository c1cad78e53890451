"""Computational cost of each co-adaptation method (the paper's Table 7): environment
interactions (training + evaluation) and wall clock, on one preset and seed.

    python benchmarks/coadapt_cost.py                  # smoke preset, the real learner
    python benchmarks/coadapt_cost.py --fake           # the analytic backend of the tests
    python benchmarks/coadapt_cost.py --preset quick --methods ours,no-surrogate --json out.json

Prints a Markdown table, the ratio ours / no-surrogate (the paper: 102 M / 132 M = 0.77
interactions, 1.07 h / 1.73 h = 0.62 wall clock) and, last, one JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Table 7 of the paper: interactions (M, training + evaluation), hours (training + evaluation)
PAPER = {
    "ours": ((72, 30), (0.4, 0.67)),
    "no-surrogate": ((72, 60), (0.4, 1.33)),
    "no-real": ((72, 0), (0.4, 0.0)),
    "no-retrain": ((0, 60), (0.0, 1.33)),
    "bo-specialized": ((200, 0), (2.67, 0.33)),
}


def run_method(method: str, args: argparse.Namespace, out: Path) -> dict:
    from coadapt_core.coadapt import make_config, run_coadaptation

    overrides = {"method": method, "seed": args.seed, "objective": args.objective, "optimizer": args.optimizer,
                 "out": str(out), "sim": args.sim, "terrain": args.terrain}
    config = make_config(args.preset, None, overrides)
    kwargs = {}
    if args.fake:
        sys.path.insert(0, str(ROOT))
        from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend

        kwargs = dict(backend_factory=lambda seed: AnalyticBackend(seed), design_space=SPACE, nominal_design=NOMINAL)
    t0 = time.perf_counter()
    result = run_coadaptation(config, run_dir=out / method, **kwargs)
    s = result.summary
    return {
        "method": method,
        "train_interactions": s["train_interactions"],
        "eval_interactions": s["eval_interactions"],
        "final_interactions": s["final_interactions"],
        "train_seconds": s["train_seconds"],
        "eval_seconds": s["eval_seconds"],
        "wall_seconds": time.perf_counter() - t0,
        "real_rounds": s["real_evaluations"],
        "surrogate_rounds": s["surrogate_evaluations"],
        "designs_evaluated": s["designs_evaluated"],
        "best_design": s["best_design"],
        "best_cost": s["best_cost"],
        "improvement": s["improvement"],
    }


def table(rows: list[dict]) -> str:
    lines = [
        "| Method | Interactions (training + evaluation) | Wall clock s (training + evaluation) | Rounds real / surrogate | Designs | Best cost | Improvement | Paper (M; h) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        search = r["train_interactions"] + r["eval_interactions"]
        (pt, pe), (ht, he) = PAPER[r["method"]]
        lines.append(
            f"| {r['method']} | {search:,} ({r['train_interactions']:,} + {r['eval_interactions']:,}) "
            f"| {r['train_seconds'] + r['eval_seconds']:.1f} ({r['train_seconds']:.1f} + {r['eval_seconds']:.1f}) "
            f"| {r['real_rounds']} / {r['surrogate_rounds']} | {r['designs_evaluated']} | {r['best_cost']:.4g} "
            f"| {100 * r['improvement']:+.1f} % | {pt + pe} ({pt}+{pe}); {ht + he:.2f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="smoke", help="smoke | quick | paper (default smoke)")
    parser.add_argument("--methods", default="ours,no-surrogate,no-real,no-retrain,bo-specialized")
    parser.add_argument("--objective", default="torque")
    parser.add_argument("--optimizer", default="pso")
    parser.add_argument("--sim", default="mujoco")
    parser.add_argument("--terrain", default="flat")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fake", action="store_true", help="the analytic backend of the tests (seconds)")
    parser.add_argument("--out", default=None, help="folder for the run folders (default: a temporary one)")
    parser.add_argument("--json", default=None, help="also write the rows to this JSON file")
    args = parser.parse_args(argv)

    from coadapt_core.coadapt.config import METHODS
    from coadapt_core.errors import UserError

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        print(f"error: unknown method(s) {', '.join(unknown)}; accepted: {', '.join(METHODS)}", file=sys.stderr)
        return 2
    out = Path(args.out or tempfile.mkdtemp(prefix="coadapt-cost-"))
    rows = []
    try:
        for method in methods:
            print(f"running {method} ...", file=sys.stderr)
            rows.append(run_method(method, args, out))
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"\nCo-adaptation cost, preset {args.preset}, objective {args.objective}, "
          f"{'analytic backend' if args.fake else args.sim}, seed {args.seed}\n")
    print(table(rows))
    by = {r["method"]: r for r in rows}
    ratios = {}
    if "ours" in by and "no-surrogate" in by:
        o, n = by["ours"], by["no-surrogate"]
        ratios = {
            "interactions": (o["train_interactions"] + o["eval_interactions"]) / max(1, n["train_interactions"] + n["eval_interactions"]),
            "eval_interactions": o["eval_interactions"] / max(1, n["eval_interactions"]),
            "wall_seconds": (o["train_seconds"] + o["eval_seconds"]) / max(1e-9, n["train_seconds"] + n["eval_seconds"]),
        }
        print(f"\nours / no-surrogate: interactions {ratios['interactions']:.2f} (paper 102/132 = 0.77), "
              f"evaluation interactions {ratios['eval_interactions']:.2f} (paper 30/60 = 0.50), "
              f"wall clock {ratios['wall_seconds']:.2f} (paper 1.07/1.73 = 0.62)")
    payload = {"preset": args.preset, "fake": args.fake, "objective": args.objective, "seed": args.seed,
               "rows": rows, "ratios_ours_over_no_surrogate": ratios, "run_folders": str(out)}
    if args.json:
        Path(args.json).write_text(json.dumps(payload, indent=2))
    print(json.dumps(payload))
    return 0


if __name__ == "__main__":
    sys.exit(main())
