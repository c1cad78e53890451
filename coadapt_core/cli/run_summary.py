"""What `coadapt run` prints at its end: the best and the nominal design with their costs,
plain means and fall rates (each +- its standard error), the cost rule and the protocol,
the walking gate, the improvement over nominal said in one direction, the Pareto front and
the run's warnings; with --json, the one JSON line instead."""

from __future__ import annotations

import json
import math
from typing import Any

from coadapt_core.cli.progress import fmt_duration

#: a final check on fewer paired scenarios than this (the smoke preset's 2) is said to be one
FEW_SCENARIOS = 8


def with_se(value: float, se: float | None) -> str:
    """A cost and its standard error to the SE's two significant digits, in one notation
    (6645 +- 480, 1.258 +- 0.012), never mixed (6644.7 +- 4.8e+02)."""
    if se is None or not math.isfinite(se) or se <= 0 or not math.isfinite(value):
        return f"{value:.5g}"
    places = 1 - math.floor(math.log10(se))
    if places <= 0:
        step = 10**-places
        return f"{round(value / step) * step:.0f} +- {round(se / step) * step:.0f}"
    return f"{value:.{places}f} +- {se:.{places}f}"


def _design_value(x: float, discrete: bool) -> str:
    """A design variable: a discrete one (a motor type) as a whole number, a scale to 3 decimals."""
    return f"{x:.0f}" if discrete else f"{x:.3f}"


def _rate(value: float | None, se: float | None = None) -> str:
    if value is None:
        return "-"
    return f"{100 * value:.1f} %" if se is None else f"{100 * value:.1f} +- {100 * se:.1f} %"


def _summary_table(summary: dict[str, Any], names: list[str], discrete: list[bool]) -> Any:
    """The best and the nominal design with their costs, plain means and fall rates (each
    +- its standard error), as a rich table."""
    from rich import box
    from rich.table import Table

    # light borders and headers over two lines: 4 design variables and a cost fit 80 columns;
    # a narrower terminal folds cells onto more lines (never cuts them), a pipe or a file gets
    # the table's own width (`wide_console`)
    table = Table(
        title=f"coadapt run {summary['run_id']}: final check costs",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        collapse_padding=True,
    )
    table.add_column("", overflow="fold")
    for name in names:
        table.add_column(name, min_width=len(name), overflow="fold")
    units = summary.get("cost_units") or {}
    for objective in summary["best_costs"]:
        unit = f" [{units[objective]}]" if units.get(objective) else ""
        table.add_column(f"{objective}{_symbol(objective)}{unit}\n+- SE", overflow="fold")
    plain = summary.get("best_plain_means") or {}
    for objective in plain:
        table.add_column(f"{objective} plain\nmean +- SE", overflow="fold")
    table.add_column("fall rate\n+- SE", min_width=4, overflow="fold")
    best_se, nominal_se = summary.get("best_costs_se") or {}, summary.get("nominal_costs_se") or {}
    plain_se = summary.get("best_plain_means_se") or {}
    nominal_plain, nominal_plain_se = (
        summary.get("nominal_plain_means") or {},
        summary.get("nominal_plain_means_se") or {},
    )
    table.add_row(
        "best",
        *[_design_value(x, d) for x, d in zip(summary["best_design"], discrete, strict=False)],
        *[with_se(v, best_se.get(k)) for k, v in summary["best_costs"].items()],
        *[with_se(v, plain_se.get(k)) for k, v in plain.items()],
        _rate(summary.get("best_fall_rate"), summary.get("best_fall_rate_se")),
    )
    table.add_row(
        "nominal",
        *[_design_value(x, d) for x, d in zip(summary["nominal_design"], discrete, strict=False)],
        *[with_se(summary["nominal_costs"][k], nominal_se.get(k)) for k in summary["best_costs"]],
        *[with_se(nominal_plain[k], nominal_plain_se.get(k)) for k in plain],
        _rate(summary.get("nominal_fall_rate"), summary.get("nominal_fall_rate_se")),
    )
    return table


def better_by(value: float, se: float | None = None) -> str:
    """An improvement said in one direction: "better by 23.5 +- 6.3 %" or "worse by ..."."""
    return (
        f"{'worse' if value < 0 else 'better'} by {100 * abs(value):.1f}"
        f"{'' if se is None else f' +- {100 * se:.1f}'} %"
    )


