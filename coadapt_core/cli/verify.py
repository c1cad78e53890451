"""`coadapt verify`: does a finished run's answer hold with a controller of its own?
(`coadapt_core.coadapt.verify`)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common import ctrl_c_once, fail, interrupted, invocation
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.settings import Int, setting, settings, shared


@settings
class VerifyCommand:
    """`coadapt verify`'s settings."""

    run: str = setting(help="Run folder, or a run id under --runs-dir.", argument="run")
    budget: Int | None = setting(
        None,
        "Interactions each specialist is fine-tuned for (default by the run's preset: smoke "
        "2,000, quick 1,000,000, paper 10,000,000).",
    )
    pick: str | None = setting(
        None,
        "A run of several objectives: chosen (the design it returned; default), extremes (the "
        "front's lowest cost of each objective) or all (both).",
    )
    design: str | None = setting(
        None,
        "Verify this design instead (values comma-separated in the order of the run's design "
        "space); it must lie in the universal policy's range.",
    )
    checkpoint: str | None = setting(
        None,
        "Universal policy the specialists start from (default: the run's last checkpoint); "
        "it must be a policy of the run's robot.",
    )
    runs_dir: Path = setting(Path("runs"), "Where run ids are looked up.")
    #: its own declaration: the default is the run's seed, not CommonOptions' 0
    seed: Int | None = setting(
        None, "Random seed of the specialists' fine-tuning (default: the run's seed).", ge=0
    )
    #: default: the run's store (else coadapt.db beside its runs folder)
    store: Any = shared(CommonOptions)
    threads: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)
    as_json: Any = shared(CommonOptions)


def verify_and_record(plan: Any, store: str | None, say: Any) -> dict[str, Any]:
    """Run a checked verification (`verify.verify`) and record its rows in the run's store
    (`store`, else the one the run recorded, else beside its runs folder); the result says
    where (`store`) or why not."""
    from coadapt_core.coadapt.verify import verify

    result = verify(plan, progress=say)
    result["store"] = record_rows(plan.run_dir, plan.run_id, result, store or plan.config.store)
    return result


def record_rows(
    run_dir: Path, run_id: str, result: dict[str, Any], store: str | None
) -> str | None:
    """The result's rows into the store the run records to; None when it has none or the
    run is not in it (one line says so)."""
    from coadapt_core.results.storage import store_url_for_run
    from coadapt_core.results.store import ResultsStore

    url = store_url_for_run(run_dir, store or None)
    if url is None:
        return None
    with ResultsStore(url) as st:
        if not st.has_run(run_id):
            print(
                f"note: store {url} does not hold run {run_id}; rows not recorded", file=sys.stderr
            )
            return None
        st.record_verification(run_id, result)
    return url


def print_result(result: dict[str, Any]) -> None:
    """The verification as a few lines on stdout: per verified design both improvements
    with the plain mean and the fall-rate difference beside each, then the verdict line."""

    def pct(x: Any, se: Any = None) -> str:
        if x is None:
            return "-"
        return f"{100 * x:+.1f} ± {100 * se:.1f} %" if se is not None else f"{100 * x:+.1f} %"

    print(
        f"run {result['run_id']}: specialists fine-tuned {result['budget']:,} interactions each "
        f"(seed {result['seed']}), {result['scenarios']} paired scenarios in "
        f"{result['blocks']} blocks, cost rule {result['cost_rule']}"
    )
    for e in result["designs"]:
        print(f"  {e['role']} ({', '.join(f'{x:.3g}' for x in e['design'])}), {e['objective']}:")
        for label, side in (("with specialists", e["specialist"]), ("universal", e["universal"])):
            falls = side.get("fall_rate_difference")
            fall_text = (
                "-"
                if falls is None
                else pct(falls, side.get("fall_rate_difference_se")).replace("%", "points")
            )
            print(
                f"    {label:17s} {pct(side['improvement'], side['improvement_se']):>18s}"
                f"   plain mean {pct(side['improvement_plain'], side['improvement_plain_se'])}"
                f"   fall-rate difference {fall_text}"
            )
        print(f"  verdict: {e['line']}")


def run_stage(result: Any, values: dict[str, Any]) -> None:
    """`coadapt run --verify`: the finished run verified (`coadapt verify`), its rows in the
    run's store; what it found printed before the run's own summary (on stderr with --json)."""
    import contextlib

    from coadapt_core.coadapt.verify import NothingToVerify, plan_verification

    try:
        plan = plan_verification(result.run_dir, budget=values["verify_budget"])
    except NothingToVerify as nothing:
        result.summary["verification"] = {"skipped": str(nothing)}
        print(f"verify: skipped: {nothing}", file=sys.stderr)
        return
    quiet = values.get("quiet")
    found = verify_and_record(
        plan,
        values.get("store"),
        (lambda _line: None) if quiet else (lambda line: print(line, file=sys.stderr)),
    )
    result.summary["verification"] = {
        "key": found["key"],
        "designs": [
            {k: e[k] for k in ("role", "verdict", "difference", "difference_se", "line")}
            for e in found["designs"]
        ],
    }
    with contextlib.redirect_stdout(sys.stderr) if values["as_json"] else contextlib.nullcontext():
        print_result(found)


def register(app: typer.Typer) -> None:
    declared = options_of(VerifyCommand)

    def verify_command(**values: Any) -> None:
        """Fine-tune a specialist policy at the run's best design and one at the nominal
        design from its universal policy (same budget, same seed), repeat its paired final
        check with each design driven by its own specialist, and say whether the answer
        holds, shrinks, grows or does not hold."""
        o = filled(values, declared)
        if o["budget"] is not None and o["budget"] <= 0:
            fail(f"--budget must be a positive number of interactions, got {o['budget']}")
        from coadapt_core.coadapt.verify import plan_verification
        from coadapt_core.design_space import parse_numbers
        from coadapt_core.handoff.run_info import find_run
        from coadapt_core.threads import apply_threads

        run_dir = find_run(o["run"], o["runs_dir"])
        design = None
        if o["design"] is not None:
            design = parse_numbers(
                o["design"], what=f"--design '{o['design']}' must be comma-separated numbers"
            )
        plan = plan_verification(
            run_dir,
            budget=o["budget"],
            pick=o["pick"],
            design=design,
            seed=o["seed"],
            checkpoint=o["checkpoint"],
        )
        apply_threads(o["threads"])
        t0 = time.perf_counter()
        say = (lambda _line: None) if o["quiet"] else (lambda line: print(line, file=sys.stderr))
        with ctrl_c_once():
            try:
                result = verify_and_record(plan, o["store"], say)
            except KeyboardInterrupt:
                # the state written after the last chunk or block: the same command goes on
                import shlex

                interrupted(
                    f"verification of run {plan.run_id} (its state is in {plan.folder})",
                    shlex.join(["coadapt", *invocation()]),
                )
        print_result(result)
        print(
            f"written to {plan.folder} in {time.perf_counter() - t0:.0f} s"
            + (f"; rows in {result['store']}" if result.get("store") else ""),
            file=sys.stderr,
        )
        if o["as_json"]:
            print(json.dumps(result))

    register_command(app, "verify", verify_command, declared)
