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
which robot, simulator and objectives to build.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.coadapt.final_check import SIGNIFICANCE_RATIO
from coadapt_core.costs import (
    CostRule,
    _resamples,
    compare_designs,
    fall_statistics,
    falls_more,
)
from coadapt_core.errors import UserError
from coadapt_core.fitness import CoadaptationBackend, RealFitness
from coadapt_core.objective import Objective
from coadapt_core.scenarios.seeds import scenario_seed
from coadapt_core.statefile import read_json, write_json

#: where verifications live in a run folder
VERIFY_DIR = "verify"
STATE = "state.json"
RESULT = "verification.json"
STATE_FORMAT = "coadapt-verify-1"
#: interactions per specialist by the run's preset (`--budget` overrides)
DEFAULT_BUDGETS = {"smoke": 2_000, "quick": 1_000_000, "paper": 10_000_000}
#: interactions between a specialist's checkpoints (the run's checkpoint_interactions when
#: smaller)
CHUNK = 250_000
#: what `--pick` accepts for a run of several objectives
PICKS = ("chosen", "extremes", "all")
#: the difference of the two improvements counts as a change (grows / shrinks) beyond this
#: many standard errors
CHANGE_RATIO = 2.0
#: seed positions of a verification (`seed_at(seed, VERIFY_SEED, ...)`), apart from the run's
VERIFY_SEED = 60


def seed_at(seed: int, *parts: int) -> int:
    return int(np.random.SeedSequence([seed, *parts]).generate_state(1)[0] % (2**31 - 1))


def verify_key(budget: int, seed: int) -> str:
    return f"b{int(budget)}-s{int(seed)}"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# -- what to verify ----------------------------------------------------------------------------
@dataclass
class Plan:
    """A checked verification request: nothing of it has been written yet."""

    run_dir: Path
    run_id: str
    config: Any  # CoadaptConfig
    summary: dict[str, Any]
    objectives: list[Objective]
    designs: dict[str, np.ndarray]  # role -> design; "nominal" last
    universal: Path  # the universal policy the specialists start from
    budget: int
    seed: int
    chunk: int
    folder: Path  # run_dir / verify / key
    min_blocks: int
    max_blocks: int
    rule: CostRule
    factory: Callable[[int], CoadaptationBackend] | None = None
    eval_factory: Callable[[int], CoadaptationBackend] | None = None

    @property
    def roles(self) -> list[str]:
        return list(self.designs)


def _in_space(space: Any, design: np.ndarray) -> str | None:
    """Why `design` lies outside a checkpoint's design space (its dict), or None."""
    variables = (space or {}).get("variables") or []
    if len(variables) != len(design):
        return f"{len(design)} values, the policy takes {len(variables)}"
    for v, x in zip(variables, design, strict=True):
        lo, hi = float(v.get("low", -np.inf)), float(v.get("high", np.inf))
        if not lo - 1e-9 <= float(x) <= hi + 1e-9:
            return f"{v.get('name', '?')} = {float(x):g} outside [{lo:g}, {hi:g}]"
    return None


def _front_designs(summary: dict[str, Any], pick: str, names: Sequence[str]) -> dict[str, Any]:
    """role -> design of a multi-objective run: `chosen` (the design the run returned),
    `extremes` (the front's lowest cost of each objective), or `all`."""
    front = summary.get("pareto_front") or {}
    out: dict[str, Any] = {}
    if pick in ("chosen", "all"):
        out["chosen"] = summary["best_design"]
    if pick in ("extremes", "all"):
        designs, costs = front.get("designs") or [], front.get("costs") or []
        for name in names:
            if not designs:
                break
            i = int(np.argmin([float(c[name]) for c in costs]))
            out[f"lowest-{name}"] = designs[i]
    return out


