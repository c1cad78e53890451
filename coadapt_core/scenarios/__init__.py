"""Scenarios: the common random numbers of real fitness, end to end (docs/coadaptation.md,
"Evaluation protocol"). A real evaluation of K designs with A agents runs A scenarios, and
agent i of every design gets scenario i: its command, its Table 2 randomization draw and
spawn point, its initial gait phase, its observation-noise stream and, for a stochastic
policy, its action noise. A scenario depends on its seed and i alone.

This package holds the seeding: `scenario_seed` (`seeds`), the seed of a run's scenario set
block by block; it needs neither torch nor the physics room. Drawing a set and applying it
to an environment (`apply_scenarios`, `apply_unpaired`, `prepare`) live with the rollout that
uses them, in `coadapt_core.learning.evaluate`, and work through the environment's own
methods; the task imports nothing from either (it reads a set's `PairedStreams` as its own
`SharedStreams` protocol)."""
