"""Where eq. 8's torque cost sits: its two factors (sum_i tau_i^2 and the tracking penalty
w_t) and each joint's tau^2, for designs against the nominal design on the common scenarios.

    python benchmarks/torque_split.py --design 0.51,0.54 --design 0.52,0.64 --blocks 4
    python benchmarks/torque_split.py --design 0.51,0.54 --checkpoint SHORT.pt \
        --nominal-checkpoint NOMINAL.pt --blocks 4 --json

P_tau = w_t sum_i tau_i^2 (eq. 8): a design can save torque and still lose part of the saving
to a worse tracking penalty. Each design runs under --checkpoint (default: the robot's shipped
policy for the terrain) and the nominal design under --nominal-checkpoint (default: the same
policy), so a design can also be judged under its own specialized policy. The scenarios are
the common set of benchmarks/common_scenarios.py (blocks of 32 x 250 from
`scenario_seed(1000, b)`), the same commands, pushes and randomization for every design, so
each improvement is paired by scenario. Per row: the capped rule's and the plain mean's
improvement with its paired standard error, for eq. 8, for sum tau^2 and w_t alone, and for
each joint's tau^2 (plain mean only, whose shares add up); and the fall-rate difference.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
    return 2


def _parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--design", action="append", default=[], help="thigh,shank (repeatable)")
    p.add_argument("--checkpoint", default=None, help="the designs' policy (default: shipped)")
    p.add_argument(
        "--nominal-checkpoint", default=None, help="the nominal design's policy (default: same)"
    )
    p.add_argument("--robot", default=None, help="robot (default: the default robot)")
    p.add_argument("--terrain", default="flat", help="terrain (default: flat)")
    p.add_argument("--blocks", type=int, default=4, help="blocks of 32 paired scenarios")
    p.add_argument("--json", action="store_true", help="one JSON line per design")
    return p.parse_args(argv)


def _split_objectives(joint_names: list[str]) -> list:
    """eq. 8's factors as objectives: each joint's tau^2, sum tau^2, w_t, and eq. 8 itself."""
    from coadapt_plugins.objectives.locomotion import TorqueObjective, tracking_penalty_weight

    from coadapt_core.objective import Objective

    class JointTorque(Objective):
        display_name = "tau^2 of one joint"

        def __init__(self, index: int):
            self.index = index
            self.name = f"tau2_{joint_names[index]}"
            super().__init__()

        def step_cost(self, step):
            return step.joint_torque[:, self.index] ** 2  # [N]

    class TorqueSquares(Objective):
        name = "tau2_sum"
        display_name = "sum tau^2 (eq. 8 without w_t)"

        def step_cost(self, step):
            return (step.joint_torque**2).sum(dim=-1)  # [N]

    class TrackingPenalty(Objective):
        name = "w_t"
        display_name = "w_t = exp(e_v^2 + e_w^2), capped"

        def step_cost(self, step):
            return tracking_penalty_weight(step)  # [N]

    joints = [JointTorque(j) for j in range(len(joint_names))]
    return [*joints, TorqueSquares(), TrackingPenalty(), TorqueObjective()]


def _costs(robot, sim_cls, objectives, checkpoint, designs, args) -> tuple:
    """[D, A, M] per-scenario costs and [D, A] falls of the designs under one policy."""
    from coadapt_core.learning.factory import make_backend
    from coadapt_core.scenarios.seeds import scenario_seed

    backend = make_backend(
        robot,
        sim_cls,
        objectives,
        terrain=args.terrain,
        design_space=robot.design_space(False),
        mixed=False,
        checkpoint=str(checkpoint),
        agents_per_design=32,
    )
    fits = [
        backend.real_fitness(designs, objectives, agents=32, steps=250, seed=scenario_seed(1000, b))
        for b in range(args.blocks)
    ]
    backend.close()
    per = np.concatenate([f.per_scenario for f in fits], axis=1)
    return per, np.concatenate([f.scenario_falls for f in fits], axis=1)


def _row(objectives, per, falls, design) -> dict:
    """One design (row 0) against nominal (row 1), paired by scenario."""
    from coadapt_core.costs import CostRule, compare_designs

    out: dict = {"design": design, "scenarios": int(per.shape[1])}
    for rule in ("capped", "mean"):
        comp = compare_designs(CostRule(rule, 3.0), objectives, per, falls, 0, 1)
        names = [o.name for o in objectives]
        if rule == "capped":
            names = ["tau2_sum", "w_t", "torque"]
        for name in names:
            v = comp["objectives"][name]
            # w_t's own improvement is 1 - w/w0 (the Objective default); negative: dearer
            out[f"{name}_{rule}"] = [v["improvement"], v["improvement_se"]]
        out["fall_rate_difference"] = [
            comp["fall_rate_difference"],
            comp["fall_rate_difference_se"],
        ]
    nominal_sum = per[1, :, [o.name for o in objectives].index("tau2_sum")].mean()
    out["nominal_shares"] = {
        o.name: float(per[1, :, k].mean() / nominal_sum)
        for k, o in enumerate(objectives)
        if o.name.startswith("tau2_") and o.name != "tau2_sum"
    }
    return out


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    args = _parse(argv)
    if args.blocks < 1:
        return _fail(f"--blocks must be >= 1, got {args.blocks}")
    try:
        designs = [[float(x) for x in text.split(",")] for text in args.design]
    except ValueError:
        return _fail("--design takes comma-separated numbers such as 0.51,0.54")
    if not designs or any(len(d) != 2 for d in designs):
        return _fail("give at least one --design thigh,shank (two numbers)")

    from coadapt_core.errors import CoadaptError
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import resolve_plugins
    from coadapt_core.plugins import default_plugin, get_registry

    try:
        robot = get_registry().create("robot", args.robot or default_plugin("robot"))
        checkpoint = args.checkpoint or shipped_checkpoint(robot, args.terrain, False)
        if checkpoint is None:
            return _fail(f"no shipped policy for terrain '{args.terrain}': pass --checkpoint")
        nominal_checkpoint = args.nominal_checkpoint or checkpoint
        nominal = [float(x) for x in robot.nominal_design(False)]
        joint_names = list(robot.build(np.array(nominal)).joint_names)
        robot, sim_cls, objectives = resolve_plugins(
            robot, default_plugin("simulator"), _split_objectives(joint_names)
        )
        per, falls = _costs(robot, sim_cls, objectives, checkpoint, np.array(designs), args)
        nominal_per, nominal_falls = _costs(
            robot, sim_cls, objectives, nominal_checkpoint, np.array([nominal]), args
        )
    except CoadaptError as exc:
        return _fail(" ".join(str(exc).split()))
    for i, design in enumerate(designs):
        row = _row(
            objectives,
            np.stack([per[i], nominal_per[0]]),
            np.stack([falls[i], nominal_falls[0]]),
            design,
        )
        if args.json:
            print(json.dumps(row), flush=True)
            continue

        def pct(key: str, row: dict = row) -> str:
            return f"{100 * row[key][0]:+.1f} +- {100 * row[key][1]:.1f} %"

        print(
            f"{design}: eq. 8 {pct('torque_capped')} (plain {pct('torque_mean')}); "
            f"sum tau^2 {pct('tau2_sum_capped')} (plain {pct('tau2_sum_mean')}); "
            f"w_t {pct('w_t_capped')} (plain {pct('w_t_mean')}); "
            f"fall-rate difference {pct('fall_rate_difference')}",
            flush=True,
        )
        for name, share in row["nominal_shares"].items():
            print(f"    {name}: {100 * share:.0f} % of nominal sum tau^2, {pct(name + '_mean')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