def falls_more_by(difference: float, se: float | None = None) -> str:
    """A fall-rate difference (best - nominal) said in one direction: "falls more by 0.8 +-
    0.4 points", "falls less by ...", "falls no more (0.0 +- 0.0 points)"."""
    spread = "" if se is None else f" +- {100 * se:.1f}"
    if difference == 0:
        return f"falls no more than nominal (0.0{spread} points)"
    direction = "more" if difference > 0 else "less"
    return f"falls {direction} by {100 * abs(difference):.1f}{spread} points than nominal"


def _symbol(name: str) -> str:
    """The symbol of an objective's cost (" P_cmd": its description's "P_cmd = ...") where
    its improvement is not the cost reduction, so that its cost and its improvement are told
    apart; else ''."""
    from coadapt_core.analysis.measures import improvement_measure, objective_named

    objective = objective_named(name)
    text = getattr(objective, "description", "") or ""
    return f" {text.split(' = ')[0]}" if " = " in text and improvement_measure(objective) else ""


def _measured(name: str) -> str:
    """An objective's name with what its improvement measures where that is not the cost
    reduction: "tracking (RMS error reduction 1 - √(c/c0))"."""
    from coadapt_core.analysis.measures import improvement_measure, objective_named

    measure = improvement_measure(objective_named(name))
    return f"{name} ({measure})" if measure else name


def _improvements(summary: dict[str, Any]) -> str:
    """The improvement over the nominal design, per objective (+- its paired SE; the first
    said not significant when it is not), the plain means', the fall-rate difference, each
    in one direction ("better by", "falls more by")."""
    improvement_se = summary.get("improvements_se") or {}
    first = next(iter(summary["improvements"]), None)
    parts = []
    for k, v in summary["improvements"].items():
        text = f"{_measured(k)} {better_by(v, improvement_se.get(k))}"
        if k == first and summary.get("significant") is False:
            why = (
                "the nominal design stands"
                if summary.get("best_is_nominal")
                else "under 4 paired standard errors"
            )
            text += f" (not significant: {why})"
        parts.append(text)
    improvements = ", ".join(parts)
    plain_imp, plain_imp_se = (
        summary.get("improvements_plain") or {},
        summary.get("improvements_plain_se") or {},
    )
    if plain_imp:
        improvements += (
            " (plain mean: "
            + ", ".join(f"{k} {better_by(v, plain_imp_se.get(k))}" for k, v in plain_imp.items())
            + ")"
        )
    if summary.get("fall_rate_difference") is not None:
        falls = falls_more_by(
            summary["fall_rate_difference"], summary.get("fall_rate_difference_se")
        )
        improvements += f"; best {falls}"
    return improvements


def _caveat(summary: dict[str, Any]) -> str:
    """Why the printed improvement is no result: the smoke preset, or too few scenarios."""
    scenarios = summary.get("final_scenarios")
    if summary.get("preset") == "smoke":
        return "; smoke preset, too short to judge: a check that the run is wired, not a result"
    if scenarios and scenarios < FEW_SCENARIOS:
        return (
            f"; from {scenarios} paired scenarios only: a check that the run is wired, not a result"
        )
    return ""


def print_summary(
    summary: dict[str, Any], space_names: list[str] | None, discrete: list[bool] | None = None
) -> None:
    from coadapt_core.cli.common import wide_console

    names = space_names or [f"x{i}" for i in range(len(summary["best_design"]))]
    table = _summary_table(summary, names, discrete or [False] * len(names))
    console = wide_console(table)
    console.print(table)
    blocks, scenarios = summary.get("final_blocks"), summary.get("final_scenarios")
    if summary.get("cost_rule"):
        from coadapt_core.costs import CostRule

        rule = CostRule.from_config(summary | {"cost_cap": summary.get("cost_cap")})
        console.print(
            f"cost: {rule.describe()}; plain mean: the paper's eq. 4 over the same scenarios"
        )
    if summary.get("best_is_nominal"):
        console.print(
            "no candidate beat the nominal design without falling more often than it: the "
            "nominal design stands"
        )
    steps = f" of {summary['eval_steps']} steps" if summary.get("eval_steps") else ""
    block_word = "block" if blocks == 1 else "blocks"
    size = (
        f"{scenarios} paired scenarios{steps} per design ({blocks} {block_word}; "
        if scenarios
        else f"paired scenarios{steps} ("
    )
    console.print(
        f"costs: per step over the final check's {size}`coadapt run` protocol, not comparable with "
        "other commands or sizes); SE = standard error over scenarios"
    )
    if "starting_policy" in summary:
        policy = summary["starting_policy"] or "none (trained from scratch in this run)"
        console.print(f"starting policy: {policy}")
    if "numerics" in summary:  # which numerics trained and evaluated (coadapt_core.numerics)
        from coadapt_core.numerics import numerics_text

        console.print(
            f"numerics: {numerics_text(summary['numerics'])}", markup=False, highlight=False
        )
    if summary.get("preset") == "smoke":  # 20 steps per scenario: nothing about walking is known
        console.print(
            f"walking gate: too short to judge (smoke preset, {summary.get('eval_steps')} steps "
            "per scenario; `--preset quick` is judged)"
        )
    elif summary.get("reliable") is False:
        console.print(f"[bold red]UNRELIABLE[/]: {summary.get('reliability')}")
    elif summary.get("reliability"):  # passed, not judged or not measured: said as well
        console.print(f"walking gate: {summary.get('reliability')}")
    console.print(
        f"improvement over nominal (final check{_caveat(summary)}): {_improvements(summary)}; "
        f"interactions {summary['interactions']:,} "
        f"(training {summary['train_interactions']:,}, "
        f"evaluation {summary['eval_interactions']:,}, "
        f"final check {summary['final_interactions']:,}); {summary['real_evaluations']} real and "
        f"{summary['surrogate_evaluations']} surrogate rounds; "
        f"{fmt_duration(summary['seconds'])} wall clock"
    )
    if summary.get("refinement"):
        console.print(refinement_line(summary["refinement"]), markup=False, highlight=False)
    if summary.get("pareto_front"):
        from coadapt_core.cli.front import front_lines

        for line in front_lines(summary["pareto_front"], with_se):
            console.print(line, markup=False, highlight=False, soft_wrap=True)
    _print_warnings(console, summary)


