"""The search's plugins of a run, built and checked before any training is paid for: the
optimizer class and its options, the objectives with theirs, whether the mixed design space
is searched, and the combinations refused (several objectives on a single-objective
optimizer, discrete variables on a continuous one)."""

from __future__ import annotations

from collections.abc import Sequence

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer


def search_plugins(
    config: CoadaptConfig,
    optimizer_cls: type[Optimizer] | None,
    objectives: Sequence[Objective] | None,
) -> tuple[type[Optimizer], list[Objective]]:
    """The optimizer class (the config's unless given; validation chose it for the method,
    `methods.optimizer_for`) with `optimizer_options` checked against its declarations, and
    the objectives (built from the config unless given). The options given are recorded in
    the config typed, as the plugins converted them (the plugins' defaults stay theirs)."""
    from coadapt_core.options import resolve_options
    from coadapt_core.plugins import get_registry
    from coadapt_core.results.storage import check_database_url

    if optimizer_cls is None:
        optimizer_cls = get_registry().get("optimizer", config.optimizer)
    specs = getattr(optimizer_cls, "option_specs", ())
    resolved = resolve_options(
        specs,
        config.optimizer_options,
        owner=f"optimizer '{optimizer_cls.name}'",
        field="optimizer_options",
    )
    config.optimizer_options = {k: resolved[k] for k in config.optimizer_options}
    # a database URL given to an option the run would otherwise fill with its store
    # (`from_run="store_url"`, e.g. a study kept there): a bad one is one line now, not an
    # error after the first training phase
    for spec in specs:
        value = config.optimizer_options.get(spec.name)
        if spec.from_run == "store_url" and value:
            check_database_url(str(value), field=spec.alias or f"optimizer_options.{spec.name}")
    if objectives is None:
        objectives = make_objectives(config)
        given = set(config.objective_options)  # recorded typed, as the objectives converted them
        config.objective_options = {
            k: v for o in objectives for k, v in getattr(o, "options", {}).items() if k in given
        }
    return optimizer_cls, list(objectives)


def make_objectives(config: CoadaptConfig) -> list[Objective]:
    """The configured objectives, each given the `objective_options` it declares; an option
    no objective of the run declares is a user error."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    classes = [registry.get("objective", name) for name in config.objectives]
    given = dict(config.objective_options)
    declared = {spec.name for cls in classes for spec in getattr(cls, "option_specs", ())}
    for key in given:
        if key not in declared:
            names = ", ".join(f"'{c.name}'" for c in classes)
            raise UserError(
                f"objective {names} has no option '{key}'; its options: "
                f"{', '.join(sorted(declared)) or 'none'}",
                field="objective_options",
            )
    out = []
    for cls in classes:
        mine = {spec.name for spec in getattr(cls, "option_specs", ())}
        out.append(cls(**{k: v for k, v in given.items() if k in mine}))
    return out


def uses_mixed_space(config: CoadaptConfig) -> bool:
    """`mixed`, or an optimizer that declares `implies_mixed` (searching discrete variables
    is what it is for)."""
    if config.mixed:
        return True
    from coadapt_core.plugins import get_registry

    try:
        cls = get_registry().get("optimizer", config.optimizer)
    except UserError:
        return False
    return bool(getattr(cls, "implies_mixed", False))


def check_search(
    optimizer_cls: type[Optimizer], objectives: Sequence[Objective], space: DesignSpace
) -> None:
    """Refuse, before any training is paid for, an optimizer that cannot search the run's
    objectives or its design space."""
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
    if space.is_mixed and not optimizer_cls.supports_mixed:
        raise UserError(
            f"optimizer '{optimizer_cls.name}' handles continuous variables only; the mixed "
            "design space needs one that declares supports_mixed (see `coadapt plugins`)",
            field="optimizer",
        )
