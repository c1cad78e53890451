"""Scenario sets of paired real fitness (common random numbers, docs/coadaptation.md
"Evaluation protocol"): what agent i of every design is given in an evaluation."""

from __future__ import annotations

import numpy as np
import torch

from coadapt_core.physics.randomization import sample_env_params
from coadapt_core.task.env import LocomotionEnv


def apply_scenarios(
    env: LocomotionEnv,
    agents: int,
    designs: int,
    seed: int,
    *,
    command_state: dict | None = None,
    commands: torch.Tensor | None = None,
) -> torch.Tensor:
    """Give the `designs` consecutive groups of `agents` environments of `env` the scenario
    set of `seed`: agent i of each group gets scenario i, that is its command (`commands`
    [agents, 3] when given, else stratified over the command box of `command_state`, the
    curriculum's), its randomization draw (Table 2) and spawn point, its initial gait phase
    and its observation-noise stream (`LocomotionEnv.pair_scenarios`; the action noise of a
    stochastic rollout follows through `LocomotionEnv.paired_draw`). A scenario depends on
    `seed` and i alone, not on the designs or on the other agents. Returns the commands
    [agents, 3]."""
    if command_state is not None:
        env.commands.load_state_dict(command_state)
    if commands is None:
        gen = torch.Generator()
        gen.manual_seed(int(seed))
        commands = env.commands.stratified(agents, gen)  # [A, 3]
    commands = torch.as_tensor(commands, dtype=torch.float32, device=env.device).reshape(agents, 3)
    env.set_commands(commands.repeat(designs, 1))
    rng = np.random.default_rng([int(seed), 0xC0])  # the randomization draw of each scenario
    params = sample_env_params(env.sim.randomization, agents, rng)
    spawn = rng.random((agents, 2))
    env.sim.fix_scenarios(params.repeat(designs), np.tile(spawn, (designs, 1)))
    env.pair_scenarios(agents, int(seed))
    return commands
