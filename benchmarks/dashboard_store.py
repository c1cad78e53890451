"""A big results store for the dashboard's benchmark: 10 000 runs and 1 000 000 evaluations
by default (100 per run: 5 outer iterations x 4 rounds x 4 real designs and one surrogate
design), two training phases per run, a summary and configuration per run as `coadapt run`
records them, and grids of 96 cells over them. A few runs are left running.

    python benchmarks/dashboard_store.py /tmp/big.db                    # 10 000 runs, 1 M rows
    python benchmarks/dashboard_store.py /tmp/small.db --runs 100       # a small one

The tables are made by `ResultsStore` (the schema as it is), the rows written by sqlite3 in
one transaction (about a minute on 2 cores). Prints one JSON line: the counts and seconds.
"""

from __future__ import annotations

import argparse
import json
import random
import sqlite3
import sys
import time
from pathlib import Path

from coadapt_core.results import ResultsStore

OBJECTIVES = (["torque"], ["power"], ["tracking"], ["torque", "power"])
METHODS = ("ours", "no-surrogate", "no-real", "no-retrain")
TERRAINS = ("flat", "rough", "slope")
CELLS_PER_GRID = 96


def run_rows(i: int, rng: random.Random, t0: float) -> tuple[tuple, list[tuple], list[tuple]]:
    """(the run's row, its evaluation rows, its training rows)."""
    objectives = OBJECTIVES[i % len(OBJECTIVES)]
    method, terrain, seed = METHODS[i // 4 % 4], TERRAINS[i // 16 % 3], i // 48 % 5
    stamp = f"20260101-{i // 3600:02d}{i // 60 % 60:02d}{i % 60:02d}"
    run_id = f"{stamp}-{method}-{'+'.join(objectives)}-s{seed}-{i:06x}"
    grid = f"grid-{i // CELLS_PER_GRID:04d}"
    cell = f"{method}/{'+'.join(objectives)}/{terrain}/s{seed}/{i}"
    created = t0 + i * 10.0
    status = "running" if i % 997 == 0 else "finished"
    config = {
        "method": method,
        "objective": ",".join(objectives),
        "terrain": terrain,
        "seed": seed,
        "outer_iterations": 5,
        "population": 4,
        "optimizer_iterations": 4,
        "run_dir": f"/nonexistent/runs/{run_id}",
    }
    best = [round(rng.uniform(0.5, 1.5), 4), round(rng.uniform(0.5, 1.5), 4)]
    improvement = rng.uniform(-0.05, 0.25)
    summary = {
        "run_id": run_id,
        "best_design": best,
        "best_cost": 1.0 - improvement,
        "best_cost_se": 0.004,
        "nominal_cost": 1.0,
        "improvement": improvement,
        "improvement_se": rng.uniform(0.003, 0.02),
        "fall_rate_difference": rng.uniform(-0.01, 0.03),
        "fall_rate_difference_se": 0.004,
        "warnings": ["best design at a bound of the design space"] if i % 7 == 0 else [],
    }
    if len(objectives) > 1:
        summary["pareto_front"] = {
            "designs": [best, [1.0, 1.0]],
            "costs": [{o: 1.0 - improvement for o in objectives}, {o: 1.0 for o in objectives}],
            "hypervolume": 0.3,
            "hypervolume_se": 0.01,
        }
    run = (
        run_id, grid, cell, method, ",".join(objectives), terrain, "pso", "mujoco", "kuafu",
        "paper", seed, json.dumps(config), "0.1.0", None, status, config["run_dir"], created,
        created + 5000, None if status == "running" else created + 5000,
        None if status == "running" else json.dumps(summary),
    )  # fmt: skip
    evaluations = []
    for n in range(100):
        outer, inner, k = n // 20, n // 5 % 4, n % 5
        kind, idx = ("surrogate", 0) if k == 4 else ("real", k)
        design = [rng.uniform(0.5, 1.5), rng.uniform(0.5, 1.5)]
        costs = {o: 1.0 + (design[0] - 0.6) ** 2 + (design[1] - 0.6) ** 2 for o in objectives}
        error = json.dumps({objectives[0]: 0.01}) if kind == "real" else None
        interactions = 32_000 if kind == "real" else 0
        evaluations.append(
            (run_id, outer, inner, idx, kind, json.dumps(design), json.dumps(costs), error,
             interactions, 1.5, None, created + n)
        )  # fmt: skip
    training = [
        (run_id, outer, 0, 2_000_000, 600.0, 0.5, "{}", created + outer) for outer in range(2)
    ]
    return run, evaluations, training


def make_store(path: Path, runs: int, seed: int = 0) -> dict[str, float]:
    if path.exists():
        sys.exit(f"{path} exists; give a new file")
    with ResultsStore(path):  # the tables and the schema version, as coadapt makes them
        pass
    start = time.perf_counter()
    rng, t0 = random.Random(seed), time.time() - runs * 10.0
    db = sqlite3.connect(path)
    with db:
        for first in range(0, runs, 500):
            batch = [run_rows(i, rng, t0) for i in range(first, min(runs, first + 500))]
            db.executemany(f"INSERT INTO runs VALUES ({','.join('?' * 20)})", [b[0] for b in batch])
            db.executemany(
                "INSERT INTO evaluations (run_id, outer, inner, idx, kind, design, costs, "
                "surrogate_error, interactions, seconds, simulator, created_at) "
                f"VALUES ({','.join('?' * 12)})",
                [e for b in batch for e in b[1]],
            )
            db.executemany(
                "INSERT INTO training_phases (run_id, outer, idx, steps, seconds, final_reward, "
                "extra, created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [t for b in batch for t in b[2]],
            )
        grids = (runs + CELLS_PER_GRID - 1) // CELLS_PER_GRID
        db.executemany(
            "INSERT INTO grids VALUES (?, ?, ?, ?)",
            [(f"grid-{g:04d}", "{}", t0, t0) for g in range(grids)],
        )
        db.execute(
            "INSERT INTO grid_cells SELECT grid_id, cell, id, status, 1, NULL, updated_at FROM runs"
        )
    db.close()
    return {"runs": runs, "evaluations": runs * 100, "seconds": time.perf_counter() - start}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("store", type=Path, help="the SQLite file to make (must not exist)")
    parser.add_argument("--runs", type=int, default=10_000, help="runs (100 evaluations each)")
    args = parser.parse_args()
    print(json.dumps(make_store(args.store, args.runs)))


if __name__ == "__main__":
    main()
