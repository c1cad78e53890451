"""The cost of a design over its scenarios, and its standard errors: the cost rules
(`CostRule`: capped, plain mean, trimmed), bootstrap standard errors resampling the
scenarios jointly for paired designs, improvements and fall-rate differences between two
designs (`compare_designs`). Every fitness, improvement and comparison a run reports comes
from here; the loop's protocols are `coadapt_core.fitness`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: the cost rules a run can ask for (`cost_rule`; docs/coadaptation.md, "How a fall enters the
#: fitness"): `capped` (default) scores every design on the same scenarios by the same rule,
#: each scenario's cost at most `cap` times the nominal design's median scenario and a fall
#: costing exactly that cap; `mean` is the paper's plain mean (eq. 4); `trimmed` is the rule
#: before (each design's costliest quarter dropped separately), kept to compare against.
COST_RULES: tuple[str, ...] = ("capped", "mean", "trimmed")
#: share of a design's costliest scenarios the `trimmed` rule leaves out (an upper-trimmed mean)
TRIM_SHARE = 0.25
#: bootstrap resamples behind every standard error (scenarios resampled jointly for paired designs)
BOOTSTRAP = 400


def robust_cost(per_scenario: np.ndarray) -> np.ndarray:
    """[K, M] cost of each design from its per-scenario costs [K, A, M]: the mean over its
    A - floor(TRIM_SHARE * A) cheapest scenarios (the `trimmed` rule's upper-trimmed mean)."""
    x = np.sort(np.asarray(per_scenario, dtype=float), axis=1)
    keep = x.shape[1] - int(TRIM_SHARE * x.shape[1])
    return x[:, :keep].mean(axis=1)


def plain_mean(values: np.ndarray) -> np.ndarray:
    """[K, M] the mean over the scenarios (axis 1) of [K, A, M] values."""
    return np.asarray(values, dtype=float).mean(axis=1)


@dataclass(frozen=True)
class CostRule:
    """How a design's per-scenario costs [A, M] become its cost [M]. Every design of a
    comparison is scored on the same scenarios by the same rule, so differences stay paired.

    `capped`: each scenario's cost is at most `cap` x the reference level (the nominal
    design's median scenario cost, per objective, on the same scenarios and policy), and a
    scenario in which the agent fell costs exactly that cap, whatever it cost: a design cannot
    gain by falling, and one fall moves a cost by at most cap / A of the reference. The cost is
    the plain mean of these scenario costs."""

    rule: str = "capped"
    cap: float = 3.0

    def __post_init__(self) -> None:
        if self.rule not in COST_RULES:
            raise ValueError(f"cost rule must be one of {', '.join(COST_RULES)}, got {self.rule!r}")
        if not self.cap > 1.0:
            raise ValueError(f"cost cap must be > 1, got {self.cap!r}")

    @classmethod
    def from_config(cls, config: dict[str, Any] | None) -> CostRule:
        """The rule a run recorded in its config; a run from before cost rules were settings
        used the trimmed mean."""
        config = config or {}
        return cls(str(config.get("cost_rule") or "trimmed"), float(config.get("cost_cap") or 3.0))

    def costs_of(self, fit: Any, nominal: int = -1) -> np.ndarray:
        """[K, M] the costs of a `RealFitness` whose row `nominal` is the nominal design (the
        reference level); the backend's own costs when it gives no per-scenario costs."""
        if getattr(fit, "per_scenario", None) is None:
            return np.asarray(fit.costs, dtype=float)
        per = np.asarray(fit.per_scenario, dtype=float)
        falls = (
            None
            if getattr(fit, "scenario_falls", None) is None
            else np.asarray(fit.scenario_falls, dtype=bool)
        )
        ref = (
            self.reference(per[nominal], None if falls is None else falls[nominal])
            if self.needs_reference
            else None
        )
        return self.cost(per, falls, ref)

    @property
    def needs_reference(self) -> bool:
        return self.rule == "capped"

    def describe(self) -> str:
        if self.rule == "capped":
            return (
                f"capped mean (a scenario costs at most {self.cap:g} x the nominal design's "
                "median scenario; a fall costs the cap)"
            )
        if self.rule == "trimmed":
            return f"trimmed mean (each design's costliest {TRIM_SHARE:.0%} of scenarios left out)"
        return "plain mean (eq. 4)"

    def reference(self, nominal: np.ndarray, nominal_falls: np.ndarray | None = None) -> np.ndarray:
        """[M] the reference level: the median of the nominal design's scenario costs [A, M]
        over the scenarios in which it did not fall (all of them if it fell in every one)."""
        x = np.asarray(nominal, dtype=float).reshape(-1, np.asarray(nominal).shape[-1])
        if nominal_falls is not None:
            keep = ~np.asarray(nominal_falls, dtype=bool).reshape(-1)
            if keep.any():
                x = x[keep]
        return np.median(x, axis=0)

    def scenario_values(
        self,
        per_scenario: np.ndarray,
        falls: np.ndarray | None = None,
        reference: np.ndarray | None = None,
    ) -> np.ndarray:
        """[K, A, M] what each scenario contributes under the rule (the capped costs for
        `capped`, the raw costs otherwise)."""
        x = np.asarray(per_scenario, dtype=float)
        if self.rule != "capped":
            return x
        if reference is None:
            raise ValueError(
                "the capped cost rule needs a reference level (the nominal design's costs)"
            )
        cap = self.cap * np.abs(np.asarray(reference, dtype=float)).reshape(1, 1, -1)  # [1, 1, M]
        out = np.minimum(x, cap)
        if falls is not None:
            out = np.where(np.asarray(falls, dtype=bool)[:, :, None], cap, out)
        return out

    def aggregate(self, values: np.ndarray) -> np.ndarray:
        """[K, M] a design's cost from its scenario values [K, A, M]."""
        return robust_cost(values) if self.rule == "trimmed" else plain_mean(values)

    def cost(
        self,
        per_scenario: np.ndarray,
        falls: np.ndarray | None = None,
        reference: np.ndarray | None = None,
    ) -> np.ndarray:
        """[K, M] each design's cost under the rule."""
        return self.aggregate(self.scenario_values(per_scenario, falls, reference))


#: the rule before the capped one (what `robust_cost` computes), the reference of the tests
#: and benchmarks
TRIMMED = CostRule("trimmed")


def _resamples(a: int, seed: int = 0) -> np.ndarray:
    """[BOOTSTRAP, a] scenario indices drawn with replacement (fixed seed: the same error bars
    for the same costs)."""
    return np.random.default_rng(seed).integers(0, a, size=(BOOTSTRAP, a))


def scenario_se(
    per_scenario: np.ndarray, aggregate: Callable[[np.ndarray], np.ndarray] = robust_cost
) -> np.ndarray:
    """[K, M] standard error of `aggregate(per_scenario)` over scenarios (bootstrap over the A
    scenarios; 0 with a single scenario: no spread to measure). `per_scenario` holds the
    rule's scenario values (`CostRule.scenario_values`), `aggregate` the rule's aggregate."""
    x = np.asarray(per_scenario, dtype=float)
    if x.shape[1] < 2:
        return np.zeros((x.shape[0], x.shape[2]))
    idx = _resamples(x.shape[1])
    boot = np.stack([aggregate(x[:, i, :]) for i in idx])  # [B, K, M]
    return boot.std(axis=0, ddof=1)


def paired_difference(
    per_scenario: np.ndarray,
    i: int,
    j: int,
    aggregate: Callable[[np.ndarray], np.ndarray] = robust_cost,
) -> tuple[np.ndarray, np.ndarray]:
    """(difference [M], paired standard error [M]) of cost(design i) - cost(design j): the
    bootstrap resamples the same scenarios for both, so what they share (command,
    randomization, noise) cancels."""
    x = np.asarray(per_scenario, dtype=float)[[i, j]]  # [2, A, M]
    cost = aggregate(x)
    diff = cost[0] - cost[1]
    if x.shape[1] < 2:
        return diff, np.zeros_like(diff)
    boot = np.stack([aggregate(x[:, r, :]) for r in _resamples(x.shape[1])])  # [B, 2, M]
    return diff, (boot[:, 0] - boot[:, 1]).std(axis=0, ddof=1)


def improvement_se(
    objective: Any,
    best: np.ndarray,
    nominal: np.ndarray,
    aggregate: Callable[[np.ndarray], np.ndarray] = robust_cost,
) -> float:
    """Paired standard error of `objective.improvement(cost(best), cost(nominal))` from the
    scenario values of the two designs [A] (bootstrap with the same scenarios drawn for
    both; a plugin's own `improvement` is honoured)."""
    b, n = np.asarray(best, dtype=float), np.asarray(nominal, dtype=float)
    if len(b) < 2:
        return float("nan")
    pair = np.stack([b, n])[:, :, None]  # [2, A, 1]
    values = []
    for r in _resamples(len(b)):
        cb, cn = aggregate(pair[:, r, :])[:, 0]
        values.append(float(objective.improvement(float(cb), float(cn))))
    values = np.asarray(values)
    values = values[np.isfinite(values)]
    return float(values.std(ddof=1)) if len(values) > 1 else float("nan")


def fall_statistics(falls: np.ndarray | None, i: int, j: int) -> dict[str, float | None]:
    """Fall rates of designs i and j over their common scenarios [K, A] with standard errors,
    and the paired difference (i - j) with its standard error (the scenarios are shared, so
    the difference's error is that of the per-scenario differences)."""
    if falls is None:
        return {
            "fall_rate": None,
            "fall_rate_se": None,
            "reference_fall_rate": None,
            "reference_fall_rate_se": None,
            "fall_rate_difference": None,
            "fall_rate_difference_se": None,
        }
    f = np.asarray(falls, dtype=float)
    a = f.shape[1]

    def se(x: np.ndarray) -> float:
        return float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")

    d = f[i] - f[j]
    return {
        "fall_rate": float(f[i].mean()),
        "fall_rate_se": se(f[i]),
        "reference_fall_rate": float(f[j].mean()),
        "reference_fall_rate_se": se(f[j]),
        "fall_rate_difference": float(d.mean()),
        "fall_rate_difference_se": se(d) if a > 1 else float("nan"),
    }


def falls_more(difference: float | None, se: float | None, tolerance: float) -> bool:
    """Whether a design falls significantly more often than the reference: its paired fall-rate
    difference exceeds max(tolerance, 2 standard errors)."""
    if difference is None or not np.isfinite(difference):
        return False
    bound = max(float(tolerance), 2.0 * float(se) if se is not None and np.isfinite(se) else 0.0)
    return bool(difference > bound)


def compare_designs(
    rule: CostRule,
    objectives: Sequence[Any],
    per_scenario: np.ndarray,
    falls: np.ndarray | None,
    i: int,
    nominal: int,
) -> dict[str, Any]:
    """Design i against the nominal design on their common scenarios, per objective: the
    rule's cost and the plain mean (eq. 4), each with its standard error, the improvements
    under both with their paired standard errors, and the fall rates with the paired
    difference. The reference level comes from the nominal row."""
    per = np.asarray(per_scenario, dtype=float)
    ref = (
        rule.reference(per[nominal], None if falls is None else np.asarray(falls)[nominal])
        if rule.needs_reference
        else None
    )
    values = rule.scenario_values(per, falls, ref)
    cost, cost_se = rule.aggregate(values), scenario_se(values, rule.aggregate)
    mean, mean_se = plain_mean(per), scenario_se(per, plain_mean)
    out: dict[str, Any] = {"cost_rule": rule.rule, "scenarios": int(per.shape[1]), "objectives": {}}
    for j, o in enumerate(objectives):
        imp = float(o.improvement(float(cost[i, j]), float(cost[nominal, j])))
        imp_plain = float(o.improvement(float(mean[i, j]), float(mean[nominal, j])))
        out["objectives"][o.name] = {
            "cost": float(cost[i, j]),
            "cost_se": float(cost_se[i, j]),
            "plain_mean": float(mean[i, j]),
            "plain_mean_se": float(mean_se[i, j]),
            "nominal_cost": float(cost[nominal, j]),
            "nominal_cost_se": float(cost_se[nominal, j]),
            "nominal_plain_mean": float(mean[nominal, j]),
            "nominal_plain_mean_se": float(mean_se[nominal, j]),
            "improvement": imp,
            "improvement_se": improvement_se(
                o, values[i, :, j], values[nominal, :, j], rule.aggregate
            ),
            "improvement_plain": imp_plain,
            "improvement_plain_se": improvement_se(o, per[i, :, j], per[nominal, :, j], plain_mean),
        }
    out.update(fall_statistics(falls, i, nominal))
    return out
