"""Where one co-adaptation run's wall clock goes, phase by phase, against the physics ceiling.

Runs one co-adaptation (`run_coadaptation`, the code path of `coadapt run`) of a named size,
then reads the run's summary.json (and evaluations.jsonl, which tells surrogate rounds from
real ones) and prints wall clock and interactions per phase: train, real evaluation,
surrogate (pseudo-critic fits and predictions, in real rounds as well as surrogate rounds),
final check and other (set-up, checkpoints, records). Each phase's interactions/s is set
against the batched physics ceiling measured in the same process, before and after the run
(their mean): the run's own simulator class stepped with fixed targets, no task and no policy,
at the batch the phase steps (population x evaluation agents for real evaluation,
population x agents per design for training).

    python benchmarks/run_cost.py --json                    # the default quick run, torque, seed 0
    python benchmarks/run_cost.py --size small --json       # one outer iteration, same rounds
    python benchmarks/run_cost.py --objective power --seed 1

Prints a table, then (with --json) one JSON line with `evaluation_vs_physics_ceiling`,
`training_vs_physics_ceiling` and `surrogate_share` (surrogate seconds / run seconds).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: named sizes: a preset and overrides ("small": the quick preset's population, scenarios, steps
#: and surrogate samples per round, one outer iteration and a shorter first training; "smoke":
#: seconds, for the tests)
SIZES: dict[str, tuple[str, dict]] = {
    "quick": ("quick", {}),
    "small": ("quick", {"outer_iterations": 1, "train_steps": 25_000}),
    "smoke": ("smoke", {}),
}


def physics_ceiling(
    sim_cls,
    robot,
    designs: np.ndarray,
    agents: int,
    *,
    terrain: str,
    randomization,
    steps: int = 40,
) -> float:
    """Environment steps/s of `sim_cls` holding the default pose: `designs` x `agents`
    environments, no task and no policy (one warm-up step)."""
    per_env = np.repeat(designs, agents, axis=0)
    sim = sim_cls(robot, per_env, terrain=terrain, randomization=randomization, seed=0)
    try:
        targets = sim.default_joint_pos.clone()
        sim.step(targets)
        t0 = time.perf_counter()
        for _ in range(steps):
            sim.step(targets)
        return len(per_env) * steps / (time.perf_counter() - t0)
    finally:
        sim.close()


def phases(summary: dict, evaluations: list[dict], wall: float) -> dict:
    """{phase: (seconds, interactions)} from a run's summary and evaluation records. The loop
    counts a surrogate round's seconds both as evaluation and as surrogate time: real
    evaluation is the evaluation seconds less the surrogate rounds'."""
    surrogate_rounds = sum(
        float(e.get("seconds", 0.0)) for e in evaluations if e.get("kind") == "surrogate"
    )
    out = {
        "train": (float(summary["train_seconds"]), int(summary["train_interactions"])),
        "real evaluation": (
            float(summary["eval_seconds"]) - surrogate_rounds,
            int(summary["eval_interactions"]),
        ),
        "surrogate": (float(summary["surrogate_seconds"]), 0),
        "final check": (float(summary["final_seconds"]), int(summary["final_interactions"])),
    }
    out["other"] = (wall - sum(s for s, _ in out.values()), 0)
    return out


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--size", choices=sorted(SIZES), default="quick", help="named run size (default quick)"
    )
    parser.add_argument("--objective", default="torque")
    parser.add_argument("--optimizer", default="pso")
    parser.add_argument("--sim", default="mujoco")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--out", default=None, help="parent folder of the run folder (default: a temporary one)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON line last")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)

    # the `coadapt` command's OpenMP wait policy, chosen before torch is imported
    from coadapt_core.launch import apply_omp_wait_policy

    apply_omp_wait_policy()
    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.coadapt.run import run_coadaptation
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.trainer import read_checkpoint
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.plugins import get_registry

    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="run-cost-"))
    overrides = {
        "objective": args.objective,
        "optimizer": args.optimizer,
        "sim": args.sim,
        "seed": args.seed,
        "out": str(out),
        "logger": "none",
        "store": "none",
        **SIZES[args.size][1],
    }
    config = make_config(SIZES[args.size][0], None, overrides)
    registry = get_registry()
    robot = registry.get("robot", config.robot)()
    sim_cls = registry.get("simulator", config.sim)
    checkpoint = config.checkpoint or shipped_checkpoint(robot, config.terrain)
    randomization = (
        RandomizationConfig.recorded(read_checkpoint(checkpoint)["train_config"].get("extra") or {})
        if checkpoint
        else RandomizationConfig()
    )
    designs = robot.design_space().sample(config.population, np.random.default_rng(0))
    batches = {"evaluation": config.evaluation_agents, "training": int(config.agents_per_design)}

    def ceilings() -> dict[str, float]:
        return {
            k: physics_ceiling(
                sim_cls, robot, designs, a, terrain=config.terrain, randomization=randomization
            )
            for k, a in batches.items()
        }

    before = ceilings()
    t0 = time.perf_counter()
    result = run_coadaptation(config, run_dir=out / f"run-cost-{args.size}-s{args.seed}")
    wall = time.perf_counter() - t0
    after = ceilings()

    run_dir = Path(result.run_dir)
    summary = json.loads((run_dir / "summary.json").read_text())
    evaluations = [
        json.loads(line)
        for line in (run_dir / "evaluations.jsonl").read_text().splitlines()
        if line.strip()
    ]
    parts = phases(summary, evaluations, wall)
    report = _report(args, parts, wall, before, after, summary, result.summary, run_dir)
    _print_report(report)
    if args.json:
        print(json.dumps(report))
    return 0


