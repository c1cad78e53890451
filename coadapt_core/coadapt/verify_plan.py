"""What `coadapt verify` is asked (`coadapt_core.coadapt.verify`): the request checked
against the run folder before anything is written (`plan_verification`: a finished run with
a paired final check and a universal policy of its robot, a positive budget, designs in the
policy's range), the designs it verifies, its constants, and the backends that fine-tune and
evaluate (`default_factories`, from the run's recorded config)."""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.costs import CostRule
from coadapt_core.errors import UserError
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.objective import Objective

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


class NothingToVerify(UserError):
    """The run's answer is its nominal design (no candidate beat it): no improvement to check.
    `coadapt verify` refuses it (exit 2); `coadapt run --verify` says so and goes on."""


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


def _finished_run(run_dir: Path) -> Any:
    """(the run's state, its config), refused unless the run finished with a paired final
    check and shares one universal policy."""
    from coadapt_core.coadapt.config_loading import config_from_dict
    from coadapt_core.coadapt.state import STATE_FILE, load_state
    from coadapt_core.methods import get_method

    if not (run_dir / STATE_FILE).is_file():
        raise UserError(f"'{run_dir}' is not a run folder (no {STATE_FILE})", field="run")
    state = load_state(run_dir)
    if state.phase != "done" or state.summary is None:
        raise UserError(
            f"run {state.run_id} has not finished (it is at its '{state.phase}' phase: still "
            "running, or cut off); let it finish or resume it with `coadapt run --resume` first",
            field="run",
        )
    summary = state.summary
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
    return state, config


def _picked(
    state: Any, names: Sequence[str], pick: str | None, design: Sequence[float] | None
) -> dict[str, Any]:
    """role -> design to verify: --design, the front's picks (several objectives), else the
    run's best."""
    summary = state.summary
    if design is not None:
        if pick is not None:
            raise UserError("give --design or --pick, not both", field="pick")
        return {"design": list(design)}
    if len(names) > 1:
        pick = pick or "chosen"
        if pick not in PICKS:
            raise UserError(f"--pick must be one of {', '.join(PICKS)}, got '{pick}'", field="pick")
        return _front_designs(summary, pick, names)
    if pick not in (None, "chosen"):
        raise UserError(
            f"--pick '{pick}': run {state.run_id} has one objective and no Pareto front; "
            "leave out --pick to verify its best design",
            field="pick",
        )
    return {"best": np.asarray(summary["best_design"], dtype=float)}


def _not_nominal(run_id: str, picked: dict[str, Any], nominal: np.ndarray) -> dict[str, Any]:
    """The picked designs other than the nominal one: a specialist pair at one design would
    compare the nominal design with itself (0 +- 0 %), so a run that kept its nominal design
    has nothing to verify."""
    kept = {
        role: np.asarray(d, dtype=float)
        for role, d in picked.items()
        if not np.allclose(np.asarray(d, dtype=float), nominal, rtol=0.0, atol=1e-9)
    }
    if not kept:
        what = "the design given is" if "design" in picked else f"run {run_id}'s answer is"
        raise NothingToVerify(
            f"{what} the nominal design ({', '.join(f'{x:g}' for x in nominal)}): no candidate "
            "beat it, so there is no improvement to verify; give --design to verify another "
            "design against it",
            field="design",
        )
    return kept


def _universal(
    run_dir: Path, state: Any, config: Any, checkpoint: str | Path | None
) -> tuple[Path, dict]:
    """(the universal policy's file, its header), refused when missing or another robot's."""
    from coadapt_core.learning.checkpoints import read_checkpoint

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
    header = read_checkpoint(universal)
    if str(header.get("robot")) != str(config.robot):
        raise UserError(
            f"checkpoint '{universal}' is a policy for robot '{header.get('robot')}', the run's "
            f"robot is '{config.robot}'",
            field="checkpoint",
        )
    return universal, header


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
    from coadapt_core.coadapt.search import make_objectives

    run_dir = Path(run_dir).absolute()
    state, config = _finished_run(run_dir)
    if budget is None:
        budget = DEFAULT_BUDGETS.get(str(config.preset), DEFAULT_BUDGETS["quick"])
    if isinstance(budget, bool) or int(budget) <= 0:
        raise UserError(
            f"budget must be a positive number of interactions, got {budget}", field="budget"
        )
    budget, seed = int(budget), int(config.seed if seed is None else seed)
    picked = _picked(state, list(config.objectives), pick, design)
    universal, header = _universal(run_dir, state, config, checkpoint)
    nominal = np.asarray(state.summary["nominal_design"], dtype=float)
    designs = _not_nominal(state.run_id, picked, nominal)
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
    blocks = max(int(state.summary.get("final_blocks") or 1), 1)
    return Plan(
        run_dir=run_dir,
        run_id=state.run_id,
        config=config,
        summary=dict(state.summary),
        objectives=make_objectives(config),
        designs=designs,
        universal=universal,
        budget=budget,
        seed=seed,
        chunk=max(1, chunk),
        folder=run_dir / VERIFY_DIR / verify_key(budget, seed),
        min_blocks=blocks,
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
