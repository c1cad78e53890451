"""What the thread budget buys a run: the same co-adaptation run twice, one after the other in
one process, first with the learner on one torch thread (every run before issue 40: the
shipped policies record `torch_threads: 1` and the run took it), then with the default budget
(`coadapt_core.threads`: the physics and the learner on the CPUs this process may use).

Prints each run's wall clock, training and surrogate seconds, the threads its training phases
recorded and its answer (best design, improvement +- its paired standard error), then the
ratio of the wall clocks (one thread / default). Both runs have the same config and seed; only
the learner's threads differ (the physics has the budget in both). A smoke run before them,
not reported, pays the start-up costs (imports, compiled models).

    python benchmarks/thread_cost.py --json                  # the default quick run, torque, seed 0
    python benchmarks/thread_cost.py --size small --json     # one outer iteration, same rounds
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

#: named sizes, as benchmarks/run_cost.py's
SIZES: dict[str, tuple[str, dict]] = {
    "quick": ("quick", {}),
    "small": ("quick", {"outer_iterations": 1, "train_steps": 25_000}),
    "smoke": ("smoke", {}),
}


def one_run(config, out: Path, learner_threads: int | None) -> dict:
    """Run `config` into `out`; `learner_threads` (None: the budget) replaces the learner's
    torch threads of every backend the run builds (the PPO update and the surrogate's fits)."""
    from coadapt_core.coadapt.run import run_coadaptation
    from coadapt_core.coadapt.setup import build_parts

    factory = build_parts(config).backend_factory

    def backend(seed: int):
        built = factory(seed)
        if learner_threads is not None:
            built.trainer.learner_threads = learner_threads
        return built

    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    result = run_coadaptation(config, backend_factory=backend, run_dir=out)
    wall = time.perf_counter() - t0
    summary = result.summary
    phases = [
        json.loads(line)["extra"]
        for line in (out / "trainings.jsonl").read_text().splitlines()
        if line.strip()
    ]
    return {
        "wall_seconds": round(wall, 1),
        "train_seconds": round(summary["train_seconds"], 1),
        "surrogate_seconds": round(summary["surrogate_seconds"], 1),
        "threads_recorded": [
            {k: p.get(k) for k in ("torch_threads", "physics_threads")} for p in phases
        ],
        "best_design": summary["best_design"],
        "improvement": summary["improvement"],
        "improvement_se": summary.get("improvement_se"),
        "interactions": summary["interactions"],
        "load_average_1min_before_after": [round(load, 2), round(os.getloadavg()[0], 2)],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--size", choices=sorted(SIZES), default="quick", help="named run size (default quick)"
    )
    parser.add_argument("--objective", default="torque")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--threads",
        type=int,
        default=None,
        help="the budget (default: the CPUs this process may use)",
    )
    parser.add_argument(
        "--out",
        default=None,
        help="parent folder of the two run folders (default: a temporary one)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON line last")
    args = parser.parse_args(argv)

    from coadapt_core.launch import apply_omp_wait_policy

    apply_omp_wait_policy()  # the `coadapt` command's, chosen before torch is imported
    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.threads import apply_threads

    budget = apply_threads(args.threads)
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="thread-cost-"))
    overrides = {
        "objective": args.objective,
        "seed": args.seed,
        "out": str(out),
        "logger": "none",
        "store": "none",
        **SIZES[args.size][1],
    }
    # a smoke run first, not reported: imports, compiled models and caches are paid before the
    # timed pair, so the first of the two timed runs carries no start-up cost the second lacks
    one_run(make_config("smoke", None, {**overrides, "seed": args.seed + 1}), out / "warm-up", None)
    runs = {}
    for label, learner in (("one_learner_thread", 1), ("default", None)):
        config = make_config(SIZES[args.size][0], None, overrides)
        runs[label] = one_run(config, out / f"{args.size}-{label}", learner)
        print(
            f"{label}: {runs[label]['wall_seconds']} s, best {runs[label]['best_design']}, "
            "improvement "
            f"{runs[label]['improvement']:.3f} +- {runs[label]['improvement_se'] or 0:.3f}",
            file=sys.stderr,
        )
    report = {
        "size": args.size,
        "objective": args.objective,
        "seed": args.seed,
        "budget": budget,
        "cpus": os.cpu_count(),
        **runs,
        "wall_ratio_one_thread_over_default": round(
            runs["one_learner_thread"]["wall_seconds"] / runs["default"]["wall_seconds"], 3
        ),
    }
    if args.json:
        print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
