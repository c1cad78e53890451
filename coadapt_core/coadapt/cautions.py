"""What a researcher must be told before trusting a run's answer (issue 43): the warnings a
run prints under its table and records in summary.json's `warnings`.

- **At a bound**: a continuous variable of the best design within `BOUND_SHARE` of its full
  range from a bound of the run's design space (the space it started from, before any
  narrowing): the optimum may lie beyond the bound.
- **Plain mean not significant**: the improvement under the cost rule is significant (4
  paired standard errors, `final_check.SIGNIFICANCE_RATIO`) while the plain mean's (the
  paper's eq. 4 over the same scenarios) is not, or points the other way: the gain may be the
  rule's (fewer expensive scenarios) rather than a cheaper gait.
- **Weak surrogate**: the surrogate's pooled Spearman over the judged real rounds is below
  `WEAK_SPEARMAN`, said with how many real rounds it covers (a run judges only the rounds a
  fit already covers unless `surrogate_error_fits` is on, so the figure of a run with few
  judged rounds is not comparable with one judged on every round), and with the noise ceiling
  of those rounds where the run kept its designs' SEs (`surrogate_quality.noise_ceiling`:
  near it, the designs differ by little more than their noise; below it, the surrogate is).

Each warning is one line, starting with what it is about. `run_warnings(summary)` works on
any summary.json (older ones included: a missing field means the warning is not judged)."""

from __future__ import annotations

import math
from typing import Any

#: a best design's variable within this share of its range from a bound is said to sit at it
BOUND_SHARE = 0.05
#: below this pooled Spearman the surrogate's ranking is called weak
WEAK_SPEARMAN = 0.5


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def at_bound(summary: dict[str, Any], share: float = BOUND_SHARE) -> str | None:
    """The warning for a best design at a bound of the run's (first) design space, or None."""
    spaces = summary.get("spaces") or []
    space = spaces[0] if spaces else summary.get("final_space")
    best = summary.get("best_design")
    if not isinstance(space, dict) or not best or summary.get("best_is_nominal"):
        return None
    hits = []
    for var, x in zip(space.get("variables") or [], best, strict=False):
        low, high = var.get("low"), var.get("high")
        if (
            var.get("type", "continuous") != "continuous"
            or not (_finite(low) and _finite(high))
            or high <= low
        ):
            continue
        margin = share * (high - low)
        if x - low <= margin:
            hits.append(f"{var.get('name', '?')} {x:.3f} at its lower bound {low:g}")
        elif high - x <= margin:
            hits.append(f"{var.get('name', '?')} {x:.3f} at its upper bound {high:g}")
    if not hits:
        return None
    return (
        f"best design at a bound of the design space ({'; '.join(hits)}; within {100 * share:g} % "
        "of the range): the optimum may lie beyond it; widen the range (--design-ranges) or read "
        "the answer as found at the bound"
    )


def plain_mean_not_significant(summary: dict[str, Any], ratio: float | None = None) -> str | None:
    """The warning for a significant improvement whose plain mean is not, or None."""
    if ratio is None:
        from coadapt_core.coadapt.final_check import SIGNIFICANCE_RATIO

        ratio = SIGNIFICANCE_RATIO
    gain, gain_se = summary.get("improvement"), summary.get("improvement_se")
    plain, plain_se = summary.get("improvement_plain"), summary.get("improvement_plain_se")
    if summary.get("significant") is not True or not (
        _finite(gain) and _finite(plain) and _finite(plain_se)
    ):
        return None
    if abs(plain) >= ratio * plain_se and plain * gain > 0:
        return None
    objective = next(iter(summary.get("improvements") or {}), "cost")
    rule = summary.get("cost_rule") or "the rule's"
    shown = f"{100 * gain:+.1f}" + (f" +- {100 * gain_se:.1f}" if _finite(gain_se) else "")
    return (
        f"{objective}: the improvement ({shown} %, {rule} cost) is significant but its plain "
        f"mean's ({100 * plain:+.1f} +- {100 * plain_se:.1f} %) is not (under {ratio:g} "
        f"paired standard errors{' or of the other sign' if plain * gain <= 0 else ''}): the "
        "gain may be the cost rule's, not a cheaper gait"
    )


