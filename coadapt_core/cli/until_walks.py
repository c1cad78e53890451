"""`coadapt train --until-walks`: its options checked against the others, the clause the
start line gives it, the training loop with a walking check every --check-every iterations
(`coadapt_core.experiments.walking_check.train_until_walks`: each check's row in
OUT/checks.jsonl, the one that walks kept as OUT/walks.pt) and its last lines: walked (where
the checkpoint is, how to ship it) or which budget ran out (exit `EXIT_NOT_WALKING`)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common import fail

#: `coadapt train --until-walks`'s exit status when a budget ran out before a check walked
EXIT_NOT_WALKING = 3
#: --pseudo-catch-up's default: iterations of the pseudo-critics' fit on the walking policy
#: (docs/training.md, "Time to walk", has the measurement)
PSEUDO_CATCH_UP = 50


def check_options(values: dict[str, Any]) -> None:
    """--until-walks's options, checked against the others (one line, exit 2)."""
    if not values["until_walks"]:
        if values["max_seconds"] is not None:
            fail("--max-seconds is the wall-clock budget of --until-walks; give --until-walks too")
        return
    if values["pseudo_critics_only"]:
        fail("--until-walks trains the policy; --pseudo-critics-only keeps it as loaded")
    if values["steps"] <= 0:
        fail(f"--steps with --until-walks is the interaction budget, >= 1, got {values['steps']}")


def check_check_seconds(values: dict[str, Any], trainer: Any) -> None:
    """--check-seconds long enough for the walking gate to judge tracking (`MIN_JUDGED_STEPS`
    policy steps of the trainer's simulator): over fewer a check never says "walks"."""
    from coadapt_core.coadapt.reliability import MIN_JUDGED_STEPS

    dt = float(trainer.env.dt)
    if round(values["check_seconds"] / dt) < MIN_JUDGED_STEPS:
        fail(
            f"check_seconds must be >= {MIN_JUDGED_STEPS * dt:g} with --until-walks (the "
            f"walking gate judges tracking over >= {MIN_JUDGED_STEPS} policy steps of "
            f"{dt:g} s), got {values['check_seconds']:g}"
        )


def announced(values: dict[str, Any]) -> str:
    """The clause `coadapt train`'s start line gives --until-walks ("" without it): the gate's
    designs, how often and how long it is checked, and the budgets."""
    if not values["until_walks"]:
        return ""
    return (
        f", until it walks: the walking gate at the nominal design and the four corners "
        f"every {values['check_every']} iterations ({values['check_agents']} agents x "
        f"{values['check_seconds']:g} s each), within {values['steps']:,} interactions"
        + (
            f" and {values['max_seconds']:g} s of training"
            if values["max_seconds"] is not None
            else ""
        )
        + (
            f", the pseudo-critics fitted for {values['pseudo_catch_up']} iterations once it "
            "walks (not before)"
            if values["pseudo_catch_up"]
            else ""
        )
    )


def train_until_walking(values: dict[str, Any], runner: Any, show: Any, show_check: Any) -> Any:
    """Train until a check walks or a budget runs out (`train_until_walks`): each check's
    checkpoint is OUT/check.pt, its row appended to OUT/checks.jsonl (and, with --quiet,
    printed as {"walking_check": row}); the one that walks becomes OUT/walks.pt."""
    from coadapt_core.experiments.walking_check import check_text, check_walking, train_until_walks
    from coadapt_core.learning.runner import TrainingInterrupted

    trainer, out = runner.trainer, runner.out

    def check() -> dict[str, Any]:
        try:
            return check_walking(
                trainer,
                out / "check.pt",
                agents=values["check_agents"],
                seconds=values["check_seconds"],
                seed=values["seed"],
                device=values["device"],
            )
        except KeyboardInterrupt:  # Ctrl-C during a check: as during an iteration
            raise TrainingInterrupted(runner.checkpoint(), trainer.iteration) from None

    def on_check(row: dict[str, Any]) -> None:
        with (out / "checks.jsonl").open("a") as log:
            log.write(json.dumps(row) + "\n")
        if values["quiet"]:
            print(json.dumps({"walking_check": row}), flush=True)
        show_check(check_text(row))
        if row["walking"]:
            (out / "check.pt").replace(out / "walks.pt")

    walks = train_until_walks(
        runner,
        steps=values["steps"],
        check=check,
        check_every=values["check_every"],
        max_seconds=values["max_seconds"],
        on_iteration=show,
        on_check=on_check,
        pseudo_catch_up=values["pseudo_catch_up"],
    )
    if walks.catch_up_interactions:  # walks.pt again, with the pseudo-critics fitted
        trainer.save(out / "walks.pt")
    return walks


