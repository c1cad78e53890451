"""How many legs per second the generic numeric leg IK solves, beside the analytic IKs of
Kuafu and Qilin timed on batches of the same size in the same run (their ceiling).

    python benchmarks/leg_ik.py [--legs 16384] [--repeats 5] [--threads 1]

Targets are reachable: the feet of each robot's standing pose with every leg joint turned by
up to 0.15 rad. Prints one JSON object: per robot the legs per second (median of the
repeats), the largest foot error (m), the rate when 1 % of the designs' targets are out of
reach (as a gait reference at speed makes them) and, for Kuafu and Qilin, the analytic IK's
rate and the generic one's share of it. The issue's floor is 100 000 legs per second on a
2-core machine.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FLOOR = 100_000


def _time(fn, repeats: int) -> float:
    fn()  # warm up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _generic(robot, design):
    """The generic IK of `robot` at `design`: its own for a spec robot, else one built from
    its model at that design (feet from the body holding each hip-pitch joint)."""
    import mujoco
    import numpy as np
    from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain

    built = getattr(robot, "_built", None)
    if built is not None:
        return built.kinematics
    model = robot.build(design)
    compiled = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    hips = [
        compiled.body(compiled.jnt_bodyid[compiled.joint(j).id]).name
        for j in model.joint_names
        if j.endswith(("hip_pitch", "_hip"))
    ]
    chain = build_chain(
        compiled,
        model.base_body,
        model.joint_names,
        list(zip(model.foot_bodies, hips, strict=True)),
        [],
        model.default_joint_pos,
        np.zeros(0),
    )
    return LegKinematics(chain)


def measure(name: str, legs: int, repeats: int) -> dict:
    import torch

    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", name)
    design = robot.nominal_design()
    kinematics = _generic(robot, design)
    n = max(1, legs // kinematics.chain.num_legs)
    designs = torch.tensor(design, dtype=torch.float64)[None].expand(n, -1).clone()
    g = torch.Generator().manual_seed(0)
    x = kinematics.leg_angles(kinematics.chain.standing.expand(n, -1))
    x = x + 0.15 * (2 * torch.rand(x.shape, generator=g, dtype=torch.float64) - 1)
    feet, _, _, _, _ = kinematics.forward(kinematics.scales(designs), x)
    hips = kinematics.standing(designs)[2]
    targets = feet - hips
    solved = n * kinematics.chain.num_legs
    seconds = _time(lambda: kinematics.inverse(designs, targets), repeats)
    q = kinematics.inverse(designs, targets)
    reached, _, _, _, _ = kinematics.forward(kinematics.scales(designs), kinematics.leg_angles(q))
    out = {
        "legs": solved,
        "legs_per_s": solved / seconds,
        "max_foot_error_m": float((reached - hips - targets).norm(dim=-1).max()),
        "joints_per_leg": int(kinematics.chain.joint_index.shape[1]),
    }
    # a gait reference at speed puts a few feet out of reach (about 1 % of a walking nezha's
    # designs at 1.25 m/s): they take every iteration, the others stop when they settle
    far = targets.clone()
    far[::100] *= 1.8
    out["legs_per_s_one_percent_out_of_reach"] = solved / _time(
        lambda: kinematics.inverse(designs, far), repeats
    )
    if getattr(robot, "_built", None) is None:  # a robot with its own analytic IK: the ceiling
        analytic = _time(lambda: robot.leg_inverse_kinematics(designs, targets), repeats)
        out["analytic_legs_per_s"] = solved / analytic
        out["share_of_analytic"] = analytic / seconds
    return out


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    import torch

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--legs", type=int, default=16384, help="legs per batch")
    p.add_argument("--repeats", type=int, default=5, help="timed batches (the median is kept)")
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--robots", default="kuafu,qilin,nezha", help="comma-separated robot names")
    args = p.parse_args(argv)
    if args.legs < 1 or args.repeats < 1 or args.threads < 1:
        print("error: --legs, --repeats and --threads must be positive", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    results = {name: measure(name, args.legs, args.repeats) for name in args.robots.split(",")}
    slowest = min(r["legs_per_s"] for r in results.values())
    print(
        json.dumps(
            {
                "threads": args.threads,
                "robots": results,
                "slowest_legs_per_s": slowest,
                "floor_legs_per_s": FLOOR,
                "meets_floor": slowest >= FLOOR,
            },
            indent=2,
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
