"""Training until the policy walks: the walking gate at the nominal design and the four corners
of the design range, checked as training goes (`coadapt train --until-walks`,
`benchmarks/time_to_walk.py`).

A check writes a checkpoint of now and evaluates it as `coadapt train`'s closing verdict does
(`evaluate_checkpoint` under `VERDICT_COMMAND`, randomization as in training) at five designs:
the nominal one (clipped into the trained range) and the range's corners (`corners`). It walks
when the walking gate (`coadapt_core.coadapt.reliability`) holds at all five. A check leaves
the training's random draws as they were (`training_draws_kept`): the evaluation seeds the
global generators, and without the restore a run checked every iteration would draw other
actions than one checked once.

`train_until_walks` drives a `Runner` one iteration at a time under an interaction budget and
an optional training wall-clock budget (the checks outside it), checking every `check_every`
iterations and once more when a budget runs out, and stops at the first check that walks.
With `pseudo_catch_up` > 0 the pseudo-critics are paused meanwhile (`PPO.pseudo_paused`: no
targets, no regression; the policy's training draws and weights are those of a run that
trains them, to the bit) and, once a check walks, fitted for that many iterations on the
walking policy's rollouts with the policy frozen (`fit_pseudo_critics`), so the checkpoint
a co-design starts from carries trained pseudo-critics.
"""

from __future__ import annotations

import contextlib
import random
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: the five designs a check judges, in this order
GATE_DESIGNS = ("nominal", "lower", "upper", "alternate", "alternate_mirror")


def corners(space: Any) -> dict[str, np.ndarray]:
    """The nominal design's four companions: all lower bounds, all upper, and the two that
    alternate lower/upper by dimension."""
    lo, hi = np.asarray(space.lower, float), np.asarray(space.upper, float)
    odd = np.arange(len(lo)) % 2 == 1
    return {
        "lower": lo,
        "upper": hi,
        "alternate": np.where(odd, hi, lo),
        "alternate_mirror": np.where(odd, lo, hi),
    }


def gate_designs(robot: Any, space: Any) -> dict[str, np.ndarray]:
    """{name: design} of `GATE_DESIGNS`: the robot's nominal design clipped into `space`, then
    the space's corners."""
    nominal = np.asarray(robot.nominal_design(space.is_mixed), dtype=float)
    return {"nominal": np.clip(nominal, space.lower, space.upper), **corners(space)}


@contextlib.contextmanager
def training_draws_kept() -> Iterator[None]:
    """Within: anything (an evaluation that seeds the global generators); after: torch's
    (and CUDA's, when initialised), numpy's and Python's global random states as before."""
    import torch

    states = torch.get_rng_state(), np.random.get_state(), random.getstate()
    cuda = torch.cuda.get_rng_state_all() if torch.cuda.is_initialized() else None
    try:
        yield
    finally:
        torch.set_rng_state(states[0])
        np.random.set_state(states[1])
        random.setstate(states[2])
        if cuda is not None:
            torch.cuda.set_rng_state_all(cuda)


def worst_design(designs: dict[str, dict[str, Any]], gate: Any = None) -> str:
    """The design furthest from the gate: the largest relative shortfall of survival below
    its bar or of the tracking ratio above its bar (a passing design's is <= 0)."""
    from coadapt_core.coadapt.reliability import WALKING_GATE

    gate = gate or WALKING_GATE

    def shortfall(d: dict[str, Any]) -> float:
        s, r = d.get("survival"), d.get("tracking_ratio")
        s = -np.inf if s is None else (gate.min_survival - s) / gate.min_survival
        r = -np.inf if r is None else (r - gate.max_tracking_ratio) / gate.max_tracking_ratio
        return float(max(s, r))

    return max(designs, key=lambda name: shortfall(designs[name]))


def check_walking(
    trainer: Any,
    path: Path,
    *,
    agents: int,
    seconds: float,
    seed: int,
    device: str = "cpu",
) -> dict[str, Any]:
    """Write `trainer`'s checkpoint to `path` and judge it at `gate_designs` (`agents` agents
    x `seconds` under `VERDICT_COMMAND` each, on the trainer's terrain), the training's
    random draws kept. {'walking': all five walk, 'worst': `worst_design`, 'designs': {name:
    {'design', 'survival', 'tracking_ratio', 'vx_mean', 'walking'}}}."""
    from coadapt_core.experiments.evaluate import VERDICT_COMMAND, evaluate_checkpoint

    path = trainer.save(path)
    out: dict[str, dict[str, Any]] = {}
    with training_draws_kept():
        for name, design in gate_designs(trainer.robot, trainer.design_space).items():
            r = evaluate_checkpoint(
                path,
                trainer.robot,
                trainer.simulator_cls,
                design,
                terrain=trainer.terrain,
                command=VERDICT_COMMAND,
                agents=agents,
                seconds=seconds,
                device=device,
                seed=seed,
            )
            out[name] = {"design": [round(float(x), 4) for x in design]} | {
                k: r[k] for k in ("survival", "tracking_ratio", "vx_mean", "walking")
            }
    return {
        "walking": all(d["walking"] is True for d in out.values()),
        "worst": worst_design(out),
        "designs": out,
    }


def check_text(row: dict[str, Any]) -> str:
    """One check as the progress line shows it: 'walks' or the worst design's figures."""
    d = row["designs"][row["worst"]]
    ratio = d["tracking_ratio"]
    figures = (
        f"survival {d['survival']:.2f}, ratio "
        + ("?" if ratio is None else f"{ratio:.2f}")
        + f", vx {d['vx_mean']:.2f}"
    )
    if row["walking"]:
        return f"check it {row['iteration']}: walks (worst {row['worst']}: {figures})"
    return f"check it {row['iteration']}: no, worst {row['worst']}: {figures}"