def _report(
    args: argparse.Namespace,
    parts: dict,
    wall: float,
    before: dict[str, float],
    after: dict[str, float],
    summary: dict,
    result_summary: dict,
    run_dir: Path,
) -> dict:
    """The JSON report: each phase's seconds, share and rate, the physics ceiling (mean of
    before and after the run) and the run's outcome."""
    ceiling = {k: 0.5 * (before[k] + after[k]) for k in before}

    def rate(name: str) -> float | None:
        seconds, steps = parts[name]
        return steps / seconds if seconds > 0 and steps > 0 else None

    evaluation_rate, training_rate = rate("real evaluation"), rate("train")
    return {
        "size": args.size,
        "objective": args.objective,
        "optimizer": args.optimizer,
        "seed": args.seed,
        "load_average": os.getloadavg(),
        "wall_seconds": round(wall, 1),
        "phases": {
            name: {
                "seconds": round(s, 1),
                "share": round(s / wall, 3),
                "interactions": n,
                "interactions_per_s": None if rate(name) is None else round(rate(name)),
            }
            for name, (s, n) in parts.items()
        },
        "physics_ceiling_env_steps_per_s": {k: round(v) for k, v in ceiling.items()},
        "physics_ceiling_before_after": {k: [round(before[k]), round(after[k])] for k in before},
        "evaluation_vs_physics_ceiling": None
        if evaluation_rate is None
        else round(evaluation_rate / ceiling["evaluation"], 3),
        "training_vs_physics_ceiling": None
        if training_rate is None
        else round(training_rate / ceiling["training"], 3),
        "surrogate_share": round(parts["surrogate"][0] / wall, 3),
        "real_rounds": summary.get("real_evaluations"),
        "surrogate_rounds": summary.get("surrogate_evaluations"),
        "best_design": summary.get("best_design"),
        "improvement": result_summary.get("improvement"),
        "improvement_se": result_summary.get("improvement_se"),
        "run_dir": str(run_dir),
    }


def _print_report(report: dict) -> None:
    """The phases as a Markdown table on stdout, the wall clock and ceiling on stderr."""
    print("| phase | seconds | share | interactions | interactions/s | vs physics ceiling |")
    print("|---|---|---|---|---|---|")
    for name, row in report["phases"].items():
        vs = {
            "real evaluation": report["evaluation_vs_physics_ceiling"],
            "train": report["training_vs_physics_ceiling"],
        }.get(name)
        print(
            f"| {name} | {row['seconds']} | {row['share']:.1%} | {row['interactions']:,} | "
            f"{row['interactions_per_s'] or '-'} | {vs if vs is not None else '-'} |"
        )
    print(
        f"wall clock {report['wall_seconds']} s; physics ceiling "
        f"{report['physics_ceiling_env_steps_per_s']} env steps/s; "
        f"surrogate share {report['surrogate_share']}",
        file=sys.stderr,
    )


if __name__ == "__main__":
    sys.exit(main())
