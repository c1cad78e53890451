"""The walking gate: is the policy behind a run's costs walking at all?

Costs of a policy that falls or stands still say nothing about a design (a robot that does
not walk spends little torque). Every real evaluation of the universal policy records, per
design, the share of agents that never fell (`survival`) and how far the robots go from
where they are told (`tracking_ratio`): each scenario's mean velocity (v_x, v_y, yaw rate,
over its steps before its first fall) against its command, the RMS of that error over the
design's scenarios relative to the RMS command; 0 goes exactly where commanded, 1 is no
better than standing still. Means, not per-step errors: a stepping gait's oscillation and
the stochastic policy's action noise would otherwise count as not walking (per step, the
shipped flat policy's error is 0.85-1.1 x command, most of it yaw-rate wobble; its mean
velocities miss by 0.25-0.46 x command at the nominal design and the four corners, 32
paired scenarios of 5 s). A run
is **reliable** when

- the final check's best and nominal designs each have survival >= `min_survival` (0.8) and
  tracking_ratio <= `max_tracking_ratio` (0.5), and
- the mean over the run's real optimisation rounds passes the same thresholds.

Otherwise its summary, its `--json` line and its report row say `reliable: false` with the
reason. A run whose best design falls significantly more often than the nominal design (its
paired fall-rate difference over the final check's scenarios above max(1 percentage point,
2 standard errors), `fall_verdict`) is not reliable either: its cost was bought with falls.
A backend that reports neither measurement (the analytic fake of the tests) leaves
`reliable` null ("not measured").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: what the tracking ratio is, said wherever it is printed (not P_cmd, not a per-step error)
RATIO_MEANS = "RMS velocity error / command size"


def ratio_text(ratio: float) -> str:
    """The tracking ratio as printed: "tracking ratio 0.11 (RMS velocity error / command size)"."""
    return f"tracking ratio {ratio:.2f} ({RATIO_MEANS})"


@dataclass(frozen=True)
class WalkingGate:
    min_survival: float = 0.8
    max_tracking_ratio: float = 0.5

    def describe(self) -> str:
        return (
            f"survival >= {self.min_survival:g} and tracking ratio <= "
            f"{self.max_tracking_ratio:g} ({RATIO_MEANS})"
        )


WALKING_GATE = WalkingGate()


def walking(fit: Any, rows: list[int] | None = None) -> dict[str, float | None]:
    """{'survival', 'tracking_ratio'}: means over `rows` (all designs when None) of a
    `RealFitness`; None where the backend did not measure them."""

    def mean(values: Any) -> float | None:
        if values is None:
            return None
        arr = np.asarray(values, dtype=float).reshape(-1)
        arr = arr if rows is None else arr[rows]
        arr = arr[np.isfinite(arr)]
        return float(arr.mean()) if arr.size else None

    return {
        "survival": mean(getattr(fit, "survival", None)),
        "tracking_ratio": mean(getattr(fit, "tracking_ratio", None)),
    }


def _fails(measured: dict[str, Any], gate: WalkingGate) -> list[str]:
    out = []
    survival, ratio = measured.get("survival"), measured.get("tracking_ratio")
    if survival is not None and survival < gate.min_survival:
        out.append(f"survival {survival:.2f} < {gate.min_survival:g}")
    if ratio is not None and ratio > gate.max_tracking_ratio:
        out.append(f"{ratio_text(ratio)} > {gate.max_tracking_ratio:g}")
    return out


def assess(
    batches: list[dict[str, Any]],
    final: dict[str, dict[str, Any]] | None,
    gate: WalkingGate = WALKING_GATE,
) -> tuple[bool | None, str]:
    """(reliable, reason) from the real batches' records and the final check's per-design
    measurements ({'best': {...}, 'nominal': {...}})."""
    real = [b for b in batches if b.get("kind") == "real"]
    rounds: dict[str, float | None] = {}
    for key in ("survival", "tracking_ratio"):
        values = [b.get(key) for b in real if b.get(key) is not None and math.isfinite(b.get(key))]
        rounds[key] = float(np.mean(values)) if values else None
    measured = [
        ("real rounds", rounds),
        *((f"final check, {k} design", v) for k, v in (final or {}).items()),
    ]
    if all(m.get("survival") is None and m.get("tracking_ratio") is None for _, m in measured):
        return None, "not measured (the backend reports neither survival nor tracking)"
    problems = [f"{where}: {'; '.join(f)}" for where, m in measured if (f := _fails(m, gate))]
    if problems:
        return False, "the policy does not walk (" + " | ".join(
            problems
        ) + f"); gate: {gate.describe()}"
    return True, f"passed the walking gate ({gate.describe()})"


#: the shortest real evaluation, in policy steps per scenario, whose tracking verdict the
#: gate trusts. Every scenario starts from rest, so over a short one the mean velocity lags
#: the command whatever the policy: the shipped flat policy (Kuafu, 0.02 s steps, 8 agents,
#: the nominal design and two corners) misses by 0.51-0.56 x command over 20 steps (the
#: smoke preset's), 0.32-0.35 over 50 and 0.22-0.30 over 100.
MIN_JUDGED_STEPS = 50
#: over a shorter evaluation a policy still fails when it tracks no better than this (about
#: standing still, 1.0) or falls: that the start from rest cannot explain
SHORT_MAX_TRACKING_RATIO = 0.95


def judge_short(
    batches: list[dict[str, Any]],
    final: dict[str, dict[str, Any]] | None,
    eval_steps: int,
    *,
    from_scratch: bool,
    gate: WalkingGate = WALKING_GATE,
) -> tuple[bool | None, str]:
    """`assess`, for an evaluation of `eval_steps` steps per scenario: under
    `MIN_JUDGED_STEPS` a policy that came trained and fails only on tracking by less than
    `SHORT_MAX_TRACKING_RATIO` is "not judged" (None); one that falls, stands still, or was
    trained from scratch in the run (nothing else vouches for it) stays a failure."""
    verdict = assess(batches, final, gate)
    reliable, reason = verdict
    if reliable is not False or eval_steps >= MIN_JUDGED_STEPS:
        return verdict
    short = (
        f"{eval_steps} steps per scenario are too short to judge tracking (the gate needs >= "
        f"{MIN_JUDGED_STEPS})"
    )
    if from_scratch:
        return False, f"trained from scratch in this run, and {short}; measured: {reason}"
    loose = WalkingGate(min_survival=gate.min_survival, max_tracking_ratio=SHORT_MAX_TRACKING_RATIO)
    if assess(batches, final, loose)[0] is False:
        return (
            False,
            f"{reason}; it falls or stands still, which {eval_steps} steps per scenario do not "
            "explain",
        )
    return None, f"not judged: {short}; measured: {reason}"


def judge_policy(
    survival: float | None,
    tracking_ratio: float | None,
    steps: int,
    gate: WalkingGate = WALKING_GATE,
) -> tuple[bool | None, str]:
    """The walking gate of `coadapt run` on one evaluation of a policy (`coadapt eval`, the
    end of `coadapt train`): (walking, reason). True: it passed; False: it falls or misses
    the command; None: not measured, or `steps` per agent under `MIN_JUDGED_STEPS` and it
    missed by less than `SHORT_MAX_TRACKING_RATIO` without falling (`judge_short`'s rule)."""
    measured = {"survival": survival, "tracking_ratio": tracking_ratio}
    if survival is None and tracking_ratio is None:
        return None, "not measured"
    problems = _fails(measured, gate)
    if not problems:
        shown = [f"survival {survival:.2f}"] if survival is not None else []
        shown += [ratio_text(tracking_ratio)] if tracking_ratio is not None else []
        return True, f"walks ({', '.join(shown)}); gate: {gate.describe()}"
    reason = f"does not walk ({'; '.join(problems)}); gate: {gate.describe()}"
    if steps >= MIN_JUDGED_STEPS:
        return False, reason
    if _fails(
        measured,
        WalkingGate(min_survival=gate.min_survival, max_tracking_ratio=SHORT_MAX_TRACKING_RATIO),
    ):
        return (
            False,
            f"{reason}; it falls or stands still, which {steps} steps per agent do not explain",
        )
    return None, (
        f"not judged: {steps} steps per agent are too short to judge tracking (the gate needs "
        f">= {MIN_JUDGED_STEPS}); measured: {reason}"
    )


#: a best design may fall this much more often than the nominal one (or 2 paired standard
#: errors, if more) before the run says its gain was bought with falls
FALL_MARGIN = 0.01


def fall_verdict(summary: dict[str, Any], margin: float = FALL_MARGIN) -> dict[str, Any]:
    """`falls_more` (None: not measured) and, when the best design falls significantly more
    often than the nominal one, `reliable: false` with the figures in `reliability`."""
    from coadapt_core.costs import falls_more

    d, se = summary.get("fall_rate_difference"), summary.get("fall_rate_difference_se")
    if d is None:
        return {"falls_more": None}
    if not falls_more(d, se, margin):
        return {"falls_more": False}
    best_rate, nominal_rate = summary.get("best_fall_rate", 0), summary.get("nominal_fall_rate", 0)
    why = (
        f"the best design falls more often than the nominal design ({100 * best_rate:.1f} % "
        f"against {100 * nominal_rate:.1f} % of scenarios, difference "
        f"{100 * d:.1f} +- {100 * (se or 0):.1f} points > max({100 * margin:g}, 2 SE))"
    )
    previous = summary.get("reliability") or ""
    return {
        "falls_more": True,
        "reliable": False,
        "reliability": why if summary.get("reliable") is not False else f"{why}; {previous}",
    }


__all__ = [
    "FALL_MARGIN",
    "MIN_JUDGED_STEPS",
    "SHORT_MAX_TRACKING_RATIO",
    "WALKING_GATE",
    "WalkingGate",
    "assess",
    "fall_verdict",
    "judge_policy",
    "judge_short",
    "walking",
]
