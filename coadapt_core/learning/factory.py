"""The one place that builds the learner's `CoadaptationBackend` (the universal policy with
its critic and pseudo-critics, `coadapt_core.learning.backend.UniversalPolicyBackend`).

The co-adaptation loop's set-up, the experiments (landscape, transfer, evaluation of
recorded runs) and the benchmarks all build their backend here, so a setting of the
learner has one meaning wherever a backend is made. Plugins are given by instance or by
registered name; what cannot be built (an unknown or broken simulator plugin, a simulator
whose library is missing, the learner's own imports) is a `BackendUnavailable` naming why.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import BackendUnavailable, CoadaptError
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.objective import Objective
from coadapt_core.robot import Robot


def resolve_plugins(
    robot: Robot | str, simulator: type | str, objectives: Sequence[Objective | str]
) -> tuple[Robot, type, list[Objective]]:
    """Plugin instances / classes for what is given by registered name. An unknown name is
    the registry's one-line error; a simulator plugin that failed to load is a
    `BackendUnavailable` with the loader's reason."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    if isinstance(simulator, str):
        broken = [b for b in registry.broken if simulator in b.entry_point]
        if broken:
            raise BackendUnavailable(broken[0].line())
        try:
            simulator = registry.get("simulator", simulator)
        except CoadaptError as exc:
            raise BackendUnavailable(str(exc)) from None
    if isinstance(robot, str):
        try:
            robot = registry.create("robot", robot)
        except CoadaptError as exc:
            raise BackendUnavailable(str(exc)) from None
    made = [registry.get("objective", o)() if isinstance(o, str) else o for o in objectives]
    return robot, simulator, made


def make_backend(
    robot: Robot | str,
    simulator: type | str,
    objectives: Sequence[Objective | str],
    *,
    terrain: str = "flat",
    design_space: DesignSpace | None = None,
    mixed: bool = False,
    agents_per_design: int = 16,
    device: str = "cpu",
    seed: int = 0,
    checkpoint: str | None = None,
    **learner: Any,
) -> CoadaptationBackend:
    """The universal-policy backend for `robot` on `simulator` and `terrain`.

    - design_space: the full space the design input is normalised over (default: the
      robot's, mixed when `mixed`).
    - agents_per_design: environments per design in training and the default in real
      fitness; checkpoint: a policy file to start from (None: fresh networks).
    - learner: further `UniversalPolicyBackend` arguments (`train_config`, `task_config`).
    """
    robot, simulator_cls, made = resolve_plugins(robot, simulator, objectives)
    try:
        from coadapt_core.learning.backend import UniversalPolicyBackend
    except ImportError as exc:
        raise BackendUnavailable(f"the learner backend cannot be imported ({exc})") from None
    space = design_space if design_space is not None else robot.design_space(mixed)
    try:
        return UniversalPolicyBackend(
            robot,
            simulator_cls,
            made,
            terrain=terrain,
            design_space=space,
            agents_per_design=agents_per_design,
            device=device,
            seed=seed,
            checkpoint=checkpoint,
            **learner,
        )
    except ImportError as exc:  # e.g. the simulator's library is not installed
        raise BackendUnavailable(
            f"{getattr(simulator_cls, 'name', simulator_cls)}: {exc}"
        ) from None


__all__ = ["BackendUnavailable", "make_backend", "resolve_plugins"]
