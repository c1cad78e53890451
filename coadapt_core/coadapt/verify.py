"""Whether a run's answer holds with a controller of its own (`coadapt verify`, issue 60).

A co-design answer is measured with the universal policy that found it; a policy can be
uneven across designs. From the run's universal policy, one *specialist* is fine-tuned at
each verified design (the run's best, or for several objectives the chosen design and the
front's extremes) and one at the nominal design, every one with the same interaction budget
and the same seeds. The run's paired final-check protocol then scores each design with its
own specialist, and the universal policy beside it, on the same scenario blocks (the run's
`scenario_seed(seed, b)`, b = 1, 2, ...): at least as many blocks as the run's own final
check spent, more until the first verified design's improvement with specialists is at least
`SIGNIFICANCE_RATIO` paired standard errors or `final_max_blocks` are spent.

Per verified design: the improvement over the nominal design with specialists and with the
universal policy, each with its paired standard error, the plain mean and fall-rate
difference beside each, the difference of the two improvements with its standard error (one
bootstrap resampling the scenarios of all four rows jointly) and a verdict (`verdict`).

Everything lives in the run folder under `verify/<key>/` (`key`: budget and seed): the
specialists' checkpoints, a state written after every training chunk and every scenario
block (`state.json`), so a verification cut off continues from its last state, and the
result (`verification.json`). Nothing here names a plugin: the run's recorded config says
which robot, simulator and objectives to build. The request and its checks live in
`verify_plan.py`, the result and its verdict in `verify_result.py`; this module trains and
evaluates.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from coadapt_core.coadapt.final_check import SIGNIFICANCE_RATIO
from coadapt_core.coadapt.verify_plan import (
    DEFAULT_BUDGETS,
    RESULT,
    STATE,
    STATE_FORMAT,
    VERIFY_DIR,
    VERIFY_SEED,
    NothingToVerify,
    Plan,
    _sha256,
    default_factories,
    plan_verification,
    seed_at,
    verify_key,
)
from coadapt_core.coadapt.verify_result import (
    _pooled,
    read_verifications,
    result_of,
    specialist_policy,
    verdict,
)
from coadapt_core.costs import compare_designs
from coadapt_core.errors import UserError
from coadapt_core.fitness import CoadaptationBackend, RealFitness
from coadapt_core.scenarios.seeds import scenario_seed
from coadapt_core.statefile import read_json, write_json

__all__ = [
    "DEFAULT_BUDGETS",
    "VERIFY_DIR",
    "VERIFY_SEED",
    "NothingToVerify",
    "Plan",
    "default_factories",
    "plan_verification",
    "read_verifications",
    "result_of",
    "seed_at",
    "specialist_policy",
    "verdict",
    "verify",
    "verify_key",
]


# -- the state -----------------------------------------------------------------------------------
def _new_state(plan: Plan) -> dict[str, Any]:
    return {
        "format": STATE_FORMAT,
        "run_id": plan.run_id,
        "budget": plan.budget,
        "seed": plan.seed,
        "chunk": plan.chunk,
        "designs": {role: [float(x) for x in d] for role, d in plan.designs.items()},
        "universal": str(plan.universal),
        "universal_sha256": _sha256(plan.universal),
        "specialists": {},
        "blocks": [],
        "seconds": 0.0,
        "result": None,
    }


def _load_state(plan: Plan) -> dict[str, Any] | None:
    path = plan.folder / STATE
    if not path.is_file():
        return None
    data = read_json(path, what="verification state")
    if not isinstance(data, dict) or data.get("format") != STATE_FORMAT:
        raise UserError(f"'{path}' is not a coadapt verification state", field="run")
    wanted = {role: [float(x) for x in d] for role, d in plan.designs.items()}
    if data.get("designs") != wanted:
        # other designs at the same budget and seed: the specialists of designs both ask for
        # are kept (the same design, budget, seeds and universal policy: the same policy);
        # the others are trained, and the paired check is run again for the new set
        old = data.get("designs") or {}
        data["specialists"] = {
            role: spec
            for role, spec in (data.get("specialists") or {}).items()
            if role in wanted and old.get(role) == wanted[role] and not spec.get("same_as")
        }
        data.update(designs=wanted, blocks=[], result=None)
    if data.get("universal_sha256") != _sha256(plan.universal):
        raise UserError(
            f"{path.parent} started from another universal policy than '{plan.universal}'",
            field="checkpoint",
        )
    return data


def specialist_file(role: str) -> str:
    return f"checkpoints/specialist-{role}.pt"


def _partial_file(role: str) -> str:
    return f"checkpoints/specialist-{role}-partial.pt"


# -- the verification ----------------------------------------------------------------------------
ProgressFn = Callable[[str], None]


def verify(
    plan: Plan,
    *,
    progress: ProgressFn | None = None,
    factory: Callable[[int], CoadaptationBackend] | None = None,
    eval_factory: Callable[[int], CoadaptationBackend] | None = None,
) -> dict[str, Any]:
    """Fine-tune the specialists, run the paired blocks, return (and write) the result; a
    verification whose state is in the plan's folder continues from it."""
    say = progress or (lambda _line: None)
    if factory is None or eval_factory is None:
        made = default_factories(plan)
        factory, eval_factory = factory or made[0], eval_factory or made[1]
    state = _load_state(plan) or _new_state(plan)
    if state.get("result") is not None:
        return state["result"]
    plan.folder.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()

    def save() -> None:
        nonlocal started
        now = time.perf_counter()
        state["seconds"] = float(state["seconds"]) + now - started
        started = now
        write_json(plan.folder / STATE, state)

    save()
    trained: dict[bytes, str] = {}
    for role, design in plan.designs.items():
        key = np.asarray(design, dtype=np.float64).tobytes()
        if key in trained:  # the same design: the same specialist (same seeds, same budget)
            same = trained[key]
            state["specialists"][role] = dict(state["specialists"][same], same_as=same)
            continue
        _train_specialist(plan, state, role, design, factory, save, say)
        trained[key] = role
    _evaluate(plan, state, factory, eval_factory, save, say)
    state["result"] = result_of(plan, state)
    save()
    state["result"]["seconds"] = float(state["seconds"])
    write_json(plan.folder / STATE, state)
    write_json(plan.folder / RESULT, state["result"])
    return state["result"]


