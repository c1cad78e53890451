"""Scenarios: the common random numbers of real fitness, end to end (docs/coadaptation.md,
"Evaluation protocol"). A real evaluation of K designs with A agents runs A scenarios, and
agent i of every design gets scenario i: its command, its Table 2 randomization draw and
spawn point, its initial gait phase, its observation-noise stream and, for a stochastic
policy, its action noise. A scenario depends on its seed and i alone.

- seeding: `scenario_seed` (`seeds`), the seed of a run's scenario set block by block;
- drawing and applying (`sets`): `apply_scenarios`, `apply_unpaired` and `prepare`, which
  readies an evaluation environment for a batch of designs.

The room works on an environment through its own methods (`LocomotionEnv.restart_streams`,
`draw_commands`, `draw_randomization`, `fix_scenarios`, `set_commands`, `use_scenarios`),
and the task imports nothing from here (it reads a set's `PairedStreams` as its own
`SharedStreams` protocol). Import each name from its module: the seeds
need neither torch nor the physics room."""