def refinement_line(ref: dict[str, Any]) -> str:
    """The refinement stage (`refine_with`) in one line: its real rounds, start and accepted
    costs with their SEs (the run's scenarios, the final policy), whether the final check
    chose its design."""

    def cost(value: Any, se: Any) -> str:
        return "?" if value is None else with_se(float(value), se)

    step = ref.get("chosen_step")
    if ref.get("chosen"):
        verdict = "its design won the final check"
    elif step == 0:
        verdict = "the final check chose its start (the search's design)"
    elif step is not None:
        verdict = f"the final check chose its step {step}'s design (not the last accepted)"
    else:
        verdict = {False: "the final check chose another design"}.get(ref.get("chosen"), "")
    return (
        f"refinement ({ref['with']}, {ref['rounds']} real rounds on the run's scenarios): "
        f"start {cost(ref.get('start_cost'), ref.get('start_cost_se'))} -> "
        f"{cost(ref.get('center_cost'), ref.get('center_cost_se'))}, "
        f"{ref.get('accepted_steps', 0)} of {max(ref['rounds'] - 1, 0)} steps accepted; "
        f"{verdict or 'not checked'}"
    )


def _print_warnings(console: Any, summary: dict[str, Any]) -> None:
    """The run's warnings (`coadapt.cautions`; a summary written before they were recorded:
    judged now), one line each."""
    from rich.markup import escape

    from coadapt_core.coadapt.cautions import run_warnings, surrogate_note, weak_surrogate

    if surrogate_note(summary) and not weak_surrogate(
        summary
    ):  # a weak one is said below, with its rounds
        console.print(surrogate_note(summary))
    warnings = summary["warnings"] if "warnings" in summary else run_warnings(summary)
    for warning in warnings:
        console.print(f"[bold yellow]warning[/]: {escape(warning)}")
    if summary.get("preset") == "quick":
        console.print(quick_preset_note(len(warnings)))


def quick_preset_note(warnings: int) -> str:
    """What the quick preset (the default) is for and how to get a firmer answer, so that
    its warnings read as guidance (README, "The first run")."""
    said = (
        ("the warning above says" if warnings == 1 else f"the {warnings} warnings above say")
        + " where it is thin (guidance, not a failure)"
        if warnings
        else "nothing flagged at this size"
    )
    return (
        "quick preset: a first answer in minutes (one seed, 3 outer iterations, a small final "
        f"check); {said}. For a firmer answer: more seeds (--seed 1, --seed 2, or `coadapt "
        'grid`), then `--preset paper` (about 50 x the interactions); README, "The first run"'
    )


def report(result: Any, as_json: bool) -> None:
    """The run's JSON line, or its table and folder."""
    summary = result.summary
    if as_json:
        print(json.dumps(result.json_line()))
        return
    names, discrete = None, None
    try:
        from coadapt_core.design_space import DesignSpace

        space = DesignSpace.from_dict(summary["final_space"])
        names = space.names
        discrete = [not hasattr(v, "low") for v in space.variables]
    except Exception:
        names = None
    print_summary(summary, names, discrete)
    print(f"run folder: {result.run_dir}")
