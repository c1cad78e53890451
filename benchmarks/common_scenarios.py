"""Re-evaluate designs (the best designs of several runs, or designs given by hand) and the
nominal design together, with one policy (default: the robot's shipped policy for the terrain),
on one common set of paired scenarios, so their costs and improvements can be compared
directly, each with its standard error, under the cost rule and under the paper's plain mean.

    python benchmarks/common_scenarios.py RUN_A RUN_B --blocks 8 --json
    python benchmarks/common_scenarios.py --design 0.5,0.66 --design 1.08,1.43 --objectives torque
    python benchmarks/common_scenarios.py RUN_A RUN_B --policy run --blocks 8 --json

With `--policy run` each run's best design is judged with the policy the run handed back (its
last checkpoint, `checkpoints/backend-outer<N>.pt`), paired with the nominal design under that
same policy: one nominal row per run, labelled "nominal (policy of RUN)".

Runs are run folders or run ids (folders under --runs-dir) holding a summary.json. The
scenarios are blocks of 32 x 250 (the quick preset's size) drawn from `scenario_seed(1000, b)`,
a set no run with a small seed uses. One JSON line per design (`--json`), the nominal design
last: per objective `cost`, `cost_se`, `plain_mean`, `plain_mean_se` and, against nominal
(paired), `improvement`, `improvement_se`, `improvement_plain`, `improvement_plain_se`; and
`fall_rate`, `fall_rate_se`, `fall_rate_difference`, `fall_rate_difference_se`.
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


class _Refused(Exception):
    """Bad input, said in one line (exit 2)."""


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    args = _parser().parse_args(argv)
    if args.blocks < 1 or args.agents < 2 or args.steps < 1:
        return _fail("--blocks must be >= 1, --agents >= 2, --steps >= 1")
    if not args.cost_cap > 1:
        return _fail(f"--cost-cap must be > 1, got {args.cost_cap}")
    from coadapt_core.errors import CoadaptError

    try:
        summaries = _summaries(args)
        for row in _evaluate(args, summaries):
            _print_row(row, as_json=args.json)
    except _Refused as exc:
        return _fail(str(exc))
    except CoadaptError as exc:
        return _fail(" ".join(str(exc).split()))
    return 0


def _parser() -> argparse.ArgumentParser:
    from coadapt_core.costs import COST_RULES

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="*", help="run folders or run ids (each with a summary.json)")
    p.add_argument(
        "--design",
        action="append",
        default=[],
        help="a design as comma-separated values (repeatable)",
    )
    p.add_argument("--runs-dir", default="runs", help="where run ids are looked up (default: runs)")
    p.add_argument(
        "--blocks", type=int, default=2, help="blocks of 32 paired scenarios (default 2)"
    )
    p.add_argument("--agents", type=int, default=32, help="scenarios per block (default 32)")
    p.add_argument("--steps", type=int, default=250, help="policy steps per scenario (default 250)")
    p.add_argument(
        "--robot", default=None, help="robot (default: the runs' robot, else the default robot)"
    )
    p.add_argument("--sim", default=None, help="simulator (default: the default simulator)")
    p.add_argument(
        "--terrain", default=None, help="terrain (default: the runs' terrain, else flat)"
    )
    p.add_argument(
        "--objectives",
        default=None,
        help="comma list (default: every objective the runs optimised)",
    )
    p.add_argument(
        "--checkpoint",
        default=None,
        help="policy (default: the robot's shipped policy for the terrain)",
    )
    p.add_argument(
        "--policy",
        choices=("shipped", "run"),
        default="shipped",
        help="shipped: one policy for every design (--checkpoint, else the shipped one); "
        "run: each run's own final policy, with nominal evaluated under each",
    )
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
    p.add_argument("--json", action="store_true", help="one JSON line per design")
    return p


def _summaries(args: argparse.Namespace) -> list[dict]:
    """The runs' summaries (label, folder) and the hand-given designs, in the order given."""
    summaries: list[dict] = []
    for name in args.runs:
        folder = Path(name) if Path(name).is_dir() else Path(args.runs_dir) / name
        path = folder / "summary.json"
        if not path.is_file():
            raise _Refused(f"run '{name}' has no summary.json (looked in {folder})")
        summary = json.loads(path.read_text())
        if "best_design" not in summary:
            raise _Refused(f"run '{name}' did not finish (its summary has no best_design)")
        summaries.append({**summary, "label": summary.get("run_id", name), "folder": folder})
    for text in args.design:
        try:
            design = [float(x) for x in text.split(",")]
        except ValueError:
            raise _Refused(f"--design '{text}' is not comma-separated numbers") from None
        summaries.append({"best_design": design, "label": f"design {text}"})
    if not summaries:
        raise _Refused("give run folders / ids or at least one --design t,s")

    return summaries


