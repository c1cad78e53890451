"""How repeatable is real fitness (Algorithm 2)? Evaluates one grid of (thigh, shank) designs
with the shipped flat policy under two scenario seeds and prints, per objective:

- the Spearman rank correlation of the grid's costs between the two seeds (does the ranking
  an optimizer sees repeat?), for the cost rule a run uses (`--cost-rule`, default the
  capped mean of `coadapt_core.costs.CostRule`, its reference level the grid's nominal
  design), for the plain mean over scenarios (eq. 4) and for the trimmed mean (the rule before),
- the median relative standard error of a design's cost over its scenarios,
- the median ratio of the paired to the unpaired standard error of a design's difference to
  the nominal design (what common random numbers buy; 1 = nothing),
- each seed's fall rate (share of agents that fell at least once), mean and worst design.

    python benchmarks/fitness_noise.py                      # 5 x 5, the quick preset's 32 x 250
    python benchmarks/fitness_noise.py --grid 5 --json      # one JSON line last
    python benchmarks/fitness_noise.py --protocol unpaired  # the protocol before pairing
    python benchmarks/fitness_noise.py --agents 32 --steps 500
    python benchmarks/fitness_noise.py --cost-rule trimmed  # the rule before the capped one

`--protocol unpaired` reproduces the evaluation before common random numbers: commands drawn
independently per agent, randomization and noise independent per environment, and (as
`coadapt landscape` did) one scenario seed per grid row. Its unpaired-to-paired ratio is
computed on those independent streams, so it is about 1 by construction.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OBJECTIVES = ("tracking", "power", "torque")


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    from scipy.stats import spearmanr

    return float(spearmanr(a, b).statistic)


def evaluate_grid(
    backend,
    objectives,
    designs: np.ndarray,
    *,
    agents: int,
    steps: int,
    seed: int,
    grid: int,
    paired: bool,
) -> dict:
    """costs [D, M], per-scenario costs [D, A, M], fall rates [D], fall cost share [D, M]."""
    backend.paired_evaluation = paired
    if paired:  # one call, one scenario set for every design
        fit = backend.real_fitness(designs, objectives, agents=agents, steps=steps, seed=seed)
        fits = [fit]
    else:  # the old landscape: a seed per row
        fits = [
            backend.real_fitness(
                designs[r * grid : (r + 1) * grid],
                objectives,
                agents=agents,
                steps=steps,
                seed=seed + r,
            )
            for r in range(grid)
        ]
    per = np.concatenate([f.per_scenario for f in fits])
    falls = np.concatenate([f.fall_rate for f in fits])
    scenario_falls = np.concatenate([f.scenario_falls for f in fits])
    seconds = sum(f.seconds for f in fits)
    return {
        "per": per,
        "fall_rate": falls,
        "scenario_falls": scenario_falls,
        "seconds": seconds,
        "interactions": int(sum(f.interactions for f in fits)),
    }


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    from coadapt_core.coadapt.config import PRESETS
    from coadapt_core.costs import COST_RULES, TRIMMED, CostRule, paired_difference, scenario_se
    from coadapt_core.experiments.landscape import landscape_designs
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import make_backend, resolve_plugins
    from coadapt_core.scenarios.seeds import scenario_seed

    quick = PRESETS["quick"]
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--grid", type=int, default=5, help="points per axis (grid x grid designs)")
    p.add_argument(
        "--agents",
        type=int,
        default=quick.get("eval_agents") or quick["agents_per_design"],
        help="paired scenarios (agents) per design (default: the quick preset's)",
    )
    p.add_argument("--steps", type=int, default=quick["eval_steps"], help="policy steps per agent")
    p.add_argument("--seeds", default="0,1", help="the two scenario seeds")
    p.add_argument("--protocol", choices=("paired", "unpaired"), default="paired")
    p.add_argument(
        "--cost-rule",
        choices=COST_RULES,
        default="capped",
        help="how scenarios make a cost (default: capped)",
    )
    p.add_argument(
        "--cost-cap",
        type=float,
        default=3.0,
        help="the capped rule's cap (nominal median scenarios)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON line last")
    args = p.parse_args(argv)
    if not args.cost_cap > 1:
        print(f"error: --cost-cap must be > 1, got {args.cost_cap}", file=sys.stderr)
        return 2
    rule = CostRule(args.cost_rule, args.cost_cap)
    if args.grid < 2 or args.agents < 2 or args.steps < 1:
        print("error: --grid and --agents must be >= 2, --steps >= 1", file=sys.stderr)
        return 2
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
        assert len(seeds) == 2
    except (ValueError, AssertionError):
        print(f"error: --seeds must be two integers a,b, got '{args.seeds}'", file=sys.stderr)
        return 2

    checkpoint = shipped_checkpoint("kuafu", "flat")
    robot, sim_cls, objectives = resolve_plugins("kuafu", "mujoco", list(OBJECTIVES))
    backend = make_backend(
        robot,
        sim_cls,
        objectives,
        terrain="flat",
        checkpoint=str(checkpoint),
        agents_per_design=args.agents,
    )
    designs = landscape_designs(args.grid, (0.5, 0.5), (1.5, 1.5), (1.0, 1.0))
    nominal = int(np.argmin(np.abs(designs - 1.0).sum(axis=1)))
    paired = args.protocol == "paired"
    t0 = time.perf_counter()
    # the scenario sets `coadapt run/landscape --seed s` use (scenario_seed); rows of the
    # unpaired protocol take consecutive seeds, as the old landscape did
    runs = [
        evaluate_grid(
            backend,
            objectives,
            designs,
            agents=args.agents,
            steps=args.steps,
            seed=scenario_seed(s),
            grid=args.grid,
            paired=paired,
        )
        for s in seeds
    ]
    wall = time.perf_counter() - t0

    for r in (
        runs
    ):  # the rule's scenario values and costs, the reference level from the grid's nominal design
        ref = (
            rule.reference(r["per"][nominal], r["scenario_falls"][nominal])
            if rule.needs_reference
            else None
        )
        r["values"] = rule.scenario_values(r["per"], r["scenario_falls"], ref)
        r["costs"] = rule.aggregate(r["values"])
    result: dict = {
        "grid": args.grid,
        "cost_rule": rule.rule,
        "cost_cap": rule.cap,
        "agents": args.agents,
        "steps": args.steps,
        "seeds": seeds,
        "protocol": args.protocol,
        "policy": Path(checkpoint).name,
        "seconds": round(wall, 1),
        "seconds_per_grid": [round(r["seconds"], 1) for r in runs],
        "interactions_per_grid": runs[0]["interactions"],
        "fall_rate_mean": [float(r["fall_rate"].mean()) for r in runs],
        "fall_rate_max": [float(r["fall_rate"].max()) for r in runs],
        "objectives": {},
    }
    print(
        f"{args.grid}x{args.grid} grid, {args.agents} agents x {args.steps} steps, protocol "
        f"{args.protocol}, "
        f"seeds {seeds}, {wall:.0f} s"
    )
    print(f"cost rule: {rule.describe()}")
    print(
        f"{'objective':10s} {'spearman':>9s} {'(plain mean)':>13s} {'(trimmed)':>10s} "
        f"{'median rel SE':>14s} {'paired/unpaired SE':>19s}"
    )
    for j, name in enumerate(OBJECTIVES):
        rho = spearman(runs[0]["costs"][:, j], runs[1]["costs"][:, j])
        rel, ratios = [], []
        for r in runs:
            se = scenario_se(r["values"], rule.aggregate)[:, j]
            rel.extend((se / np.abs(r["costs"][:, j])).tolist())
            for i in range(len(designs)):
                if i == nominal:
                    continue
                _, pse = paired_difference(r["values"], i, nominal, rule.aggregate)
                unpaired = float(np.hypot(se[i], se[nominal]))
                if unpaired > 0:
                    ratios.append(float(pse[j]) / unpaired)
        plain = spearman(runs[0]["per"][:, :, j].mean(axis=1), runs[1]["per"][:, :, j].mean(axis=1))
        trimmed = spearman(TRIMMED.cost(runs[0]["per"])[:, j], TRIMMED.cost(runs[1]["per"])[:, j])
        entry = {
            "spearman": round(rho, 3),
            "spearman_plain_mean": round(plain, 3),
            "spearman_trimmed": round(trimmed, 3),
            "median_relative_se": round(float(np.median(rel)), 4),
            "paired_to_unpaired_se": round(float(np.median(ratios)), 3),
        }
        result["objectives"][name] = entry
        print(
            f"{name:10s} {entry['spearman']:9.3f} {entry['spearman_plain_mean']:13.3f} "
            f"{entry['spearman_trimmed']:10.3f} {entry['median_relative_se']:14.4f} "
            f"{entry['paired_to_unpaired_se']:19.3f}"
        )
    print(f"fall rate: mean {result['fall_rate_mean']}, max {result['fall_rate_max']}")
    if args.json:
        print(json.dumps(result))
    backend.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