def _train_specialist(
    plan: Plan,
    state: dict[str, Any],
    role: str,
    design: np.ndarray,
    factory: Callable[[int], CoadaptationBackend],
    save: Callable[[], None],
    say: ProgressFn,
) -> None:
    """Fine-tune `role`'s specialist in chunks of `plan.chunk` interactions, its backend and
    the state written after each; a state with the chunks done continues after them."""
    record = state["specialists"].setdefault(
        role, {"done": 0, "chunk": 0, "seconds": 0.0, "finished": False, "rewards": []}
    )
    if record["finished"]:
        return
    backend = factory(seed_at(plan.seed, VERIFY_SEED, 0))
    try:
        if record["done"] > 0:
            backend.load(str(plan.folder / _partial_file(role)))
        else:
            record["start"] = _fingerprint(backend)
        while record["done"] < plan.budget:
            left = plan.budget - record["done"]
            say(f"specialist {role}: {record['done']:,} of {plan.budget:,} interactions")
            result = backend.train(
                np.asarray(design, dtype=float)[None, :],
                min(plan.chunk, left),
                seed=seed_at(plan.seed, VERIFY_SEED, 1, record["chunk"]),
            )
            if int(result.steps) <= 0:
                break
            record["done"] += int(result.steps)
            record["chunk"] += 1
            record["seconds"] += float(result.seconds)
            record["rewards"].append(float(result.mean_reward))
            path = plan.folder / (
                specialist_file(role) if record["done"] >= plan.budget else _partial_file(role)
            )
            path.parent.mkdir(parents=True, exist_ok=True)
            backend.save(str(path))
            if record["done"] >= plan.budget:
                record["finished"] = True
                record["checkpoint"] = specialist_file(role)
            save()
        (plan.folder / _partial_file(role)).unlink(missing_ok=True)
        say(f"specialist {role}: {record['done']:,} interactions in {record['seconds']:.0f} s")
    finally:
        _close(backend)


