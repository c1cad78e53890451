"""The loop's last phase, after its last outer iteration: the final check of the candidates
and the nominal design (`final_check.py`, paired blocks of fresh scenarios) read as the run's
outcome, and, without a shared policy, the own policies of the best and nominal designs
written to the run folder.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.final_check import final_check
from coadapt_core.coadapt.reliability import walking
from coadapt_core.coadapt.specialized import OWN_POLICY_FILES, OwnPolicies
from coadapt_core.coadapt.summary import FinalOutcome
from coadapt_core.costs import CostRule
from coadapt_core.fitness import CoadaptationBackend, RealFitness, TrainingResult
from coadapt_core.objective import Objective
from coadapt_core.pareto import front_rows


def check_final_designs(
    fitness: Callable[[np.ndarray, int], RealFitness],
    designs: np.ndarray,
    objectives: Sequence[Objective],
    config: CoadaptConfig,
    rule: CostRule,
    on_block: Callable[[int], None],
) -> tuple[FinalOutcome, RealFitness]:
    """Paired blocks of fresh scenarios (`fitness(designs, block)`) for the candidates and
    the nominal design (last) until the improvement is >= 4 standard errors (final_check.py).
    Returns the outcome and the check's pooled evaluation (what it spent)."""
    c = config
    names = [o.name for o in objectives]
    check = final_check(
        fitness,
        designs,
        objectives,
        max_blocks=c.final_max_blocks,
        min_blocks=min(c.final_min_blocks, c.final_max_blocks),
        rule=rule,
        fall_tolerance=c.fall_tolerance if len(objectives) == 1 else None,
        on_block=on_block,
    )
    fit = check.fit
    costs = np.asarray(fit.costs, dtype=float).reshape(len(designs), -1)
    # several objectives: the front is the non-dominated part of this real re-evaluation and
    # the run returns its design of lowest first cost; one: the lowest cost among candidates
    # that do not fall more (else the nominal)
    front = check.front(designs, names) if len(objectives) > 1 else None
    i = int(front_rows(designs[:-1], costs[:-1])[0]) if front is not None else check.best
    outcome = FinalOutcome(
        best_design=designs[i],
        best_costs=costs[i],
        nominal_costs=costs[-1],
        uncertainty=check.uncertainty(names),
        front=front,
        walking={"best": walking(fit, [i]), "nominal": walking(fit, [len(designs) - 1])},
    )
    return outcome, fit


def save_own_policies(
    backend: CoadaptationBackend,
    run_dir: Path,
    designs: dict[str, np.ndarray],
    count_training: Callable[[Sequence[TrainingResult]], None],
) -> dict[str, str]:
    """Without a shared policy, the own policies of `designs` (by role: best, nominal) go to
    the run folder as `OWN_POLICY_FILES` (the yardstick and sim-to-sim look them up by
    name); the training this takes goes to `count_training`. Returns the files by role ({}
    for a backend that keeps no policy per design)."""
    if not isinstance(backend, OwnPolicies):
        return {}
    (run_dir / "checkpoints").mkdir(exist_ok=True)
    for role, design in designs.items():
        path = str(run_dir / OWN_POLICY_FILES[role])
        count_training(backend.save_policy(np.asarray(design, dtype=float), path))
    return dict(OWN_POLICY_FILES)