def walks_report(
    values: dict[str, Any], robot: str, trainer: Any, walks: Any, weights: Path
) -> None:
    """--until-walks's last lines: walked (the time and interactions it took, where the
    checkpoint is and how to ship it), or which budget ran out (exit `EXIT_NOT_WALKING`)."""
    from coadapt_core.experiments.walking_check import check_text

    out, quiet = values["out"], values["quiet"]
    last = walks.checks[-1] if walks.checks else None
    n = len(walks.checks)
    notes = [
        f"{walks.carried_seconds:.0f} s of it before the resume, as the checkpoint counted"
        if walks.carried_seconds
        else "",
        f"the {n} check{'s' if n != 1 else ''} took {walks.check_seconds:.0f} s more",
        f"the pseudo-critics' fit on the walking policy {walks.catch_up_interactions:,} "
        f"interactions and {walks.catch_up_seconds:.0f} s"
        if walks.catch_up_interactions
        else "",
    ]
    took = (
        f"{walks.interactions:,} interactions and {walks.train_seconds:.0f} s of training "
        f"({'; '.join(x for x in notes if x)})"
    )
    if quiet:
        summary = {
            "walked": walks.walked,
            "interactions": walks.interactions,
            "train_seconds": round(walks.train_seconds, 2),
            "carried_seconds": round(walks.carried_seconds, 2),
            "check_seconds": round(walks.check_seconds, 2),
            "pseudo_catch_up_interactions": walks.catch_up_interactions,
            "pseudo_catch_up_seconds": round(walks.catch_up_seconds, 2),
            "budget": walks.budget,
            "checkpoint": str(out / "walks.pt") if walks.walked else None,
            "last_check": last,
        }
        print(json.dumps({"until_walks": summary}), flush=True)
    if walks.walked:
        policies = f"{values['terrain']}-mixed.pt" if values["mixed"] else f"{values['terrain']}.pt"
        print(
            f"walks at the nominal design and the four corners after {took}: "
            f"{check_text(last)}. Kept: {out / 'walks.pt'} (the checkpoint) and {weights} (its "
            f"weights). Ship it as {robot}'s policy: copy {weights} to policies/{policies} in "
            f"the robot's folder (a spec robot: {robot}/policies/{policies} beside robot.yaml); "
            f"confirm with coadapt eval --robot {robot} --checkpoint {out / 'walks.pt'} "
            "--agents 50 --seconds 20",
            file=sys.stderr,
        )
        return
    budget = (
        f"the wall-clock budget (--max-seconds {values['max_seconds']:g})"
        if walks.budget == "seconds"
        else f"the interaction budget (--steps {values['steps']})"
    )
    print(
        f"not walking yet: {budget} ran out after {took}; "
        + (f"last {check_text(last)}" if last else "no check ran")
        + f". Go on with coadapt train --robot {robot} --terrain {values['terrain']}"
        + (" --mixed" if values["mixed"] else "")
        + f" --resume {out / 'model_final.pt'} --until-walks --out {out}"
        + (
            f" --max-seconds S (S above {walks.train_seconds:.0f}: the resumed run's count "
            "goes on from there)"
            if walks.budget == "seconds"
            else ""
        ),
        file=sys.stderr,
    )
    raise typer.Exit(EXIT_NOT_WALKING)