def _setting(args: argparse.Namespace, summaries: list[dict]) -> dict:
    """Robot, simulator, objectives, terrain, design space and the policy groups: each
    group's members, its policy and the nominal design's label."""
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import resolve_plugins
    from coadapt_core.plugins import default_plugin, get_registry

    config: dict = {}
    folders = [
        s["folder"] for s in summaries if "folder" in s and (s["folder"] / "config.yaml").is_file()
    ]
    if folders:
        import yaml

        config = yaml.safe_load((folders[0] / "config.yaml").read_text()) or {}
    robot_name = args.robot or config.get("robot") or default_plugin("robot")
    terrain = args.terrain or summaries[0].get("terrain") or config.get("terrain") or "flat"
    robot = get_registry().create("robot", robot_name)
    dims = {len(s["best_design"]) for s in summaries}
    if len(dims) != 1:
        raise _Refused(
            f"designs of different lengths {sorted(dims)}: compare one design space at a time"
        )
    dim = dims.pop()
    mixed = dim != robot.design_space(False).dim
    space = robot.design_space(mixed)
    if space.dim != dim:
        raise _Refused(
            f"designs have {dim} values; robot '{robot_name}' has "
            f"{robot.design_space(False).dim} "
            f"(continuous) or {robot.design_space(True).dim} (mixed)"
        )
    nominal = np.asarray(robot.nominal_design(mixed), dtype=float)
    checkpoint = args.checkpoint or shipped_checkpoint(robot, terrain, mixed)
    if checkpoint is None:
        raise _Refused(
            f"robot '{robot_name}' ships no policy for terrain '{terrain}'; pass --checkpoint"
        )
    # default: every objective any of the runs optimised (each design is scored on all of them)
    names = (
        [o.strip() for o in args.objectives.split(",") if o.strip()]
        if args.objectives
        else list(dict.fromkeys(k for s in summaries for k in (s.get("best_costs") or {})))
        or ["tracking", "power", "torque"]
    )
    robot, sim_cls, objectives = resolve_plugins(
        robot, args.sim or default_plugin("simulator"), names
    )
    if args.policy == "run":
        if any("folder" not in s for s in summaries):
            raise _Refused(
                "--policy run judges runs with their own policies: give run folders or ids, "
                "not --design"
            )
        groups = [
            ([s], _run_policy(s["folder"]), f"nominal (policy of {s['label']})") for s in summaries
        ]
    else:
        groups = [(summaries, Path(str(checkpoint)), "nominal")]
    return {
        "robot": robot,
        "sim_cls": sim_cls,
        "objectives": objectives,
        "terrain": terrain,
        "space": space,
        "mixed": mixed,
        "nominal": nominal,
        "groups": groups,
    }


def _evaluate(args: argparse.Namespace, summaries: list[dict]):
    """Each design's row, group by group, on the common scenario blocks."""
    from coadapt_core.costs import CostRule
    from coadapt_core.learning.factory import make_backend
    from coadapt_core.scenarios.seeds import scenario_seed

    s = _setting(args, summaries)
    robot, sim_cls, objectives, terrain = s["robot"], s["sim_cls"], s["objectives"], s["terrain"]
    space, mixed, nominal, groups = s["space"], s["mixed"], s["nominal"], s["groups"]
    rule = CostRule(args.cost_rule, args.cost_cap)
    for members, policy, nominal_label in groups:
        backend = make_backend(
            robot,
            sim_cls,
            objectives,
            terrain=terrain,
            design_space=space,
            mixed=mixed,
            checkpoint=str(policy),
            agents_per_design=args.agents,
        )
        designs = np.array([s["best_design"] for s in members] + [nominal.tolist()], dtype=float)
        fits = [
            backend.real_fitness(
                designs,
                objectives,
                agents=args.agents,
                steps=args.steps,
                seed=scenario_seed(1000, b),
            )
            for b in range(args.blocks)
        ]
        backend.close()
        labelled = [*members, {"label": nominal_label, "best_design": nominal.tolist()}]
        yield from _rows(fits, designs, labelled, objectives, rule, terrain, policy.name)


