"""What a cheaper surrogate fit costs in ranking (issue 25): the fitted pseudo-critic ensemble
(`coadapt_core.learning.surrogate.fit_ensemble`) under variants of its size, each timed and
judged on designs it was not fitted to.

One real round with the robot's shipped policy labels `--designs` random designs of the full
range (paired scenarios, the plain mean of each objective); the ensemble is fitted to the
first `--designs - --held-out` of them, one objective at a time, for each fit seed, and
ranks the rest. Per variant and objective it prints the fit's seconds (mean over seeds) and
the Spearman correlation of the held-out designs' surrogate and real costs per seed, and
their mean relative error (the level, which the fit's level check on `--check-states` buffer
states sets; the ranking does not depend on it). The
real costs carry their own scenario noise (a relative standard error of about 7-10 % a
design at 32 x 250), which bounds every Spearman figure alike: compare variants with each
other on the same data, not with 1.

    # the earlier fit (5x128x200), today's (5x64x100) and three between
    python benchmarks/surrogate_fit_cost.py --json
    python benchmarks/surrogate_fit_cost.py --variants 5x128x200,5x64x100 --seeds 0,1,2,3,4
    python benchmarks/surrogate_fit_cost.py --variants 5x64x100 --samples 1024 --check-states 1024

A variant is MEMBERSxROWSxSTEPS: ensemble members, rows per member and Adam step, steps.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

import numpy as np

DEFAULT_VARIANTS = "5x128x200,3x128x200,5x64x200,5x128x100,5x64x100"


def parse_variants(text: str) -> list[tuple[int, int, int]]:
    """[(members, rows, steps)] from "5x128x200,3x64x100"; ValueError naming the bad item."""
    out = []
    for item in text.split(","):
        try:
            members, rows, steps = (int(x) for x in item.strip().lower().split("x"))
        except ValueError:
            raise ValueError(f"'{item}' is not MEMBERSxROWSxSTEPS (e.g. 5x128x200)") from None
        if min(members, rows, steps) < 1:
            raise ValueError(f"'{item}' needs whole numbers >= 1")
        out.append((members, rows, steps))
    return out


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--variants",
        default=DEFAULT_VARIANTS,
        help=f"MEMBERSxROWSxSTEPS, comma-separated (default {DEFAULT_VARIANTS})",
    )
    parser.add_argument("--objectives", default="torque,power,tracking")
    parser.add_argument(
        "--designs", type=int, default=48, help="designs of the real round (default 48)"
    )
    parser.add_argument(
        "--held-out", type=int, default=16, help="of them, judged and not fitted (default 16)"
    )
    parser.add_argument(
        "--agents", type=int, default=32, help="paired scenarios per design (default 32)"
    )
    parser.add_argument("--steps", type=int, default=250, help="steps per scenario (default 250)")
    parser.add_argument("--seeds", default="0,1,2", help="fit seeds (default 0,1,2)")
    parser.add_argument(
        "--samples", type=int, default=4096, help="buffer states per prediction (default 4096)"
    )
    parser.add_argument(
        "--check-states",
        type=int,
        default=None,
        help="buffer states of the fit's level check (default: the fit's own)",
    )
    parser.add_argument("--robot", default=None)
    parser.add_argument("--sim", default=None)
    parser.add_argument("--json", action="store_true", help="one JSON line last")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    variants, seeds = _checked(parser, args)

    from coadapt_core.learning.factory import make_backend
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    robot_name = args.robot or registry.default("robot")
    robot = registry.create("robot", robot_name)
    policy = robot.shipped_policy("flat")
    if policy is None:
        parser.error(f"--robot: '{robot_name}' ships no flat-ground policy")
    names = [o.strip() for o in args.objectives.split(",") if o.strip()]
    objectives = [registry.get("objective", o)() for o in names]
    backend = make_backend(
        robot, args.sim or registry.default("simulator"), objectives, checkpoint=str(policy)
    )
    space = robot.design_space()
    designs = space.sample(args.designs, rng=7)
    t0 = time.perf_counter()
    real = backend.real_fitness(designs, objectives, agents=args.agents, steps=args.steps, seed=0)
    real_seconds = time.perf_counter() - t0
    costs = np.asarray(real.costs, dtype=float)
    fit, held = slice(0, args.designs - args.held_out), slice(args.designs - args.held_out, None)
    results = {}
    for members, rows, steps in variants:
        backend.surrogate_members_count = members
        backend.surrogate_fit_options = {"batch": rows, "steps": steps}
        if args.check_states is not None:
            backend.surrogate_fit_options["check_states"] = args.check_states
        per = {
            name: _judge(
                backend,
                objective,
                designs,
                costs[:, j],
                real.buffer,
                fit,
                held,
                seeds,
                args.samples,
            )
            for j, (name, objective) in enumerate(zip(names, objectives, strict=True))
        }
        key = f"{members}x{rows}x{steps}"
        results[key] = per
        print(
            f"{key:>11}  "
            + "  ".join(
                f"{n}: {v['fit_seconds']:.1f} s, Spearman {v['spearman']}, rel. error "
                f"{v['mean_relative_error']}"
                for n, v in per.items()
            ),
            flush=True,
        )
    if args.json:
        print(
            json.dumps(
                {
                    "robot": robot_name,
                    "designs": args.designs,
                    "held_out": args.held_out,
                    "agents": args.agents,
                    "steps": args.steps,
                    "seeds": seeds,
                    "samples": args.samples,
                    "check_states": args.check_states,
                    "real_round_seconds": round(real_seconds, 1),
                    "variants": results,
                }
            )
        )
    return 0


def _checked(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> tuple[list[tuple[int, int, int]], list[int]]:
    """(the variants, the fit seeds); bad input is one line and exit 2 (`parser.error`)."""
    try:
        variants = parse_variants(args.variants)
    except ValueError as exc:
        parser.error(f"--variants: {exc}")  # one line, exit 2
    if args.check_states is not None and args.check_states < 1:
        parser.error("--check-states: needs a whole number >= 1")
    if not 2 <= args.held_out <= args.designs - 2:
        parser.error("--held-out: needs at least 2 held-out and 2 fitted designs")
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        parser.error(f"--seeds: '{args.seeds}' is not a comma-separated list of whole numbers")
    return variants, seeds


def _judge(
    backend: Any,
    objective: Any,
    designs: np.ndarray,
    costs: np.ndarray,
    buffer: Any,
    fit: slice,
    held: slice,
    seeds: list[int],
    samples: int,
) -> dict:
    """One objective's surrogate, fitted on the `fit` designs with each seed and judged on the
    held-out ones: Spearman, mean relative error and the mean fit time."""
    from scipy.stats import spearmanr

    rho, seconds, error = [], [], []
    for seed in seeds:
        t = time.perf_counter()
        backend.fit_surrogate(designs[fit], costs[fit, None], [objective], buffer, seed=seed)
        seconds.append(time.perf_counter() - t)
        predicted = backend.surrogate_fitness(
            designs[held], [objective], buffer, samples=samples, seed=seed
        )[:, 0]
        rho.append(round(float(spearmanr(predicted, costs[held])[0]), 3))
        relative = np.abs(predicted - costs[held]) / np.abs(costs[held])
        error.append(round(float(np.mean(relative)), 3))
    return {
        "spearman": rho,
        "mean_relative_error": error,
        "fit_seconds": float(f"{np.mean(seconds):.3g}"),  # three figures: a tiny fit is not 0.0
    }


if __name__ == "__main__":
    sys.exit(main())
