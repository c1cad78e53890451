"""Scenarios: the common random numbers of real fitness, end to end (docs/coadaptation.md,
"Evaluation protocol"). A real evaluation of K designs with A agents runs A scenarios, and
agent i of every design gets scenario i: its command, its Table 2 randomization draw and
spawn point, its initial gait phase, its observation-noise stream and, for a stochastic
policy, its action noise. A scenario depends on its seed and i alone.

- seeding: `scenario_seed` (`seeds`), the seed of a run's scenario set block by block, and
  `restart_streams` (`sets`), every random stream of an environment restarted from a seed
  (exact resume rests on it);
- drawing and applying (`sets`): `apply_scenarios`, `apply_unpaired`, `PairedStreams` and
  `prepare`, which readies an evaluation environment for a batch of designs.

The task and the simulator only expose hooks: `LocomotionEnv.set_commands`,
`LocomotionEnv.use_scenarios` (with `paired_draw` for the action noise),
`Simulator.fix_scenarios` and `Simulator.reseed`. The names below are looked up lazily:
the seeds need neither torch nor the physics room."""

from importlib import import_module
from typing import Any

_EXPORTS = {
    "scenario_seed": "coadapt_core.scenarios.seeds",
    "restart_streams": "coadapt_core.scenarios.sets",
    "PairedStreams": "coadapt_core.scenarios.sets",
    "apply_scenarios": "coadapt_core.scenarios.sets",
    "apply_unpaired": "coadapt_core.scenarios.sets",
    "prepare": "coadapt_core.scenarios.sets",
}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'coadapt_core.scenarios' has no attribute '{name}'")


__all__ = sorted(_EXPORTS)
