"""`coadapt verify`'s result (`coadapt_core.coadapt.verify`): from the pooled paired
blocks, per verified design the improvement with specialists and with the universal policy
(each with its paired SE, the plain mean and the fall-rate difference beside it), their
difference with one bootstrap SE over the scenarios of all four rows, the verdict and its
line; and the verifications a run folder holds (`read_verifications`, `specialist_policy`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from coadapt_core.coadapt.final_check import SIGNIFICANCE_RATIO
from coadapt_core.coadapt.verify_plan import CHANGE_RATIO, RESULT, VERIFY_DIR, verify_key
from coadapt_core.costs import CostRule, _resamples, compare_designs, fall_statistics, falls_more
from coadapt_core.objective import Objective
from coadapt_core.statefile import read_json

if TYPE_CHECKING:
    from coadapt_core.coadapt.verify_plan import Plan


def _pooled(state: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    per = np.concatenate([np.asarray(b["per_scenario"], dtype=float) for b in state["blocks"]], 1)
    falls = np.concatenate([np.asarray(b["falls"], dtype=bool) for b in state["blocks"]], 1)
    return per, falls


def _side(comp: dict[str, Any], name: str) -> dict[str, Any]:
    o = comp["objectives"][name]
    return {
        "improvement": o["improvement"],
        "improvement_se": _finite(o["improvement_se"]),
        "improvement_plain": o["improvement_plain"],
        "improvement_plain_se": _finite(o["improvement_plain_se"]),
        "cost": o["cost"],
        "nominal_cost": o["nominal_cost"],
        "fall_rate": comp.get("fall_rate"),
        "nominal_fall_rate": comp.get("reference_fall_rate"),
        "fall_rate_difference": comp.get("fall_rate_difference"),
        "fall_rate_difference_se": _finite(comp.get("fall_rate_difference_se")),
        "improvements": {k: v["improvement"] for k, v in comp["objectives"].items()},
        "improvements_se": {k: _finite(v["improvement_se"]) for k, v in comp["objectives"].items()},
    }


def _finite(x: Any) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def difference_se(
    rule: CostRule,
    objective: Objective,
    column: int,
    per: np.ndarray,
    falls: np.ndarray,
    rows: tuple[int, int, int, int],
) -> tuple[float, float]:
    """(improvement with specialists - improvement with the universal policy, its standard
    error): `rows` = (specialist at the design, specialist at the nominal design, universal
    at the design, universal at the nominal design) of `per` [R, A, M]; each policy's scenario
    values under `rule` with its own nominal design as the reference; the bootstrap resamples
    the scenarios of all four rows together."""
    values = []
    for d, n in (rows[:2], rows[2:]):
        pair = per[[d, n]]
        pair_falls = falls[[d, n]]
        ref = rule.reference(pair[1], pair_falls[1]) if rule.needs_reference else None
        values.append(rule.scenario_values(pair, pair_falls, ref)[:, :, column : column + 1])

    def improvements(idx: np.ndarray | slice) -> float:
        out = []
        for v in values:
            cost = rule.aggregate(v[:, idx])[:, 0]
            out.append(float(objective.improvement(float(cost[0]), float(cost[1]))))
        return out[0] - out[1]

    diff = improvements(slice(None))
    a = per.shape[1]
    if a < 2:
        return diff, float("nan")
    boot = np.asarray([improvements(r) for r in _resamples(a)])
    boot = boot[np.isfinite(boot)]
    return diff, float(boot.std(ddof=1)) if len(boot) > 1 else float("nan")


def verdict(
    universal: float,
    universal_se: float | None,
    specialist: float,
    specialist_se: float | None,
    diff: float,
    diff_se: float | None,
) -> str:
    """`holds` (same sign, both at least SIGNIFICANCE_RATIO standard errors, their difference
    within CHANGE_RATIO standard errors), `grows` or `shrinks` (the same, the difference
    beyond that), or `does not hold`."""

    def significant(x: float, se: float | None) -> bool:
        return se is not None and x != 0 and abs(x) >= SIGNIFICANCE_RATIO * se

    if not (
        significant(universal, universal_se)
        and significant(specialist, specialist_se)
        and np.sign(universal) == np.sign(specialist)
    ):
        return "does not hold"
    if diff_se is not None and abs(diff) > CHANGE_RATIO * diff_se:
        return "grows" if abs(specialist) > abs(universal) else "shrinks"
    return "holds"


def _pct(x: float | None, se: float | None = None) -> str:
    if x is None:
        return "-"
    text = f"{100 * x:+.1f}"
    return f"{text} ± {100 * se:.1f} %" if se is not None else f"{text} %"


def verdict_line(entry: dict[str, Any]) -> str:
    """One line: the verdict, both improvements and their difference, and a specialist that
    falls more than the universal policy said so."""
    u, s = entry["universal"], entry["specialist"]
    diff = f"difference {_pct(entry['difference'], entry['difference_se'])[:-2]} points"
    line = (
        f"{entry['role']}: {entry['verdict']}: {_pct(s['improvement'], s['improvement_se'])} with "
        f"specialists, {_pct(u['improvement'], u['improvement_se'])} with the universal policy "
        f"({diff})"
    )
    if entry["verdict"] == "does not hold":
        line += "; " + _why_not(u, s)
    for note in entry.get("falls_more") or []:
        line += f"; {note}"
    return line


def _why_not(u: dict[str, Any], s: dict[str, Any]) -> str:
    def weak(side: dict[str, Any]) -> bool:  # not significant, as `verdict` reads it
        x, se = side["improvement"], side["improvement_se"]
        return se is None or x == 0 or abs(x) < SIGNIFICANCE_RATIO * se

    if weak(u) and weak(s):
        return f"neither improvement is {SIGNIFICANCE_RATIO:g} standard errors"
    if weak(u):
        return f"the universal policy's improvement is under {SIGNIFICANCE_RATIO:g} standard errors"
    if weak(s):
        return f"the improvement with specialists is under {SIGNIFICANCE_RATIO:g} standard errors"
    return "the specialists reverse its sign"


def _entry(plan: Plan, per: np.ndarray, falls: np.ndarray, i: int) -> dict[str, Any]:
    """Verified design i (rows: the n specialists, nominal last, then the n universal ones)
    against the nominal design, with both policies, their difference and the verdict."""
    n, role, first = len(plan.roles), plan.roles[i], plan.objectives[0]
    spec = compare_designs(plan.rule, plan.objectives, per[:n], falls[:n], i, n - 1)
    uni = compare_designs(plan.rule, plan.objectives, per[n:], falls[n:], i, n - 1)
    diff, diff_se = difference_se(plan.rule, first, 0, per, falls, (i, n - 1, n + i, 2 * n - 1))
    s, u = _side(spec, first.name), _side(uni, first.name)
    entry = {
        "role": role,
        "design": [float(x) for x in plan.designs[role]],
        "objective": first.name,
        "specialist": s,
        "universal": u,
        "difference": diff,
        "difference_se": _finite(diff_se),
        "verdict": verdict(
            u["improvement"],
            u["improvement_se"],
            s["improvement"],
            s["improvement_se"],
            diff,
            _finite(diff_se),
        ),
    }
    tolerance = float(getattr(plan.config, "fall_tolerance", 0.01))
    notes = []
    for label, d, r in ((role, i, n + i), ("nominal", n - 1, 2 * n - 1)):
        st = fall_statistics(falls.astype(float), d, r)
        if falls_more(st["fall_rate_difference"], st["fall_rate_difference_se"], tolerance):
            notes.append(
                f"the {label} design's specialist falls more than the universal policy "
                f"({100 * st['fall_rate']:.1f} % of scenarios against "
                f"{100 * st['reference_fall_rate']:.1f} %)"
            )
    entry["falls_more"] = notes
    entry["line"] = verdict_line(entry)
    return entry


def _costs(plan: Plan, per: np.ndarray, falls: np.ndarray) -> dict[str, Any]:
    """Each policy's cost at every verified design and the nominal one, under its own rule."""
    rule, n, names = plan.rule, len(plan.roles), [o.name for o in plan.objectives]
    out = {}
    for label, offset in (("specialist", 0), ("universal", n)):
        part, pf = per[offset : offset + n], falls[offset : offset + n]
        ref = rule.reference(part[-1], pf[-1]) if rule.needs_reference else None
        c = rule.cost(part, pf, ref)
        out[label] = {
            role: dict(zip(names, map(float, c[i]), strict=True))
            for i, role in enumerate(plan.roles)
        }
    return out