def plan_verification(
    run_dir: str | Path,
    *,
    budget: int | None = None,
    pick: str | None = None,
    design: Sequence[float] | None = None,
    seed: int | None = None,
    checkpoint: str | Path | None = None,
    chunk: int | None = None,
) -> Plan:
    """Check a request against the run folder (every refusal a one-line `UserError` naming
    its field, before anything is written) and say what will be done."""
    from coadapt_core.coadapt.config_loading import config_from_dict
    from coadapt_core.coadapt.state import STATE_FILE, load_state
    from coadapt_core.methods import get_method

    run_dir = Path(run_dir).absolute()
    if not (run_dir / STATE_FILE).is_file():
        raise UserError(f"'{run_dir}' is not a run folder (no {STATE_FILE})", field="run")
    state = load_state(run_dir)
    if state.phase != "done" or state.summary is None:
        raise UserError(
            f"run {state.run_id} has not finished (it is at its '{state.phase}' phase: still "
            "running, or cut off); let it finish or resume it with `coadapt run --resume` first",
            field="run",
        )
    summary = dict(state.summary)
    if int(summary.get("final_blocks") or 0) <= 0 or int(summary.get("final_scenarios") or 0) <= 0:
        raise UserError(
            f"run {state.run_id} has no final check with paired scenarios to repeat "
            "(its backend gave no per-scenario costs)",
            field="run",
        )
    config = config_from_dict(state.config)
    if not get_method(config.method).backend_kind.shared_policy:
        raise UserError(
            f"run {state.run_id} ({config.method}) has no universal policy: each of its "
            "designs already has its own",
            field="run",
        )
    if budget is None:
        budget = DEFAULT_BUDGETS.get(str(config.preset), DEFAULT_BUDGETS["quick"])
    if isinstance(budget, bool) or int(budget) <= 0:
        raise UserError(
            f"budget must be a positive number of interactions, got {budget}", field="budget"
        )
    budget = int(budget)
    seed = int(config.seed if seed is None else seed)
    names = list(config.objectives)
    best = np.asarray(summary["best_design"], dtype=float)
    nominal = np.asarray(summary["nominal_design"], dtype=float)
    if design is not None:
        if pick is not None:
            raise UserError("give --design or --pick, not both", field="pick")
        picked: dict[str, Any] = {"design": list(design)}
    elif len(names) > 1:
        pick = pick or "chosen"
        if pick not in PICKS:
            raise UserError(f"--pick must be one of {', '.join(PICKS)}, got '{pick}'", field="pick")
        picked = _front_designs(summary, pick, names)
    else:
        if pick not in (None, "chosen"):
            raise UserError(
                f"--pick '{pick}': run {state.run_id} has one objective and no Pareto front; "
                "leave out --pick to verify its best design",
                field="pick",
            )
        picked = {"best": best}
    universal = (
        Path(checkpoint).absolute()
        if checkpoint is not None
        else run_dir / str(state.backend_checkpoint or "")
    )
    if (not state.backend_checkpoint and checkpoint is None) or not universal.is_file():
        raise UserError(
            f"universal policy '{universal}' does not exist (the run's last checkpoint)",
            field="checkpoint",
        )
    from coadapt_core.learning.checkpoints import read_checkpoint

    header = read_checkpoint(universal)
    if str(header.get("robot")) != str(config.robot):
        raise UserError(
            f"checkpoint '{universal}' is a policy for robot '{header.get('robot')}', the run's "
            f"robot is '{config.robot}'",
            field="checkpoint",
        )
    designs = {role: np.asarray(d, dtype=float) for role, d in picked.items()}
    designs["nominal"] = nominal
    for role, d in designs.items():
        why = _in_space(header.get("design_space"), d)
        if why is not None:
            raise UserError(
                f"design {role} ({', '.join(f'{x:g}' for x in d)}) is outside the policy's "
                f"range: {why}",
                field="design",
            )
    every = int(getattr(config, "checkpoint_interactions", 0) or 0)
    chunk = int(chunk or (min(CHUNK, every) if every else CHUNK))
    blocks = int(summary.get("final_blocks") or 1)
    from coadapt_core.coadapt.search import make_objectives

    return Plan(
        run_dir=run_dir,
        run_id=state.run_id,
        config=config,
        summary=summary,
        objectives=make_objectives(config),
        designs=designs,
        universal=universal,
        budget=budget,
        seed=seed,
        chunk=max(1, chunk),
        folder=run_dir / VERIFY_DIR / verify_key(budget, seed),
        min_blocks=max(blocks, 1),
        max_blocks=max(blocks, int(config.final_max_blocks)),
        rule=CostRule(config.cost_rule, config.cost_cap),
    )


def default_factories(
    plan: Plan,
) -> tuple[Callable[[int], CoadaptationBackend], Callable[[int], CoadaptationBackend]]:
    """(a specialist's backend, starting from the universal policy, with the universal
    training's batch on its one design; the universal policy's, for evaluation), built from
    the run's recorded config."""
    from coadapt_core.coadapt.backends import universal_policy_factory
    from coadapt_core.coadapt.search import uses_mixed_space
    from coadapt_core.plugins import get_registry

    config = plan.config
    robot = get_registry().create("robot", config.robot)
    space = robot.design_space(uses_mixed_space(config))
    path = str(plan.universal)
    train = universal_policy_factory(
        config, robot, space, plan.objectives, shared=False, checkpoint=path
    )
    evaluate = universal_policy_factory(
        config, robot, space, plan.objectives, shared=True, checkpoint=path
    )
    return train, evaluate


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


