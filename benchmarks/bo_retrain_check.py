"""Does training a BO run's policies again reproduce the run? For a run folder of a method
without a shared policy (`bo-specialized`), the best and nominal designs' policies are trained
again as the run trained them (`coadapt_core.experiments.own_policies`: the run's settings,
starting policy checked by SHA-256, seeds from the run's seed and the design's value) and
evaluated on the run's own scenario set: the best design's cost under the run's cost rule
(with the run's recorded reference level) beside the cost the run recorded, and the reference
level from the nominal design's scenarios (its median scenario cost under the capped rule)
beside the recorded one.

    python benchmarks/bo_retrain_check.py runs/<run id> --json

Runs made before the BO backend passed its per-scenario falls on scored without them; the
check applies the rule as the run did.
About a minute per policy at the quick preset on a 2-core machine.
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
    import yaml

    from coadapt_core.coadapt.config_loading import config_from_dict
    from coadapt_core.coadapt.loop import seed_at
    from coadapt_core.coadapt.search import make_objectives
    from coadapt_core.coadapt.specialized import SpecializedPolicyBackend
    from coadapt_core.costs import CostRule
    from coadapt_core.errors import CoadaptError
    from coadapt_core.experiments.own_policies import run_learner, shares_policy
    from coadapt_core.scenarios.seeds import scenario_seed

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", help="a run folder (config.yaml, summary.json, evaluations.jsonl)")
    p.add_argument("--json", action="store_true", help="one JSON line per design")
    args = p.parse_args(argv)
    folder = Path(args.run)
    try:
        cfg = yaml.safe_load((folder / "config.yaml").read_text())
        summary = json.loads((folder / "summary.json").read_text())
        evals = [
            json.loads(line)
            for line in (folder / "evaluations.jsonl").read_text().splitlines()
            if line.strip()
        ]
    except (OSError, ValueError, yaml.YAMLError) as exc:
        print(
            f"error: run: '{folder}' is not a finished run folder ({type(exc).__name__})",
            file=sys.stderr,
        )
        return 2
    run = {"id": folder.name, "config": cfg, "summary": summary, "method": cfg.get("method")}
    if shares_policy(run):
        print(
            f"error: run: '{folder}' shares one policy between designs; "
            "only runs without one are checked",
            file=sys.stderr,
        )
        return 2
    try:
        config = config_from_dict(cfg)
        objectives = make_objectives(config)
        backend = SpecializedPolicyBackend(
            run_learner(config, run),
            train_steps=config.specialized_train_steps,
            seed=seed_at(config.seed, 0),
            keep=1,
        )
    except CoadaptError as exc:
        print(f"error: run: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    rule, first = CostRule(config.cost_rule, config.cost_cap), objectives[0].name
    ref = np.asarray(summary["cost_reference"], dtype=float) if rule.needs_reference else None
    # runs since the BO backend kept its policies (summary key own_policies) scored falls too
    with_falls = "own_policies" in summary
    best_cost = next(
        (
            e["costs"][first]
            for e in evals
            if e["kind"] == "real" and e["design"] == summary["best_design"]
        ),
        None,
    )
    for role, design in (("best", summary["best_design"]), ("nominal", summary["nominal_design"])):
        fit = backend.real_fitness(
            np.asarray([design], dtype=float),
            objectives,
            agents=config.evaluation_agents,
            steps=config.eval_steps,
            seed=scenario_seed(config.seed),
        )
        falls = fit.scenario_falls if with_falls else None
        if (
            role == "nominal" and ref is not None
        ):  # the nominal design's scenarios set the reference level
            what, recorded = "reference level", float(ref[0])
            again = float(
                rule.reference(fit.per_scenario[0], None if falls is None else falls[0])[0]
            )
        else:  # the cost its one real evaluation recorded (a nominal design without a
            # reference: its final cost)
            what, recorded = "cost", best_cost if role == "best" else summary.get("nominal_cost")
            again = float(rule.cost(fit.per_scenario, falls, ref)[0, 0])
        out = {
            "run": folder.name,
            "design": role,
            "value": design,
            "compared": what,
            "recorded": recorded,
            "trained_again": again,
            "equal": recorded == again,
            "difference": None if recorded is None else again - recorded,
            "fall_rate": float(np.mean(fit.scenario_falls)),
        }
        verdict = "equal" if out["equal"] else "differs"
        print(
            json.dumps(out)
            if args.json
            else f"{role} {design}: {what} recorded {recorded!r}, trained again {again!r} "
            f"({verdict})"
        )
    backend.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
