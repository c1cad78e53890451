"""Rebuilding a run's `CoadaptationBackend` (the universal policy and its evaluation) from
what the store holds, for the report's sim-to-sim column and `coadapt landscape`.

The learner lives in `coadapt_core.learning.backend.UniversalPolicyBackend`; it is imported
here lazily so the store, grids and reports work without torch being loaded, and so a
missing piece is reported as a reason ("n/a: ...") instead of a traceback.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.objective import Objective


class BackendUnavailable(Exception):
    """Why a backend cannot be built here; the message is shown to the user as is."""


@dataclass
class BackendRequest:
    """What a backend is built for."""

    robot: str
    simulator: str
    objectives: list[str]
    terrain: str
    checkpoint: str | None
    agents_per_design: int = 16
    device: str = "cpu"
    seed: int = 0
    mixed: bool = False


#: builds a backend and returns it with the objective instances it evaluates
BackendFactory = Callable[[BackendRequest], tuple[CoadaptationBackend, list[Objective]]]


def objective_instances(names: Sequence[str]) -> list[Objective]:
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    return [registry.get("objective", n)() for n in names]


def universal_policy_backend(request: BackendRequest) -> tuple[CoadaptationBackend, list[Objective]]:
    """The learner's `UniversalPolicyBackend` on `request.simulator`, loaded from the
    checkpoint. Raises `BackendUnavailable` with the reason when it cannot be built."""
    from coadapt_core.errors import CoadaptError
    from coadapt_core.plugins import get_registry

    try:
        from coadapt_core.learning.backend import UniversalPolicyBackend
    except ImportError as exc:
        raise BackendUnavailable(f"the learner backend cannot be imported ({exc})") from None
    registry = get_registry()
    try:
        simulator_cls = registry.get("simulator", request.simulator)
        robot = registry.get("robot", request.robot)()
    except CoadaptError as exc:
        raise BackendUnavailable(str(exc)) from None
    broken = [b for b in registry.broken if request.simulator in b.entry_point]
    if broken:
        raise BackendUnavailable(broken[0].line())
    objectives = objective_instances(request.objectives)
    space = robot.design_space(mixed=request.mixed)
    try:
        backend = UniversalPolicyBackend(
            robot,
            simulator_cls,
            objectives,
            terrain=request.terrain,
            design_space=space,
            agents_per_design=request.agents_per_design,
            device=request.device,
            seed=request.seed,
            checkpoint=request.checkpoint,
        )
    except ImportError as exc:  # e.g. pybullet missing
        raise BackendUnavailable(f"{request.simulator}: {exc}") from None
    return backend, objectives


def nominal_design(robot_name: str, dim: int) -> np.ndarray:
    """The robot's nominal design ((1, 1), motor type 1 for Kuafu), padded to `dim`."""
    from coadapt_core.plugins import get_registry

    try:
        robot = get_registry().get("robot", robot_name)()
        nominal = np.asarray(robot.nominal_design(mixed=dim > 2), dtype=float)
        if nominal.shape[0] == dim:
            return nominal
    except Exception:
        pass
    return np.ones(dim)


def run_request(run: dict[str, Any], *, simulator: str | None = None, checkpoint: str | None = None, agents: int = 16) -> BackendRequest:
    cfg = run.get("config") or {}
    return BackendRequest(
        robot=run.get("robot") or cfg.get("robot") or "kuafu",
        simulator=simulator or run.get("simulator") or "mujoco",
        objectives=list(run["objectives"]),
        terrain=run.get("terrain") or "flat",
        checkpoint=checkpoint,
        agents_per_design=agents,
        device=str(cfg.get("device", "cpu")),
        seed=int(run.get("seed") or 0),
        mixed=bool(cfg.get("mixed", False)) or _implies_mixed(run.get("optimizer")),
    )


def _implies_mixed(optimizer: Any) -> bool:
    """The run's optimizer declares that choosing it means the mixed design space."""
    from coadapt_core.errors import UserError
    from coadapt_core.plugins import get_registry

    try:
        return bool(getattr(get_registry().get("optimizer", str(optimizer)), "implies_mixed", False))
    except UserError:
        return False
