"""Turn a `CoadaptConfig` into the parts the loop needs (`build_parts`), each resolved once:
the method, the design spaces and nominal design, the objectives and optimizer class
(`search.py`), the starting policy (`starting_policy.py`) and the backend factory of the
method's backend kind (`backends.py`: the universal-policy learner, or a policy per design
for the BO baseline)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from coadapt_core.coadapt.backends import (
    check_device_available,
    specialized_factory,
    universal_policy_factory,
)
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.first_round import first_round_warnings
from coadapt_core.coadapt.refine import check_refinement
from coadapt_core.coadapt.search import check_search, search_plugins, uses_mixed_space
from coadapt_core.coadapt.starting_policy import starting_policy
from coadapt_core.design_space import DesignSpace
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.methods import Method, get_method
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer


@dataclass
class LoopParts:
    full_space: DesignSpace  # the robot's whole space: the reference of narrowing
    space: DesignSpace  # the first outer iteration's range (`design_ranges`)
    nominal: np.ndarray  # [dim] the design improvements are measured against
    objectives: list[Objective]
    optimizer_cls: type[Optimizer]
    backend_factory: Callable[[int], CoadaptationBackend]
    method: Method  # the config's method (`coadapt_core.methods`), looked up once here
    pretrained: bool = False  # the shared policy starts from a universal policy over the full range
    #: the starting policy's provenance (`policy_provenance`); None when the backend was given
    policy: dict | None = None
    #: lines the run prints at its start and records in its summary (`notes`)
    notes: list[str] = field(default_factory=list)
    #: objectives the starting policy has no pseudo-critic for (`objectives_without_critic`)
    no_critic: list[str] = field(default_factory=list)


def build_parts(
    config: CoadaptConfig,
    *,
    design_space: DesignSpace | None = None,
    nominal_design: np.ndarray | None = None,
    objectives: Sequence[Objective] | None = None,
    optimizer_cls: type[Optimizer] | None = None,
    backend_factory: Callable[[int], CoadaptationBackend] | None = None,
) -> LoopParts:
    """The loop's parts from `config`; a part given is taken as it is (tests, benchmarks).
    Every combination the run would refuse is refused here, before any training is paid for
    or a run folder exists."""
    from coadapt_core.plugins import get_registry

    method = get_method(config.method)
    shared = method.backend_kind.shared_policy
    # checked now, before any training; recorded typed
    optimizer_cls, objectives = search_plugins(config, optimizer_cls, objectives)
    mixed = uses_mixed_space(config)
    robot = None
    if design_space is None or nominal_design is None or backend_factory is None:
        robot = get_registry().create("robot", config.robot)
    full_space = design_space if design_space is not None else robot.design_space(mixed)
    nominal = np.asarray(
        nominal_design if nominal_design is not None else robot.nominal_design(mixed), dtype=float
    )
    full_space.validate(nominal)
    ranges = config.design_ranges.strip()
    space = full_space.parse_ranges(config.design_ranges) if ranges else full_space
    check_search(optimizer_cls, objectives, full_space)
    check_refinement(config, objectives, full_space)
    parts = LoopParts(
        full_space, space, nominal, objectives, optimizer_cls, backend_factory, method
    )
    if backend_factory is None:
        check_device_available(config.device)  # the learner's; before a run folder exists
        start = starting_policy(config, method, robot, full_space, mixed, objectives)
        parts.backend_factory = universal_policy_factory(
            config, robot, full_space, objectives, shared=shared, checkpoint=start.checkpoint
        )
        parts.pretrained, parts.policy = start.pretrained, start.provenance
        parts.no_critic, parts.notes = start.no_critic, [start.note] if start.note else []
    if not shared:  # the factory builds each design's policy
        parts.backend_factory = specialized_factory(config, parts.backend_factory)
    else:
        parts.notes += first_round_warnings(
            optimizer_cls, space, config.population, len(objectives), config.optimizer_options
        )
    return parts
