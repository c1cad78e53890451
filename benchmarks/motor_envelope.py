"""Why does a motor type win the torque objective? For one pair of leg scales, evaluates every
(hip motor, knee motor) combination of the mixed design space with the robot's shipped mixed
policy on the same paired scenarios, and prints per combination: the torque cost under the
cost rule and the plain mean, the fall rate, the walking gate's tracking ratio, and what the
torque-speed envelope did: the share of joint-steps whose commanded torque was clipped, the
mean |commanded| and |applied| torque, and the joints' peak and 99th-percentile speed against
their no-load speed (hip and knee joints separately).

    python benchmarks/motor_envelope.py --design 0.5,0.6 --json
    python benchmarks/motor_envelope.py --design 1.0,1.0 --blocks 2

The torque objective prices the torque the joints *receive* (after the envelope): a motor that
clips more lowers the cost by delivering less of what the policy asks for.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


class EnvelopeProbe:
    """Wraps the simulator module's `pd_torque`: records, per physics step, the commanded
    (unclipped) and applied torque and the joint speed against the no-load speed."""

    def __init__(self, module):
        self.module, self.original = module, module.pd_torque
        self.clipped: list[np.ndarray] = []  # [N, J] bool per physics step
        self.commanded: list[np.ndarray] = []
        self.applied: list[np.ndarray] = []
        self.speed_ratio: list[np.ndarray] = []

    def __enter__(self):
        def probe(
            q_target, q, dq, kp, kd, tau_max, dq_max, pd_factor=1.0, motor_strength=1.0, out=None
        ):
            def col(x):
                return x[:, None] if hasattr(x, "dim") and x.dim() == 1 else x

            commanded = (
                ((kp * (q_target - q) - kd * dq) * col(pd_factor) * col(motor_strength))
                .numpy()
                .copy()
            )
            ratio = (dq / dq_max).abs().numpy().copy()
            tau = self.original(
                q_target, q, dq, kp, kd, tau_max, dq_max, pd_factor, motor_strength, out=out
            )
            applied = tau.numpy()
            self.commanded.append(commanded)
            self.applied.append(applied.copy())
            self.clipped.append(np.abs(applied - commanded) > 1e-6 * (1.0 + np.abs(commanded)))
            self.speed_ratio.append(ratio)
            return tau

        self.module.pd_torque = probe
        return self

    def __exit__(self, *exc):
        self.module.pd_torque = self.original
        self.clipped, self.commanded, self.applied, self.speed_ratio = [], [], [], []

    def summary(self, rows: np.ndarray, joints: list[int]) -> dict[str, float]:
        clipped = np.stack(self.clipped)[:, rows][:, :, joints]
        com = np.abs(np.stack(self.commanded)[:, rows][:, :, joints])
        app = np.abs(np.stack(self.applied)[:, rows][:, :, joints])
        ratio = np.stack(self.speed_ratio)[:, rows][:, :, joints]
        return {
            "clipped_share": float(clipped.mean()),
            "commanded_abs_torque": float(com.mean()),
            "applied_abs_torque": float(app.mean()),
            "speed_over_no_load_p99": float(np.percentile(ratio, 99)),
            "speed_over_no_load_max": float(ratio.max()),
        }


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--design", default="0.5,0.6", help="thigh,shank scales (default 0.5,0.6)")
    p.add_argument("--robot", default="kuafu")
    p.add_argument("--sim", default="mujoco")
    p.add_argument("--terrain", default="flat")
    p.add_argument(
        "--blocks", type=int, default=1, help="blocks of 32 x 250 paired scenarios (default 1)"
    )
    p.add_argument("--json", action="store_true", help="one JSON line per motor combination")
    return p


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    from coadapt_core.costs import CostRule, compare_designs
    from coadapt_core.errors import CoadaptError
    from coadapt_core.scenarios.seeds import scenario_seed

    args = _parser().parse_args(argv)
    try:
        legs = [float(x) for x in args.design.split(",")]
        assert len(legs) == 2
    except (ValueError, AssertionError):
        print(f"error: --design must be two numbers t,s, got '{args.design}'", file=sys.stderr)
        return 2
    try:
        robot, sim_cls, objectives, backend = _backend(args)
    except CoadaptError as exc:
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    if backend is None:
        print(
            f"error: robot '{args.robot}' ships no mixed policy for terrain '{args.terrain}'",
            file=sys.stderr,
        )
        return 2
    space = robot.design_space(True)
    nominal = np.asarray(robot.nominal_design(True), dtype=float)
    types = [
        sorted({int(round(v)) for v in np.linspace(space.lower[i], space.upper[i], 8)})
        for i in range(2, space.dim)
    ]
    combos = list(itertools.product(*types))
    designs = np.array([[*legs, *c] for c in combos] + [nominal.tolist()])
    module = sys.modules[sim_cls.__module__]
    agents = 32
    names = robot.build(nominal).joint_names
    hips = [i for i, n in enumerate(names) if "hip" in n.lower()]
    knees = [i for i, n in enumerate(names) if "knee" in n.lower()]
    per, falls, ratios, probes = [], [], [], []
    for b in range(max(1, args.blocks)):
        with EnvelopeProbe(module) as probe:
            fit = backend.real_fitness(
                designs, objectives, agents=agents, steps=250, seed=scenario_seed(1000, b)
            )
            # the backend may step its environments in another order (rows): env of each row
            order = getattr(backend.trainer.eval_env.sim, "_env_of_row_t", None)
            env_of_row = np.arange(len(designs) * agents) if order is None else np.asarray(order)
            design_of_row = env_of_row // agents
            probes.append(
                {
                    i: {
                        "hip": probe.summary(np.flatnonzero(design_of_row == i), hips),
                        "knee": probe.summary(np.flatnonzero(design_of_row == i), knees),
                    }
                    for i in range(len(designs))
                }
            )
        per.append(fit.per_scenario)
        falls.append(fit.scenario_falls)
        ratios.append(fit.tracking_ratio)
    per, falls = np.concatenate(per, axis=1), np.concatenate(falls, axis=1)
    tracking_ratio = np.mean(ratios, axis=0)
    rule = CostRule()
    for i, design in enumerate(designs):
        comp = compare_designs(rule, objectives, per, falls, i, len(designs) - 1)
        row = _row(comp, design, float(tracking_ratio[i]), int(per.shape[1]), probes, i)
        print(json.dumps(row) if args.json else _row_text(row))
    backend.close()
    return 0


def _backend(args: argparse.Namespace) -> tuple:
    """(robot, simulator class, objectives, the learner's backend on the robot's shipped
    mixed policy for the terrain; None when it ships none)."""
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    robot, sim_cls, objectives = resolve_plugins(
        args.robot, args.sim, ["tracking", "power", "torque"]
    )
    checkpoint = shipped_checkpoint(robot, args.terrain, True)
    if checkpoint is None:
        return robot, sim_cls, objectives, None
    backend = make_backend(
        robot,
        sim_cls,
        objectives,
        terrain=args.terrain,
        design_space=robot.design_space(True),
        mixed=True,
        checkpoint=str(checkpoint),
        agents_per_design=32,
    )
    return robot, sim_cls, objectives, backend


def _row(
    comp: dict, design: np.ndarray, tracking_ratio: float, scenarios: int, probes: list, i: int
) -> dict:
    """Design i's row: its torque cost, falls and tracking (`compare_designs` against the
    nominal design) and the envelope probes' means over the blocks."""
    t = comp["objectives"]["torque"]
    row = {
        "design": design.tolist(),
        "torque_cost": t["cost"],
        "torque_cost_se": t["cost_se"],
        "torque_plain_mean": t["plain_mean"],
        "torque_plain_mean_se": t["plain_mean_se"],
        "tracking_plain_mean": comp["objectives"]["tracking"]["plain_mean"],
        "fall_rate": comp["fall_rate"],
        "fall_rate_se": comp["fall_rate_se"],
        "tracking_ratio": tracking_ratio,
        "scenarios": scenarios,
    }
    for part in ("hip", "knee"):
        keys = probes[0][i][part].keys()
        row[part] = {k: float(np.mean([pr[i][part][k] for pr in probes])) for k in keys}
    return row


def _row_text(row: dict) -> str:
    hip, knee = row["hip"], row["knee"]
    return (
        f"{row['design']}: torque {row['torque_cost']:.0f} +- "
        f"{row['torque_cost_se']:.0f} (plain {row['torque_plain_mean']:.0f}), "
        f"falls {100 * row['fall_rate']:.1f} %, tracking ratio "
        f"{row['tracking_ratio']:.2f}; clipped hip {100 * hip['clipped_share']:.1f} % "
        f"knee {100 * knee['clipped_share']:.1f} %; |tau| asked/applied knee "
        f"{knee['commanded_abs_torque']:.1f}/{knee['applied_abs_torque']:.1f} N m; "
        f"knee speed p99 {knee['speed_over_no_load_p99']:.2f} x no-load"
    )


if __name__ == "__main__":
    sys.exit(main())