@dataclass
class UntilWalks:
    """What `train_until_walks` did: whether a check walked, the interactions (this call's)
    and training seconds (the run's count, a resumed checkpoint's included; checks excluded)
    until then or until the budget ran out, the seconds this call's checks took, the budget
    that ran out ('interactions', 'seconds'; None when it walked) and every check's row."""

    walked: bool
    interactions: int
    train_seconds: float
    check_seconds: float
    budget: str | None
    checks: list[dict[str, Any]] = field(default_factory=list)
    #: the training seconds the run had counted before this call (a resumed checkpoint's
    #: `train_seconds`): `train_seconds` includes them
    carried_seconds: float = 0.0
    #: the pseudo-critics' fit after the check that walked (`fit_pseudo_critics`): its
    #: interactions and seconds (0 when they trained all along or nothing walked)
    catch_up_interactions: int = 0
    catch_up_seconds: float = 0.0


def fit_pseudo_critics(
    runner: Any,
    iterations: int,
    on_iteration: Callable[[Any], None] | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> tuple[int, float]:
    """Fit the pseudo-critics for `iterations` iterations on the rollouts of the policy as it
    is, the policy frozen (`PPO.freeze_policy`: actor, critic, their optimizer and the
    observation normalisers stay as they were), then let the policy learn again. Returns
    the interactions and seconds it took."""
    trainer = runner.trainer
    first, start = trainer.total_steps, clock()
    trainer.ppo.freeze_policy()  # and unpauses the pseudo-critics
    try:
        runner.run(iterations, on_iteration)
    finally:
        trainer.ppo.policy_frozen = False
    return trainer.total_steps - first, clock() - start


def _row(trainer: Any, stats: Any, train_seconds: float, seconds: float, result: dict) -> dict:
    """A check's row: where the training was, what the check took and what it found."""
    return {
        "iteration": trainer.iteration,
        "interactions": trainer.total_steps,
        "train_seconds": round(train_seconds, 2),
        "check_seconds": round(seconds, 2),
        "mean_reward": round(float(stats.mean_reward), 5),
        **result,
    }


def train_until_walks(
    runner: Any,
    *,
    steps: int,
    check: Callable[[], dict[str, Any]],
    check_every: int,
    max_seconds: float | None = None,
    on_iteration: Callable[[Any], None] | None = None,
    on_check: Callable[[dict[str, Any]], None] | None = None,
    clock: Callable[[], float] = time.perf_counter,
    pseudo_catch_up: int = 0,
) -> UntilWalks:
    """Train `runner` for at most `steps` interactions (this call's) and until the training
    wall clock `trainer.train_seconds` (the checks not counted; a resumed checkpoint's count
    goes on) reaches `max_seconds` (None: no limit), calling `check()` (a
    `check_walking`) after every `check_every` iterations and after the last one a budget
    allows; stop at the first check that walks. `on_iteration` sees each iteration's
    statistics, `on_check` each check's row: the check's result with 'iteration',
    'interactions', 'train_seconds', 'check_seconds' and 'mean_reward'. `pseudo_catch_up` > 0:
    the pseudo-critics pause meanwhile and, when a check walked, `fit_pseudo_critics` runs
    for that many iterations after it (the checkpoint the check wrote has them untrained:
    write it again)."""
    trainer = runner.trainer
    paused = pseudo_catch_up > 0 and trainer.ppo.pseudo_critic is not None
    trainer.ppo.pseudo_paused = paused
    first_steps = trainer.total_steps
    iterations = runner.iterations_for(steps)
    carried, check_seconds = trainer.train_seconds, 0.0
    checks: list[dict[str, Any]] = []
    budget: str | None = None

    mark = [0.0, 0.0]  # the count and the clock when the iteration under way began

    def counted(stats: Any) -> None:
        # the count moves on before anything sees the iteration: a Ctrl-C's checkpoint, written
        # after this, carries it
        trainer.train_seconds = mark[0] + clock() - mark[1]
        if on_iteration is not None:
            on_iteration(stats)

    for done in range(1, iterations + 1):
        mark[:] = trainer.train_seconds, clock()
        stats = runner.run(1, counted)
        trainer.train_seconds = train_seconds = mark[0] + clock() - mark[1]
        out_of_time = max_seconds is not None and train_seconds >= max_seconds
        if not (done % check_every == 0 or done == iterations or out_of_time):
            continue
        tick = clock()
        result = check()
        check_seconds += clock() - tick
        row = _row(trainer, stats, train_seconds, clock() - tick, result)
        checks.append(row)
        if on_check is not None:
            on_check(row)
        if row["walking"]:
            break
        if out_of_time:
            budget = "seconds"
            break
    else:
        budget = "interactions"
    walked = bool(checks and checks[-1]["walking"])
    out = UntilWalks(
        walked,
        trainer.total_steps - first_steps,
        trainer.train_seconds,
        check_seconds,
        budget,
        checks,
        carried_seconds=carried,
    )
    trainer.ppo.pseudo_paused = False
    if paused and walked:
        fit = fit_pseudo_critics(runner, pseudo_catch_up, on_iteration, clock)
        out.catch_up_interactions, out.catch_up_seconds = fit
    return out


__all__ = [
    "GATE_DESIGNS",
    "UntilWalks",
    "check_text",
    "check_walking",
    "corners",
    "fit_pseudo_critics",
    "gate_designs",
    "train_until_walks",
    "training_draws_kept",
    "worst_design",
]
