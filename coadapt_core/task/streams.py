"""The task's random numbers of one scenario set (`PairedStreams`): what paired evaluation
makes every design share, held by `LocomotionEnv.use_scenarios` and drawn by the scenarios
room (`coadapt_core.scenarios.sets.apply_scenarios`)."""

from __future__ import annotations

from dataclasses import dataclass

import torch


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
