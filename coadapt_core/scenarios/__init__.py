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
`Simulator.fix_scenarios` and `Simulator.reseed`. Import each name from its module: the
seeds need neither torch nor the physics room."""
