"""Turn a `CoadaptConfig` into the parts the loop needs: design spaces, nominal design,
objectives, optimizer class and the backend factory (the universal-policy learner)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import CoadaptError, UserError
from coadapt_core.fitness import CoadaptationBackend
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
    pretrained: bool = False  # the backend starts from a universal policy over the full range


def uses_mixed_space(config: CoadaptConfig) -> bool:
    return bool(config.mixed) or config.optimizer == "mixed-pso"


def make_objectives(config: CoadaptConfig) -> list[Objective]:
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    out = []
    for name in config.objectives:
        cls = registry.get("objective", name)
        if name == "composite" and config.objective_weights:
            out.append(cls(weights=config.objective_weights))
        else:
            out.append(cls())
    return out


def build_parts(
    config: CoadaptConfig,
    *,
    design_space: DesignSpace | None = None,
    nominal_design: np.ndarray | None = None,
    objectives: Sequence[Objective] | None = None,
    optimizer_cls: type[Optimizer] | None = None,
    backend_factory: Callable[[int], CoadaptationBackend] | None = None,
) -> LoopParts:
    from coadapt_core.coadapt.loop import METHOD_SWITCHES
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    switches = METHOD_SWITCHES[config.method]
    if optimizer_cls is None:
        optimizer_cls = registry.get("optimizer", switches.optimizer or config.optimizer)
    objectives = list(objectives) if objectives is not None else make_objectives(config)
    mixed = uses_mixed_space(config)
    robot = None
    if design_space is None or nominal_design is None or backend_factory is None:
        robot = registry.create("robot", config.robot)
    full_space = design_space if design_space is not None else robot.design_space(mixed)
    nominal = np.asarray(nominal_design if nominal_design is not None else robot.nominal_design(mixed), dtype=float)
    full_space.validate(nominal)
    space = full_space.parse_ranges(config.design_ranges) if config.design_ranges.strip() else full_space

    # refuse combinations up front, before any training is paid for
    if len(objectives) > 1 and not optimizer_cls.multi_objective:
        raise UserError(
            f"{len(objectives)} objectives need a multi-objective optimizer (nsga2); "
            f"'{optimizer_cls.name}' optimizes one (or use the composite objective)",
            field="objective",
        )
    if optimizer_cls.multi_objective and not (2 <= len(objectives) <= 3):
        raise UserError(
            f"optimizer '{optimizer_cls.name}' needs 2-3 objectives as a comma list, e.g. "
            "--objective power,torque",
            field="objective",
        )
    if full_space.is_mixed and not optimizer_cls.supports_mixed:
        raise UserError(
            f"optimizer '{optimizer_cls.name}' handles continuous variables only; the mixed design "
            "space needs mixed-pso or bo",
            field="optimizer",
        )
    pretrained = False
    if backend_factory is None:
        backend_factory = universal_policy_factory(config, robot, full_space, objectives)
        pretrained = not switches.specialized and resolve_checkpoint(config) is not None
    return LoopParts(full_space, space, nominal, objectives, optimizer_cls, backend_factory, pretrained)


def universal_policy_factory(
    config: CoadaptConfig, robot, full_space: DesignSpace, objectives: Sequence[Objective]
) -> Callable[[int], CoadaptationBackend]:
    """The real backend: `coadapt_core.learning.backend.UniversalPolicyBackend` on the
    configured simulator and terrain."""
    from coadapt_core.plugins import get_registry

    simulator_cls = get_registry().get("simulator", config.sim)
    try:
        from coadapt_core.learning.backend import UniversalPolicyBackend
    except ImportError as exc:
        raise CoadaptError(
            f"the universal-policy learner (coadapt_core.learning.backend) is not available: {exc}"
        ) from None
    from coadapt_core.coadapt.loop import METHOD_SWITCHES

    # a specialised policy (BO baseline) is trained on its one design from scratch (the
    # paper's), or fine-tuned from the universal policy (`specialized_init: universal`), with
    # the universal training's batch (K x agents environments) on that design
    specialized = METHOD_SWITCHES[config.method].specialized
    checkpoint = resolve_checkpoint(config) if not specialized or config.specialized_init == "universal" else None
    agents = config.population * config.agents_per_design if specialized else config.agents_per_design

    def factory(seed: int) -> CoadaptationBackend:
        return UniversalPolicyBackend(
            robot, simulator_cls, list(objectives), terrain=config.terrain, design_space=full_space,
            agents_per_design=agents, device=config.device, seed=seed,
            checkpoint=checkpoint,
        )

    return factory


def resolve_checkpoint(config: CoadaptConfig) -> str | None:
    """'' -> the shipped universal policy when the learner ships one, 'none' -> from scratch,
    else a path that must exist."""
    from pathlib import Path

    text = config.checkpoint.strip()
    if text.lower() == "none":
        return None
    if text:
        if not Path(text).is_file():
            raise UserError(f"checkpoint '{text}' does not exist", field="checkpoint")
        return text
    try:
        from coadapt_core.learning import shipped_checkpoint  # type: ignore[attr-defined]
    except ImportError:
        return None
    mixed = uses_mixed_space(config)
    path = shipped_checkpoint(config.robot, config.terrain, mixed=mixed)
    if path is None:
        if mixed and shipped_checkpoint(config.robot, config.terrain) is not None:
            print(
                f"note: no {config.robot} policy for the mixed design space on {config.terrain} is shipped "
                f"(policies/{config.terrain}-mixed.pt); training starts from scratch. `coadapt train --mixed "
                f"--init-from` the continuous one makes one (docs/training.md)",
                file=sys.stderr,
            )
        return None
    # a shipped policy takes the design input it was trained on; check it matches this space
    from coadapt_core.learning import read_checkpoint
    from coadapt_core.plugins import get_registry

    trained_dim = int(read_checkpoint(path)["dims"]["num_design"])
    wanted_dim = get_registry().get("robot", config.robot)().design_space(mixed).dim
    if trained_dim != wanted_dim:
        print(
            f"note: the shipped {config.robot} policy {path.name} takes {trained_dim} design values, this "
            f"run's design space has {wanted_dim}: training starts from scratch",
            file=sys.stderr,
        )
        return None
    return str(path)