def _pooled(state: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    per = np.concatenate([np.asarray(b["per_scenario"], dtype=float) for b in state["blocks"]], 1)
    falls = np.concatenate([np.asarray(b["falls"], dtype=bool) for b in state["blocks"]], 1)
    return per, falls


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


# -- the result ----------------------------------------------------------------------------------
def _side(comp: dict[str, Any], name: str) -> dict[str, Any]:
    o = comp["objectives"][name]
    return {
        "improvement": o["improvement"],
        "improvement_se": _finite(o["improvement_se"]),
        "improvement_plain": o["improvement_plain"],
        "improvement_plain_se": _finite(o["improvement_plain_se"]),
        "cost": o["cost"],
        "nominal_cost": o["nominal_cost"],
        "fall_rate": comp.get("fall_rate"),
        "nominal_fall_rate": comp.get("reference_fall_rate"),
        "fall_rate_difference": comp.get("fall_rate_difference"),
        "fall_rate_difference_se": _finite(comp.get("fall_rate_difference_se")),
        "improvements": {k: v["improvement"] for k, v in comp["objectives"].items()},
        "improvements_se": {k: _finite(v["improvement_se"]) for k, v in comp["objectives"].items()},
    }


def _finite(x: Any) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def difference_se(
    rule: CostRule,
    objective: Objective,
    column: int,
    per: np.ndarray,
    falls: np.ndarray,
    rows: tuple[int, int, int, int],
) -> tuple[float, float]:
    """(improvement with specialists - improvement with the universal policy, its standard
    error): `rows` = (specialist at the design, specialist at the nominal design, universal
    at the design, universal at the nominal design) of `per` [R, A, M]; each policy's scenario
    values under `rule` with its own nominal design as the reference; the bootstrap resamples
    the scenarios of all four rows together."""
    values = []
    for d, n in (rows[:2], rows[2:]):
        pair = per[[d, n]]
        pair_falls = falls[[d, n]]
        ref = rule.reference(pair[1], pair_falls[1]) if rule.needs_reference else None
        values.append(rule.scenario_values(pair, pair_falls, ref)[:, :, column : column + 1])

    def improvements(idx: np.ndarray | slice) -> float:
        out = []
        for v in values:
            cost = rule.aggregate(v[:, idx])[:, 0]
            out.append(float(objective.improvement(float(cost[0]), float(cost[1]))))
        return out[0] - out[1]

    diff = improvements(slice(None))
    a = per.shape[1]
    if a < 2:
        return diff, float("nan")
    boot = np.asarray([improvements(r) for r in _resamples(a)])
    boot = boot[np.isfinite(boot)]
    return diff, float(boot.std(ddof=1)) if len(boot) > 1 else float("nan")


def verdict(
    universal: float,
    universal_se: float | None,
    specialist: float,
    specialist_se: float | None,
    diff: float,
    diff_se: float | None,
) -> str:
    """`holds` (same sign, both at least SIGNIFICANCE_RATIO standard errors, their difference
    within CHANGE_RATIO standard errors), `grows` or `shrinks` (the same, the difference
    beyond that), or `does not hold`."""

    def significant(x: float, se: float | None) -> bool:
        return se is not None and x != 0 and abs(x) >= SIGNIFICANCE_RATIO * se

    if not (
        significant(universal, universal_se)
        and significant(specialist, specialist_se)
        and np.sign(universal) == np.sign(specialist)
    ):
        return "does not hold"
    if diff_se is not None and abs(diff) > CHANGE_RATIO * diff_se:
        return "grows" if abs(specialist) > abs(universal) else "shrinks"
    return "holds"


def _pct(x: float | None, se: float | None = None) -> str:
    if x is None:
        return "-"
    text = f"{100 * x:+.1f}"
    return f"{text} ± {100 * se:.1f} %" if se is not None else f"{text} %"


def verdict_line(entry: dict[str, Any]) -> str:
    """One line: the verdict, both improvements and their difference, and a specialist that
    falls more than the universal policy said so."""
    u, s = entry["universal"], entry["specialist"]
    diff = f"difference {_pct(entry['difference'], entry['difference_se'])[:-2]} points"
    line = (
        f"{entry['role']}: {entry['verdict']}: {_pct(s['improvement'], s['improvement_se'])} with "
        f"specialists, {_pct(u['improvement'], u['improvement_se'])} with the universal policy "
        f"({diff})"
    )
    if entry["verdict"] == "does not hold":
        line += "; " + _why_not(u, s)
    for note in entry.get("falls_more") or []:
        line += f"; {note}"
    return line


def _why_not(u: dict[str, Any], s: dict[str, Any]) -> str:
    def weak(side: dict[str, Any]) -> bool:
        se = side["improvement_se"]
        return se is None or abs(side["improvement"]) < SIGNIFICANCE_RATIO * se

    if weak(u) and weak(s):
        return f"neither improvement is {SIGNIFICANCE_RATIO:g} standard errors"
    if weak(u):
        return f"the universal policy's improvement is under {SIGNIFICANCE_RATIO:g} standard errors"
    if weak(s):
        return f"the improvement with specialists is under {SIGNIFICANCE_RATIO:g} standard errors"
    return "the specialists reverse its sign"


def result_of(plan: Plan, state: dict[str, Any]) -> dict[str, Any]:
    """The verification's result from its pooled blocks (see the module docstring)."""
    per, falls = _pooled(state)
    roles = plan.roles
    n = len(roles)
    names = [o.name for o in plan.objectives]
    first = plan.objectives[0]
    tolerance = float(getattr(plan.config, "fall_tolerance", 0.01))
    entries = []
    for i, role in enumerate(roles[:-1]):
        spec = compare_designs(plan.rule, plan.objectives, per[:n], falls[:n], i, n - 1)
        uni = compare_designs(plan.rule, plan.objectives, per[n:], falls[n:], i, n - 1)
        rows = (i, n - 1, n + i, 2 * n - 1)
        diff, diff_se = difference_se(plan.rule, first, 0, per, falls, rows)
        s, u = _side(spec, first.name), _side(uni, first.name)
        entry = {
            "role": role,
            "design": [float(x) for x in plan.designs[role]],
            "objective": first.name,
            "specialist": s,
            "universal": u,
            "difference": diff,
            "difference_se": _finite(diff_se),
            "verdict": verdict(
                u["improvement"],
                u["improvement_se"],
                s["improvement"],
                s["improvement_se"],
                diff,
                _finite(diff_se),
            ),
        }
        notes = []
        for label, d, r in ((role, i, n + i), ("nominal", n - 1, 2 * n - 1)):
            st = fall_statistics(falls.astype(float), d, r)
            if falls_more(st["fall_rate_difference"], st["fall_rate_difference_se"], tolerance):
                notes.append(
                    f"the {label} design's specialist falls more than the universal policy "
                    f"({100 * st['fall_rate']:.1f} % of scenarios against "
                    f"{100 * st['reference_fall_rate']:.1f} %)"
                )
        entry["falls_more"] = notes
        entry["line"] = verdict_line(entry)
        entries.append(entry)
    specialists = {
        role: {
            "design": [float(x) for x in plan.designs[role]],
            "checkpoint": rec.get("checkpoint"),
            "interactions": int(rec["done"]),
            "seconds": float(rec["seconds"]),
            "start": rec.get("start"),
            "rewards": list(rec.get("rewards") or []),
            **({"same_as": rec["same_as"]} if rec.get("same_as") else {}),
        }
        for role, rec in state["specialists"].items()
    }
    rule = plan.rule
    costs = {}
    for label, offset in (("specialist", 0), ("universal", n)):
        part, pf = per[offset : offset + n], falls[offset : offset + n]
        ref = rule.reference(part[-1], pf[-1]) if rule.needs_reference else None
        c = rule.cost(part, pf, ref)
        costs[label] = {
            role: dict(zip(names, map(float, c[i]), strict=True)) for i, role in enumerate(roles)
        }
    return {
        "run_id": plan.run_id,
        "key": verify_key(plan.budget, plan.seed),
        "budget": plan.budget,
        "seed": plan.seed,
        "universal_policy": str(plan.universal),
        "cost_rule": rule.rule,
        "objectives": names,
        "blocks": len(state["blocks"]),
        "scenarios": int(per.shape[1]),
        "evaluation_interactions": int(sum(b["interactions"] for b in state["blocks"])),
        "training_interactions": int(
            sum(r["interactions"] for r in specialists.values() if not r.get("same_as"))
        ),
        "specialists": specialists,
        "costs": costs,
        "designs": entries,
        "run_improvement": plan.summary.get("improvement"),
        "run_improvement_se": plan.summary.get("improvement_se"),
    }


def read_verifications(run_dir: str | Path) -> list[dict[str, Any]]:
    """The finished verifications of a run folder, by budget then seed."""
    out = []
    base = Path(run_dir) / VERIFY_DIR
    if not base.is_dir():
        return out
    for path in sorted(base.glob(f"*/{RESULT}")):
        data = read_json(path, what="verification")
        if isinstance(data, dict) and data.get("designs"):
            out.append(data)
    return sorted(out, key=lambda r: (int(r.get("budget") or 0), int(r.get("seed") or 0)))


def specialist_policy(
    run_dir: str | Path, role: str = "best"
) -> tuple[Path, dict[str, Any]] | None:
    """(file, verification) of the `role` design's specialist of the run's verification with
    the largest budget; None when the run has none."""
    for result in reversed(read_verifications(run_dir)):
        spec = (result.get("specialists") or {}).get(role)
        if spec and spec.get("checkpoint"):
            path = Path(run_dir) / VERIFY_DIR / result["key"] / spec["checkpoint"]
            if path.is_file():
                return path, result
    return None