def _fingerprint(backend: Any) -> float | None:
    """A number that changes with the policy's weights (the actor's parameters summed), kept
    to show where a specialist started."""
    ppo = getattr(backend, "ppo", None)
    if ppo is None:
        return None
    try:
        return float(sum(float(p.detach().double().sum()) for p in ppo.actor.parameters()))
    except AttributeError:
        return None


def _close(backend: Any) -> None:
    close = getattr(backend, "close", None)
    if callable(close):
        close()


def _evaluate(
    plan: Plan,
    state: dict[str, Any],
    factory: Callable[[int], CoadaptationBackend],
    eval_factory: Callable[[int], CoadaptationBackend],
    save: Callable[[], None],
    say: ProgressFn,
) -> None:
    """Paired scenario blocks: each design with its specialist, then every design with the
    universal policy, on `scenario_seed(run seed, b)`; the state written after each block."""
    c = plan.config
    roles = plan.roles
    designs = np.stack([plan.designs[r] for r in roles])
    while True:
        done = len(state["blocks"])
        if done >= plan.min_blocks and (done >= plan.max_blocks or _settled(plan, state)):
            return
        block = done + 1
        say(f"paired check, scenario block {block}")
        seed = scenario_seed(c.seed, block)
        fits = []
        for role in roles:
            spec = state["specialists"][role]
            backend = factory(seed_at(plan.seed, VERIFY_SEED, 0))
            try:
                backend.load(str(plan.folder / spec["checkpoint"]))
                fits.append(
                    backend.real_fitness(
                        plan.designs[role][None, :],
                        plan.objectives,
                        agents=c.evaluation_agents,
                        steps=c.eval_steps,
                        seed=seed,
                    )
                )
            finally:
                _close(backend)
        universal = eval_factory(seed_at(plan.seed, VERIFY_SEED, 2))
        try:
            fits.append(
                universal.real_fitness(
                    designs,
                    plan.objectives,
                    agents=c.evaluation_agents,
                    steps=c.eval_steps,
                    seed=seed,
                )
            )
        finally:
            _close(universal)
        state["blocks"].append(_block_of(fits))
        save()


def _block_of(fits: list[RealFitness]) -> dict[str, Any]:
    if any(f.per_scenario is None for f in fits):
        raise UserError(
            "the backend gives no per-scenario costs: a paired check cannot be run", field="run"
        )
    per = np.concatenate([np.asarray(f.per_scenario, dtype=float) for f in fits])
    falls = (
        np.concatenate([np.asarray(f.scenario_falls, dtype=bool) for f in fits])
        if all(f.scenario_falls is not None for f in fits)
        else np.zeros(per.shape[:2], dtype=bool)
    )
    return {
        "per_scenario": per,
        "falls": falls,
        "interactions": int(sum(int(f.interactions) for f in fits)),
        "seconds": float(sum(float(f.seconds) for f in fits)),
    }


def _settled(plan: Plan, state: dict[str, Any]) -> bool:
    """The first verified design's improvement with specialists is at least
    SIGNIFICANCE_RATIO paired standard errors (the run's final-check rule)."""
    per, falls = _pooled(state)
    n = len(plan.roles)
    first = plan.objectives[0]
    comp = compare_designs(plan.rule, plan.objectives, per[:n], falls[:n], 0, n - 1)
    o = comp["objectives"][first.name]
    se = o["improvement_se"]
    return bool(np.isfinite(se) and abs(o["improvement"]) >= SIGNIFICANCE_RATIO * se)
