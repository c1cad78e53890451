"""What real evaluation (`coadapt_core.learning.evaluate`: `prepare`, `apply_scenarios`)
asks of a `LocomotionEnv` to give every design the same scenarios: restart its random
streams, draw a scenario set's commands and Table 2 parameters, hold the simulator's draws,
share its groups' random numbers (`use_scenarios`, `paired_draw`). `LocomotionEnv` inherits
these methods; they read its `sim`, `commands`, `generator`, `device` and `scenarios`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np
import torch

from coadapt_core.physics.randomization import EnvParams, sample_env_params

if TYPE_CHECKING:
    from coadapt_core.physics.simulator import Simulator
    from coadapt_core.task.commands import CommandSampler


class SharedStreams(Protocol):
    """What `use_scenarios` reads of a scenario set's shared random numbers (the scenarios
    room's `PairedStreams`): groups of `agents`, their gait phases [agents], the noise seed."""

    agents: int
    seed: int
    phase: torch.Tensor


class ScenarioHooks:
    """The scenario methods of `LocomotionEnv` (module docstring)."""

    sim: Simulator
    commands: CommandSampler
    generator: torch.Generator
    device: torch.device
    #: paired evaluation: the scenario set's shared streams (`use_scenarios`), or None
    scenarios: SharedStreams | None

    def use_scenarios(self, scenarios: SharedStreams | None) -> None:
        """Paired evaluation's hook (`coadapt_core.scenarios`): environment k * agents + i
        draws what environment i draws (gait phase, observation noise, `paired_draw`), as
        `PairedStreams` says; None returns to independent draws."""
        self.scenarios = scenarios

    def restart_streams(self, seed: int, *, task: bool = True) -> None:
        """Restart the random streams from `seed`: the simulator's (`Simulator.reseed`:
        randomization draws, spawn points) and, with `task`, the task's generator (gait
        phases, observation noise, commands while drawn). Exact resume rests on it."""
        if task:
            self.generator.manual_seed(int(seed))
        self.sim.reseed(int(seed))

    def draw_commands(
        self, agents: int, seed: int, *, command_state: dict | None, paired: bool
    ) -> torch.Tensor:
        """[agents, 3] commands of the scenario set of `seed` under the curriculum
        `command_state` (None: the sampler's own): stratified over the command box (paired),
        or drawn independently by a generator seeded `seed` that the sampler keeps."""
        if command_state is not None:
            self.commands.load_state_dict(command_state)
        gen = torch.Generator() if paired else torch.Generator(device=self.device)
        gen.manual_seed(int(seed))
        if paired:
            return self.commands.stratified(agents, gen)
        self.commands.generator = gen
        return self.commands.sample(agents)

    def draw_randomization(self, agents: int, rng: np.random.Generator) -> EnvParams:
        """`agents` draws of the simulator's Table 2 randomization from `rng`."""
        return sample_env_params(self.sim.randomization, agents, rng)

    def fix_scenarios(self, params: EnvParams | None, spawn: np.ndarray | None = None) -> None:
        """Hold every environment's randomization draw and spawn point
        (`Simulator.fix_scenarios`); None draws them afresh at each reset again."""
        self.sim.fix_scenarios(params, spawn)

    def paired_draw(
        self, shape: tuple[int, ...], generator: torch.Generator, normal: bool = True
    ) -> torch.Tensor:
        """[num_envs, *shape[1:]] random numbers, standard normal or uniform in [0, 1): one
        draw per agent of a group repeated for every design when paired, else one per
        environment."""
        rows = self.scenarios.agents if self.scenarios is not None else shape[0]
        draw = torch.randn if normal else torch.rand
        x = draw((rows, *shape[1:]), generator=generator, device=self.device)
        if self.scenarios is not None:
            x = x.repeat(shape[0] // rows, *([1] * (len(shape) - 1)))
        return x
