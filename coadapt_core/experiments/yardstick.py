"""One yardstick for every run: its true cost on a common set of paired scenarios.

A run's own figures come from its own scenario set and its own final check, so two runs (two
methods, two seeds) are each measured with a different ruler. Here every run's best design and
its nominal design are evaluated with the policy the run handed back (its last checkpoint) on
one common set per terrain and preset: `blocks` blocks of scenarios drawn from
`scenario_seed(COMMON_SEED, b)`, a set no run with a small seed draws, each block as large as
one of the run's real evaluations (its `eval_agents` scenarios x `eval_steps` policy steps:
32 x 250 in the quick preset, so 8 blocks are the 256 scenarios of docs/coadaptation.md). The
costs follow the run's own cost rule (the reference level from the nominal row), with the
plain mean of eq. 4, the fall rates and the paired improvements beside them, each with its
standard error.

The figures are stored as two evaluation rows of kind "common" (idx 0 best, 1 nominal); the
report reads them, an export carries them, and a run that has them is not evaluated again.
`benchmarks/common_scenarios.py --policy run` computes the same figures without a store.

Keys of a row's `costs` (objective names never hold a "/"): per objective `NAME` (the rule's
cost), `NAME/se`, `NAME/plain`, `NAME/plain_se`; on the best row also `NAME/improvement`,
`NAME/improvement_se`, `NAME/improvement_plain`, `NAME/improvement_plain_se`; and `falls`,
`falls/se` (best row also `falls/difference`, `falls/difference_se`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from coadapt_core.costs import CostRule, compare_designs
from coadapt_core.errors import BackendUnavailable, UserError
from coadapt_core.experiments.own_policies import (
    each_own_policy,
    nominal_of,
    policy_files,
    run_backend,
    shares_policy,
)
from coadapt_core.results.recorders import batch_rows
from coadapt_core.results.schema import COMMON_KIND, COMMON_OUTER
from coadapt_core.results.store import ResultsStore
from coadapt_core.scenarios.seeds import scenario_seed
from coadapt_core.sim_to_sim import row_figures

#: the common scenario set: blocks of scenario_seed(COMMON_SEED, b); the same set
#: benchmarks/common_scenarios.py draws
COMMON_SEED = 1000
DEFAULT_BLOCKS = 8


def block_size(run: dict[str, Any]) -> tuple[int, int]:
    """(scenarios, policy steps) of one block: the run's real evaluation size."""
    cfg = run.get("config") or {}
    agents = int(cfg.get("eval_agents") or 0) or int(cfg.get("agents_per_design") or 0) or 32
    return agents, int(cfg.get("eval_steps") or 0) or 250


def yardstick_rows(store: ResultsStore, run_id: str) -> list:
    """The run's common-yardstick rows (idx 0 best design, 1 nominal)."""
    return sorted(store.evaluations(run_id, kind=COMMON_KIND), key=lambda e: e.idx)


def _backend(run: dict[str, Any], dim: int, agents: int, checkpoint: str, factory: Callable | None):
    """(backend, objectives, nominal design) for the run's robot, simulator and terrain."""
    return run_backend(
        run,
        dim,
        run.get("simulator") or (run.get("config") or {}).get("sim"),
        agents,
        checkpoint,
        factory,
    )


def _own_policy_blocks(
    run: dict[str, Any],
    best: np.ndarray,
    agents: int,
    factory: Callable | None,
    blocks_of: Callable,
) -> tuple[list, list, np.ndarray]:
    """A run without a shared policy: its best and nominal designs each with its own policy
    (saved by the run, else trained again as it did: `own_policies`), the common blocks
    stacked as if one policy had evaluated both."""
    designs = {"best": best, "nominal": nominal_of(run, best.shape[0])}
    made: dict[str, Any] = {}

    def make(path):
        backend, made["objectives"], _ = _backend(run, best.shape[0], agents, str(path), factory)
        return backend

    with policy_files(run, designs) as files:
        fits = each_own_policy(
            make, files, designs, lambda backend, d: blocks_of(backend, d, made["objectives"])
        )
    return fits, made["objectives"], designs["nominal"]


def yardstick_run(
    store: ResultsStore,
    run: dict[str, Any],
    best_design: Sequence[float] | None,
    *,
    blocks: int = DEFAULT_BLOCKS,
    agents: int | None = None,
    steps: int | None = None,
    factory: Callable | None = None,
) -> str:
    """Evaluate the run's best and nominal designs on the common set and record them, unless
    the store holds them already. Returns '' when the rows exist, else why not ("n/a: ...")."""
    from coadapt_core.experiments.transfer import run_checkpoint_in_store

    if not run.get("objectives") or best_design is None:
        return "n/a: the run has no best design"
    if len(yardstick_rows(store, run["id"])) >= 2:
        return ""
    shared = shares_policy(run)
    checkpoint, why = run_checkpoint_in_store(store, run) if shared else (None, "")
    if shared and checkpoint is None:
        return why
    best = np.asarray(best_design, dtype=float)
    own_agents, own_steps = block_size(run)
    agents, steps = agents or own_agents, steps or own_steps

    def blocks_of(backend, designs, objectives):
        return [
            backend.real_fitness(
                designs, objectives, agents=agents, steps=steps, seed=scenario_seed(COMMON_SEED, b)
            )
            for b in range(blocks)
        ]

    try:
        if shared:
            backend, objectives, nominal = _backend(
                run, best.shape[0], agents, str(checkpoint), factory
            )
            fits = blocks_of(backend, np.stack([best, nominal]), objectives)
            close = getattr(backend, "close", None)
            if callable(close):
                close()
        else:
            fits, objectives, nominal = _own_policy_blocks(run, best, agents, factory, blocks_of)
    except (BackendUnavailable, UserError) as exc:
        return f"n/a: {' '.join(str(exc).split())}"
    if any(f.per_scenario is None for f in fits):
        return "n/a: the backend reports no per-scenario costs"
    per = np.concatenate([f.per_scenario for f in fits], axis=1)
    falls = (
        None
        if any(f.scenario_falls is None for f in fits)
        else np.concatenate([f.scenario_falls for f in fits], axis=1)
    )
    rule = CostRule.from_config(run.get("config") or {})
    rows = [
        row_figures(compare_designs(rule, objectives, per, falls, i, 1), best=i == 0)
        for i in (0, 1)
    ]
    store.record_evaluations(
        run["id"],
        batch_rows(
            outer=COMMON_OUTER,
            inner=0,
            kind=COMMON_KIND,
            designs=[best.tolist(), nominal.tolist()],
            costs=rows,
            interactions=sum(f.interactions for f in fits) // 2,
            seconds=sum(f.seconds for f in fits) / 2,
            simulator=str(run.get("simulator") or ""),
        ),
    )
    return ""


def yardstick_runs(
    store: ResultsStore,
    runs: Sequence[dict[str, Any]],
    *,
    blocks: int = DEFAULT_BLOCKS,
    agents: int | None = None,
    steps: int | None = None,
    factory: Callable | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, str]:
    """`yardstick_run` for each run's best design (blocks of each run's own evaluation size
    unless `agents`/`steps` are given); returns run id -> why it has no rows."""
    from coadapt_core.experiments.transfer import each_best_design

    return each_best_design(
        store,
        runs,
        "common scenarios",
        progress,
        lambda run, best: yardstick_run(
            store, run, best, blocks=blocks, agents=agents, steps=steps, factory=factory
        ),
    )
