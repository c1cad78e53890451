"""One sim-to-sim protocol: how a design and the nominal one are compared on a second
simulator, for `coadapt report`'s sim-to-sim column and `coadapt handoff`'s per-simulator
checks alike (docs/sim-to-sim.md, "One protocol").

Both designs walk the same `scenarios` paired scenarios (block `BLOCK` of the run's seed, the
final check's first block, so no design was chosen on them) for `steps` policy steps (the
run's own evaluation length unless told otherwise). Their costs follow the run's cost rule
(the capped rule: a fall costs the cap), with the plain mean (eq. 4) and the paired fall-rate
difference beside them, as in the run's final check. The figure is withheld, and the reason
said instead, when most scenarios end in a fall for both designs or when one design falls
more than the other beyond the run's fall gate (max(fall_tolerance, 2 paired standard
errors), `costs.falls_more`); a warning goes with it when the scenarios with a fall make most
of the cost difference (`falls_share`).

`figures` turns one paired evaluation into the two stored rows' flat figures (the keys of
`row_figures`, which the common yardstick stores too, plus `scenarios`, `steps`, `block`,
`falls/share` and `falls/gate` on the best row); `reading` reads them back and `line`
prints them, so a stored row and a fresh evaluation print the same words.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from coadapt_core.costs import CostRule, compare_designs, falls_more
from coadapt_core.scenarios.seeds import scenario_seed

#: paired scenarios per design unless told otherwise (`--transfer-agents`, handoff `--agents`)
SCENARIOS = 16
#: the block of the run's seed the scenarios come from: the final check's first block
BLOCK = 1
#: both designs fall in at least this share of the scenarios: the costs compare falls
BOTH_FALL = 0.5
_FALL_KEYS = ("fall_rate", "reference_fall_rate")
#: the improvement figures a best row holds per objective (NAME/KEY)
IMPROVEMENT_KEYS = ("improvement", "improvement_se", "improvement_plain", "improvement_plain_se")
#: the scenarios with a fall make more than this share of the cost difference: a warning
FALLS_DECIDE = 0.5


@dataclass(frozen=True)
class Protocol:
    """What one sim-to-sim comparison runs: paired scenarios, policy steps, scenario block."""

    scenarios: int = SCENARIOS
    steps: int = 250
    block: int = BLOCK

    def seed(self, run_seed: int) -> int:
        """The scenario seed for a run with seed `run_seed`."""
        return scenario_seed(int(run_seed), self.block)

    def describe(self) -> str:
        return f"{self.scenarios} paired scenarios x {self.steps} steps, block {self.block}"


def protocol_of(
    config: dict[str, Any] | None, scenarios: int | None = None, steps: int | None = None
) -> Protocol:
    """The protocol for a run of `config`: `scenarios` (default `SCENARIOS`) paired scenarios
    of `steps` policy steps (default: the run's `eval_steps`, else 250)."""
    cfg = config or {}
    own_steps = int(cfg.get("eval_steps") or 0) or 250
    return Protocol(int(scenarios or SCENARIOS), int(steps or own_steps))


def gate_of(config: dict[str, Any] | None) -> float:
    """The run's fall tolerance (the final check's gate), 0.01 when it recorded none."""
    value = (config or {}).get("fall_tolerance")
    return 0.01 if value is None else float(value)


def row_figures(comparison: dict[str, Any], *, best: bool) -> dict[str, float]:
    """A `compare_designs` result as the flat `costs` mapping of one stored row."""
    out: dict[str, float] = {}
    for name, v in comparison["objectives"].items():
        out[name] = v["cost"]
        out[f"{name}/se"], out[f"{name}/plain"], out[f"{name}/plain_se"] = (
            v["cost_se"],
            v["plain_mean"],
            v["plain_mean_se"],
        )
        if best:
            for key in IMPROVEMENT_KEYS:
                out[f"{name}/{key}"] = v[key]
    out["falls"], out["falls/se"] = comparison["fall_rate"], comparison["fall_rate_se"]
    if best:
        out["falls/difference"] = comparison["fall_rate_difference"]
        out["falls/difference_se"] = comparison["fall_rate_difference_se"]
    return {k: float(x) for k, x in out.items()}


def falls_share(values: np.ndarray, falls: np.ndarray | None) -> float:
    """The share of the paired cost difference (design 0 - design 1, scenario values [2, A])
    made by the scenarios in which either design fell: |sum over them| / (|sum over them| +
    |sum over the others|); 0 without falls."""
    if falls is None:
        return 0.0
    d = np.asarray(values[0] - values[1], dtype=float)
    fell = np.asarray(falls, dtype=bool).any(axis=0)
    with_falls, without = abs(float(d[fell].sum())), abs(float(d[~fell].sum()))
    total = with_falls + without
    return with_falls / total if total > 0 else 0.0


def figures(
    fit: Any,
    objectives: Sequence[Any],
    rule: CostRule,
    gate: float,
    protocol: Protocol,
) -> list[dict[str, float]] | None:
    """The two rows' figures (best design 0, nominal 1) of a paired evaluation `fit` (rows
    [best, nominal]), or None when it carries no per-scenario costs."""
    if getattr(fit, "per_scenario", None) is None:
        return None
    per = np.asarray(fit.per_scenario, dtype=float)
    falls = getattr(fit, "scenario_falls", None)
    falls = None if falls is None else np.asarray(falls, dtype=bool)
    rows = []
    for i in (0, 1):  # each row's figures of its own design against the nominal one (row 1)
        comparison = compare_designs(rule, objectives, per, falls, i, 1)
        if falls is None:  # a backend that reports no falls: not known (NaN), not none
            comparison.update({k: math.nan for k in comparison if k.startswith(_FALL_KEYS)})
        rows.append(row_figures(comparison, best=i == 0))
    ref = rule.reference(per[1], None if falls is None else falls[1])
    values = rule.scenario_values(per, falls, ref if rule.needs_reference else None)
    best = rows[0]
    best.update(
        {
            "scenarios": float(per.shape[1]),
            "steps": float(protocol.steps),
            "block": float(protocol.block),
            "falls/share": falls_share(values[:, :, 0], falls),
            "falls/gate": float(gate),
        }
    )
    return rows


@dataclass(frozen=True)
class Reading:
    """One objective's sim-to-sim figures, and whether they answer."""

    objective: str
    improvement: float
    improvement_se: float
    plain: float
    plain_se: float
    fall_rate: float
    nominal_fall_rate: float
    fall_difference: float
    fall_difference_se: float
    scenarios: int
    falls_share: float
    gate: float

    @property
    def refusal(self) -> str:
        """Why no percentage answers ('' when one does)."""
        rates = f"{self.fall_rate:.2f} vs {self.nominal_fall_rate:.2f} of {self.scenarios}"
        if min(self.fall_rate, self.nominal_fall_rate) >= BOTH_FALL:
            return f"no answer: both designs fall (fall rate {rates} scenarios)"
        se = self.fall_difference_se
        for sign, who in ((1.0, "the design"), (-1.0, "the nominal design")):
            if falls_more(sign * self.fall_difference, se, self.gate):
                return (
                    f"no answer: {who} falls more (fall rate {rates} scenarios, beyond the gate "
                    f"max({self.gate:g}, 2 SE))"
                )
        return ""

    @property
    def warning(self) -> str:
        """A warning when the scenarios with a fall make most of the difference."""
        if self.refusal or self.falls_share <= FALLS_DECIDE:
            return ""
        return (
            f"falls decide the figure: the scenarios with a fall make {self.falls_share:.0%} "
            "of the cost difference"
        )

    @property
    def answer(self) -> float | None:
        """The improvement under the run's cost rule, None when the figures cannot answer."""
        return None if self.refusal else self.improvement


def reading(best: dict[str, float], nominal: dict[str, float], objective: str) -> Reading | None:
    """The figures of `objective` in a stored pair of rows, None when they are not this
    protocol's (older rows hold the costs alone)."""
    if any(f"{objective}/{k}" not in best for k in IMPROVEMENT_KEYS) or "scenarios" not in best:
        return None

    def num(row: dict[str, float], key: str) -> float:
        value = row.get(key)
        return float("nan") if value is None else float(value)

    return Reading(
        objective=objective,
        improvement=num(best, f"{objective}/improvement"),
        improvement_se=num(best, f"{objective}/improvement_se"),
        plain=num(best, f"{objective}/improvement_plain"),
        plain_se=num(best, f"{objective}/improvement_plain_se"),
        fall_rate=num(best, "falls"),
        nominal_fall_rate=num(nominal, "falls"),
        fall_difference=num(best, "falls/difference"),
        fall_difference_se=num(best, "falls/difference_se"),
        scenarios=int(best["scenarios"]),
        falls_share=num(best, "falls/share"),
        gate=num(best, "falls/gate"),
    )


def _pct(value: float, se: float) -> str:
    text = f"{100 * value:+.1f} %"
    return text if not np.isfinite(se) else f"{text} ± {100 * se:.1f}"


def line(r: Reading, rule: str = "capped", measure: str = "") -> str:
    """The figures in one line: the answer under the cost rule (or why none), the plain mean,
    the fall rates and their paired difference, the scenario count, and the warning.
    `measure`: what the objective's improvement measures where it is not 1 - c/c0
    (`analysis.measures.improvement_measure`: tracking's RMS error reduction)."""
    what = f"{rule} cost" + (f"; {measure}" if measure else "")
    head = r.refusal or f"{r.objective} {_pct(r.improvement, r.improvement_se)} ({what})"
    falls = (
        f"fall rate {r.fall_rate:.2f} vs {r.nominal_fall_rate:.2f} (difference "
        f"{_pct(r.fall_difference, r.fall_difference_se).replace(' %', '')} points)"
        if np.isfinite(r.fall_rate)
        else "falls not reported by the backend"
    )
    parts = [
        head,
        f"plain mean {_pct(r.plain, r.plain_se)}",
        falls,
        f"{r.scenarios} paired scenarios",
    ]
    if r.warning:
        parts.append(f"warning: {r.warning}")
    return "; ".join(parts)
