"""Scenario sets (`coadapt_core.scenarios`): drawing the scenarios of one seed and applying
them to an environment through the env's own methods (`LocomotionEnv.restart_streams`,
`draw_commands`, `draw_randomization`, `fix_scenarios`, `set_commands`, `use_scenarios`).
Agent i of every design gets scenario i: its command (stratified over the command box), its
Table 2 draw and spawn point (held by the simulator), its initial gait phase and its
observation- and action-noise streams (`PairedStreams`, which the task holds as its
`SharedStreams`). `prepare` readies an evaluation environment for a batch of designs,
paired (the protocol) or unpaired (the protocol before it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from coadapt_core.errors import UserError

if TYPE_CHECKING:
    from coadapt_core.task.env import LocomotionEnv


@dataclass(frozen=True)
class PairedStreams:
    """The task's random numbers of one scenario set, shared by every design: environment
    k * agents + i draws what environment i draws (`LocomotionEnv.use_scenarios`): its gait
    phase `phase[i]` at every episode start, its observation noise from a generator keyed
    by `seed` and the steps since the last full reset alone (the same noise however often a
    step is observed, whoever fell), and its action noise (`LocomotionEnv.paired_draw`)."""

    agents: int
    seed: int
    phase: torch.Tensor  # [agents] initial gait phases in [0, 1)

    @classmethod
    def draw(cls, agents: int, seed: int, device: torch.device) -> PairedStreams:
        gen = torch.Generator(device=device)
        gen.manual_seed(int(seed))
        return cls(int(agents), int(seed), torch.rand(int(agents), generator=gen, device=device))


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
    curriculum's, or the env's own when None), its randomization draw (Table 2) and spawn
    point, its initial gait phase and its observation- and action-noise streams
    (`PairedStreams`). A scenario depends on `seed` and i alone, not on the designs or on the
    other agents. Returns the commands [agents, 3]."""
    agents = int(agents)
    if agents < 1 or env.num_envs % agents:
        raise UserError(
            f"paired scenarios: {env.num_envs} environments do not split into groups "
            f"of {agents} agents",
            field="agents",
        )
    if commands is None:
        commands = env.draw_commands(
            agents, seed, command_state=command_state, paired=True
        )  # [A, 3]
    commands = torch.as_tensor(commands, dtype=torch.float32, device=env.device).reshape(agents, 3)
    env.set_commands(commands.repeat(designs, 1))
    rng = np.random.default_rng([int(seed), 0xC0])  # the randomization draw of each scenario
    params = env.draw_randomization(agents, rng)
    spawn = rng.random((agents, 2))
    streams = PairedStreams.draw(agents, int(seed), env.device)
    env.fix_scenarios(params.repeat(designs), np.tile(spawn, (designs, 1)))
    env.use_scenarios(streams)
    return commands


def apply_unpaired(
    env: LocomotionEnv, agents: int, designs: int, seed: int, *, command_state: dict | None = None
) -> None:
    """The protocol before paired evaluation, kept to measure what pairing buys
    (benchmarks/fitness_noise.py --protocol unpaired): commands drawn independently per
    agent from the box (shared by the designs of one call), every randomization draw and
    noise stream independent per environment."""
    commands = env.draw_commands(agents, seed, command_state=command_state, paired=False)
    env.set_commands(commands.repeat(designs, 1))
    env.fix_scenarios(None)
    env.use_scenarios(None)


def prepare(
    env: LocomotionEnv,
    agents: int,
    designs: int,
    seed: int,
    *,
    paired: bool = True,
    command_state: dict | None = None,
) -> None:
    """Ready `env` (`designs` consecutive groups of `agents` environments) for a real
    evaluation on the scenario set of `seed`: the simulator's streams restart from `seed`
    (the task's own generator restarts with the rollout's seed), then the scenarios are
    applied, paired (`apply_scenarios`) or not (`apply_unpaired`), under the command
    curriculum `command_state`. What follows is a function of the policy, the curriculum,
    the designs and `seed` alone, whatever earlier calls drew."""
    env.restart_streams(seed, task=False)
    if paired:
        apply_scenarios(env, agents, designs, seed, command_state=command_state)
    else:
        apply_unpaired(env, agents, designs, seed, command_state=command_state)