def surrogate_note(summary: dict[str, Any]) -> str | None:
    """The surrogate's pooled Spearman and the real rounds it covers, as one line (printed
    whether or not it is weak; None when no round was judged)."""
    pooled = (summary.get("surrogate_quality") or {}).get("pooled") or {}
    rho, rounds, real = (
        pooled.get("spearman"),
        pooled.get("rounds"),
        summary.get("real_evaluations"),
    )
    if not _finite(rho):
        return None
    covers = f"{rounds} judged real round{'s' if rounds != 1 else ''}" + (
        f" of {real}" if _finite(real) else ""
    )
    partial = (
        " (only rounds a fit already covers are judged; --surrogate-error-fits judges every one)"
        if _finite(real) and _finite(rounds) and rounds < real
        else ""
    )
    return (
        f"surrogate (in-run rounds): pooled Spearman {rho:.2f} over {covers}{partial}"
        f"{ceiling_text(pooled)}"
    )


def ceiling_text(figures: dict[str, Any]) -> str:
    """'; noise ceiling C +- sd: near it' (surrogate_quality.noise_ceiling: the Spearman the
    real costs' own noise allows), or '' where the run recorded none."""
    c, sd, verdict = (
        figures.get("ceiling"),
        figures.get("ceiling_sd"),
        figures.get("against_ceiling"),
    )
    if not (_finite(c) and _finite(sd) and verdict):
        return ""
    reading = (
        "near it: the designs differ by little more than their noise"
        if verdict == "near"
        else "below it: the real costs rank the designs better than the surrogate does"
    )
    return f"; the real costs' noise ceiling {c:.2f} +- {sd:.2f}, {reading}"


def weak_surrogate(summary: dict[str, Any], threshold: float = WEAK_SPEARMAN) -> str | None:
    """The warning for a surrogate whose pooled Spearman is below `threshold`, or None."""
    quality = summary.get("surrogate_quality") or {}
    pooled = quality.get("pooled") or {}
    rho, rounds = pooled.get("spearman"), pooled.get("rounds")
    if not _finite(rho) or rho >= threshold:
        return None
    real = summary.get("real_evaluations")
    covers = f"{rounds} judged real round{'s' if rounds != 1 else ''}" + (
        f" of {real}" if _finite(real) else ""
    )
    first = next(iter(quality.get("by_objective") or {}), None)
    judged = [r for r in quality.get("rounds") or [] if r.get("eligible")]
    last = (
        ((judged[-1].get("objectives") or {}).get(first) or {}).get("spearman")
        if judged and first
        else None
    )
    last_text = f", last judged round {last:.2f}" if _finite(last) else ""
    partial = (
        " (a round is judged only where a fit already covers it unless --surrogate-error-fits: not "
        "comparable with runs judged on every round)"
        if _finite(real) and _finite(rounds) and rounds < real
        else ""
    )
    return (
        f"surrogate: pooled Spearman {rho:.2f} over {covers}{last_text} is below "
        f"{threshold:g}: its rounds ranked designs weakly{partial}{ceiling_text(pooled)}"
    )


def run_warnings(summary: dict[str, Any]) -> list[str]:
    """Every warning that applies to `summary`, in the order of the module's list."""
    found = (at_bound(summary), plain_mean_not_significant(summary), weak_surrogate(summary))
    return [w for w in found if w]


__all__ = [
    "BOUND_SHARE",
    "WEAK_SPEARMAN",
    "at_bound",
    "ceiling_text",
    "plain_mean_not_significant",
    "run_warnings",
    "surrogate_note",
    "weak_surrogate",
]