def _run_policy(folder: Path) -> Path:
    """The last policy a run saved (`checkpoints.jsonl`'s highest outer iteration), looked up
    by file name inside the run's own checkpoints/ folder (a recorded path is never followed)."""
    from coadapt_core.errors import UserError
    from coadapt_core.validation import inside

    rows = (
        [
            json.loads(line)
            for line in (folder / "checkpoints.jsonl").read_text().splitlines()
            if line.strip()
        ]
        if (folder / "checkpoints.jsonl").is_file()
        else []
    )
    rows = [
        r
        for r in rows
        if isinstance(r, dict)
        and isinstance(r.get("outer"), int)
        and isinstance(r.get("path"), str)
    ]
    if not rows:
        raise UserError(
            f"run folder {folder} records no checkpoint (checkpoints.jsonl)", field="policy"
        )
    path = inside(
        folder / "checkpoints",
        Path(max(rows, key=lambda r: r["outer"])["path"]).name,
        field="policy",
    )
    if not path.is_file():
        raise UserError(f"run folder {folder} lacks its checkpoint {path.name}", field="policy")
    return path


def _rows(fits, designs, labelled, objectives, rule, terrain: str, policy: str):
    """One row per design of a group (its nominal design last), paired against that nominal."""
    from coadapt_core.costs import compare_designs

    per = np.concatenate([f.per_scenario for f in fits], axis=1)  # [D, A, M]
    falls = np.concatenate([f.scenario_falls for f in fits], axis=1)  # [D, A]
    nominal_row = len(designs) - 1
    for i, s in enumerate(labelled):
        comp = compare_designs(rule, objectives, per, falls, i, nominal_row)
        row = {
            "label": s["label"],
            "run_seed": s.get("seed"),
            "design": [round(float(x), 3) for x in designs[i]],
            "scenarios": int(per.shape[1]),
            "cost_rule": rule.rule,
            "terrain": terrain,
            "policy": policy,
        }
        for name, v in comp["objectives"].items():
            entry = {k: v[k] for k in ("cost", "cost_se", "plain_mean", "plain_mean_se")}
            if i != nominal_row:
                entry.update(
                    {
                        k: v[k]
                        for k in (
                            "improvement",
                            "improvement_se",
                            "improvement_plain",
                            "improvement_plain_se",
                        )
                    }
                )
            row[name] = entry
        row["fall_rate"], row["fall_rate_se"] = comp["fall_rate"], comp["fall_rate_se"]
        if i != nominal_row:
            row["fall_rate_difference"] = comp["fall_rate_difference"]
            row["fall_rate_difference_se"] = comp["fall_rate_difference_se"]
        row["_objectives"] = list(comp["objectives"])
        yield row


def _print_row(row: dict, *, as_json: bool) -> None:
    names = row.pop("_objectives")
    if as_json:
        print(json.dumps(row), flush=True)
        return
    parts = [
        f"{n} {e['cost']:.4g} +- {e['cost_se']:.2g} (plain {e['plain_mean']:.4g} +- "
        f"{e['plain_mean_se']:.2g})"
        + (
            f" improvement {100 * e['improvement']:+.1f} +- {100 * e['improvement_se']:.1f} % "
            f"(plain {100 * e['improvement_plain']:+.1f} +- {100 * e['improvement_plain_se']:.1f} "
            "%)"
            if "improvement" in e
            else ""
        )
        for n, e in ((n, row[n]) for n in names)
    ]
    print(
        f"{row['label']} {row['design']}: "
        + "; ".join(parts)
        + f"; fall rate {100 * row['fall_rate']:.1f} +- {100 * row['fall_rate_se']:.1f} %",
        flush=True,
    )


if __name__ == "__main__":
    sys.exit(main())
