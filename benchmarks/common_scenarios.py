"""Re-evaluate the best designs of several runs and the nominal design together, with one
policy (default: the shipped flat policy), on one common set of paired scenarios, so their
costs and improvements can be compared directly (each with its standard error).

    python benchmarks/common_scenarios.py runs/RUN_A runs/RUN_B runs/RUN_C --blocks 2

The scenarios are blocks of 32 x 250 (the quick preset's size) drawn from
`scenario_seed(1000, b)`, a set no run with a small seed uses. One JSON line per design.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    from coadapt_core.fitness import improvement_se, robust_cost, scenario_se, scenario_seed
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", help="run folders (each with a summary.json)")
    p.add_argument("--blocks", type=int, default=2, help="blocks of 32 paired scenarios")
    p.add_argument("--checkpoint", default=None, help="policy (default: the shipped flat policy)")
    args = p.parse_args(argv)
    summaries = []
    for folder in args.runs:
        path = Path(folder) / "summary.json"
        if not path.is_file():
            print(f"error: {folder} has no summary.json", file=sys.stderr)
            return 2
        summaries.append(json.loads(path.read_text()))
    checkpoint = args.checkpoint or str(shipped_checkpoint("kuafu", "flat"))
    robot, sim_cls, objectives = resolve_plugins("kuafu", "mujoco", ["tracking", "power", "torque"])
    backend = make_backend(robot, sim_cls, objectives, terrain="flat", checkpoint=checkpoint)
    designs = np.array([s["best_design"] for s in summaries] + [[1.0, 1.0]])
    per = np.concatenate([backend.real_fitness(designs, objectives, agents=32, steps=250, seed=scenario_seed(1000, b)).per_scenario
                          for b in range(max(1, args.blocks))], axis=1)
    cost, se = robust_cost(per), scenario_se(per)
    for i, s in enumerate([*summaries, {"seed": "nominal", "best_design": [1.0, 1.0]}]):
        row = {"run_seed": s.get("seed"), "design": [round(float(x), 3) for x in s["best_design"]], "scenarios": int(per.shape[1])}
        for j, o in enumerate(objectives):
            row[o.name], row[f"{o.name}_se"] = float(cost[i, j]), float(se[i, j])
            if i < len(summaries):
                row[f"{o.name}_improvement"] = float(o.improvement(cost[i, j], cost[-1, j]))
                row[f"{o.name}_improvement_se"] = improvement_se(o, per[i, :, j], per[-1, :, j])
        print(json.dumps(row))
    backend.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
