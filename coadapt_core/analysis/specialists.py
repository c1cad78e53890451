"""The paper's Tables 4-5 layout from `coadapt verify`'s rows: at each verified design and at
the nominal design, the cost under the universal policy beside the cost under the design's
own specialist, the improvements both give with their SEs, their difference and the verdict
(`coadapt_core.coadapt.verify`). `coadapt report` writes it as specialists.md and .csv when
the selected runs hold such rows."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from coadapt_core.results.store import ResultsStore


def specialist_rows(store: ResultsStore, run_ids: Sequence[str]) -> list[dict[str, Any]]:
    """One row per verified design of the runs (every budget), flat for a CSV."""
    out = []
    for r in store.verifications(list(run_ids)):
        detail = r["detail"] or {}
        u, s = detail.get("universal") or {}, detail.get("specialist") or {}
        out.append(
            {
                "run_id": r["run_id"],
                "objective": r["objective"],
                "role": r["role"],
                "design": " ".join(f"{x:.3f}" for x in r["design"]),
                "budget": int(r["budget"]),
                "seed": int(r["seed"]),
                "universal_cost": u.get("cost"),
                "specialist_cost": s.get("cost"),
                "universal_nominal_cost": u.get("nominal_cost"),
                "specialist_nominal_cost": s.get("nominal_cost"),
                "universal_improvement": r["universal_improvement"],
                "universal_improvement_se": r["universal_improvement_se"],
                "specialist_improvement": r["specialist_improvement"],
                "specialist_improvement_se": r["specialist_improvement_se"],
                "difference": r["difference"],
                "difference_se": r["difference_se"],
                "verdict": r["verdict"],
                "scenarios": int(r["scenarios"]),
            }
        )
    return out


def _num(x: Any, spec: str = ".5g") -> str:
    return "–" if x is None else format(float(x), spec)


def _pct(x: Any, se: Any) -> str:
    if x is None:
        return "–"
    return f"{100 * float(x):+.1f} %" + ("" if se is None else f" ± {100 * float(se):.1f}")


def specialists_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The rows as the paper's Tables 4-5 set universal beside specialized policies."""
    head = [
        "Run",
        "Objective",
        "Design",
        "Budget per specialist",
        "Cost at the design: universal / specialist",
        "Cost at nominal: universal / specialist",
        "Improvement: universal",
        "Improvement: with specialists",
        "Difference (points)",
        "Verdict",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        diff = _pct(r["difference"], r["difference_se"]).replace(" %", "")
        cells = [
            r["run_id"],
            r["objective"],
            f"{r['role']} ({r['design']})",
            f"{r['budget']:,}",
            f"{_num(r['universal_cost'])} / {_num(r['specialist_cost'])}",
            f"{_num(r['universal_nominal_cost'])} / {_num(r['specialist_nominal_cost'])}",
            _pct(r["universal_improvement"], r["universal_improvement_se"]),
            _pct(r["specialist_improvement"], r["specialist_improvement_se"]),
            diff,
            r["verdict"],
        ]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    lines += [
        "",
        "`coadapt verify`: from each run's universal policy, a specialist fine-tuned at the "
        "design and one at the nominal design (the same budget and seeds), the run's paired "
        "final check repeated with each design on its own specialist and with the universal "
        "policy on the same scenarios. Costs per step under each policy's capped rule (the "
        "cap from its own nominal design); improvements ± paired SE; the difference's SE "
        "from one bootstrap over the scenarios of all four rows. Verdict: holds (same sign, "
        "both at least 4 SE, difference within 2 SE), grows or shrinks (beyond 2 SE), does "
        "not hold (docs/cli/verify.md).",
    ]
    return "\n".join(lines) + "\n"