def result_of(plan: Plan, state: dict[str, Any]) -> dict[str, Any]:
    """The verification's result from its pooled blocks (see the module docstring)."""
    per, falls = _pooled(state)
    specialists = {
        role: {
            "design": [float(x) for x in plan.designs[role]],
            "checkpoint": rec.get("checkpoint"),
            "interactions": int(rec["done"]),
            "seconds": float(rec["seconds"]),
            "start": rec.get("start"),
            "rewards": list(rec.get("rewards") or []),
            **({"same_as": rec["same_as"]} if rec.get("same_as") else {}),
        }
        for role, rec in state["specialists"].items()
    }
    return {
        "run_id": plan.run_id,
        "key": verify_key(plan.budget, plan.seed),
        "budget": plan.budget,
        "seed": plan.seed,
        "universal_policy": str(plan.universal),
        "cost_rule": plan.rule.rule,
        "objectives": [o.name for o in plan.objectives],
        "blocks": len(state["blocks"]),
        "scenarios": int(per.shape[1]),
        "evaluation_interactions": int(sum(b["interactions"] for b in state["blocks"])),
        "training_interactions": int(
            sum(r["interactions"] for r in specialists.values() if not r.get("same_as"))
        ),
        "specialists": specialists,
        "costs": _costs(plan, per, falls),
        "designs": [_entry(plan, per, falls, i) for i in range(len(plan.roles) - 1)],
        "run_improvement": plan.summary.get("improvement"),
        "run_improvement_se": plan.summary.get("improvement_se"),
    }


def read_verifications(run_dir: str | Path) -> list[dict[str, Any]]:
    """The finished verifications of a run folder, by budget then seed."""
    out = []
    base = Path(run_dir) / VERIFY_DIR
    if not base.is_dir():
        return out
    for path in sorted(base.glob(f"*/{RESULT}")):
        data = read_json(path, what="verification")
        if isinstance(data, dict) and data.get("designs"):
            out.append(data)
    return sorted(out, key=lambda r: (int(r.get("budget") or 0), int(r.get("seed") or 0)))


def specialist_policy(
    run_dir: str | Path, role: str = "best"
) -> tuple[Path, dict[str, Any]] | None:
    """(file, verification) of the `role` design's specialist of the run's verification with
    the largest budget; None when the run has none."""
    for result in reversed(read_verifications(run_dir)):
        spec = (result.get("specialists") or {}).get(role)
        if spec and spec.get("checkpoint"):
            path = Path(run_dir) / VERIFY_DIR / result["key"] / spec["checkpoint"]
            if path.is_file():
                return path, result
    return None
