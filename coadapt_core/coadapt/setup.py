"""Turn a `CoadaptConfig` into the parts the loop needs: design spaces, nominal design,
objectives, optimizer class and the backend factory of the method's backend kind (the
universal-policy learner, or a policy per design for the BO baseline)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coadapt_core.coadapt.config import SECTIONS, CoadaptConfig
from coadapt_core.coadapt.learner_overrides import resolve_learner
from coadapt_core.coadapt.specialized import SpecializedPolicyBackend
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import CoadaptError, UserError
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.methods import get_method
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer
from coadapt_core.settings import overrides


@dataclass
class LoopParts:
    full_space: DesignSpace  # the robot's whole space: the reference of narrowing
    space: DesignSpace  # the first outer iteration's range (`design_ranges`)
    nominal: np.ndarray  # [dim] the design improvements are measured against
    objectives: list[Objective]
    optimizer_cls: type[Optimizer]
    backend_factory: Callable[[int], CoadaptationBackend]
    pretrained: bool = False  # the shared policy starts from a universal policy over the full range
    #: the starting policy's provenance (`policy_provenance`); None when the backend was given
    policy: dict | None = None
    #: lines the run prints at its start and records in its summary (`notes`)
    notes: list[str] = field(default_factory=list)
    #: objectives the starting policy has no pseudo-critic for (`objectives_without_critic`)
    no_critic: list[str] = field(default_factory=list)


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
                f"objective {names} has no option '{key}'; its options: {', '.join(sorted(declared)) or 'none'}",
                field="objective_options",
            )
    out = []
    for cls in classes:
        mine = {spec.name for spec in getattr(cls, "option_specs", ())}
        out.append(cls(**{k: v for k, v in given.items() if k in mine}))
    return out


def check_optimizer_options(config: CoadaptConfig, optimizer_cls: type[Optimizer]) -> dict:
    """`optimizer_options` checked against the optimizer's declarations now, before any
    training is paid for (the optimizer itself is built after the first training phase)."""
    from coadapt_core.options import resolve_options

    return resolve_options(
        getattr(optimizer_cls, "option_specs", ()),
        config.optimizer_options,
        owner=f"optimizer '{optimizer_cls.name}'",
        field="optimizer_options",
    )


def build_parts(
    config: CoadaptConfig,
    *,
    design_space: DesignSpace | None = None,
    nominal_design: np.ndarray | None = None,
    objectives: Sequence[Objective] | None = None,
    optimizer_cls: type[Optimizer] | None = None,
    backend_factory: Callable[[int], CoadaptationBackend] | None = None,
) -> LoopParts:
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    shared = get_method(config.method).backend_kind.shared_policy
    if (
        optimizer_cls is None
    ):  # the config's, as validation chose it for the method (`methods.optimizer_for`)
        optimizer_cls = registry.get("optimizer", config.optimizer)
    # checked now, before any training; recorded typed (only the options given: the
    # plugin's defaults stay the plugin's)
    resolved = check_optimizer_options(config, optimizer_cls)
    config.optimizer_options = {k: resolved[k] for k in config.optimizer_options}
    check_store_options(config, optimizer_cls)
    if objectives is None:
        objectives = make_objectives(config)
        given = set(config.objective_options)  # recorded typed, as the objectives converted them
        config.objective_options = {
            k: v for o in objectives for k, v in getattr(o, "options", {}).items() if k in given
        }
    objectives = list(objectives)
    mixed = uses_mixed_space(config)
    robot = None
    if design_space is None or nominal_design is None or backend_factory is None:
        robot = registry.create("robot", config.robot)
    full_space = design_space if design_space is not None else robot.design_space(mixed)
    nominal = np.asarray(
        nominal_design if nominal_design is not None else robot.nominal_design(mixed), dtype=float
    )
    full_space.validate(nominal)
    space = (
        full_space.parse_ranges(config.design_ranges)
        if config.design_ranges.strip()
        else full_space
    )

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
            "space needs one that declares supports_mixed (see `coadapt plugins`)",
            field="optimizer",
        )
    pretrained = False
    policy = None
    notes: list[str] = []
    no_critic: list[str] = []
    if backend_factory is None:
        check_device(config.device)  # the learner's; before a run folder exists
        backend_factory = universal_policy_factory(config, robot, full_space, objectives)
        pretrained = shared and resolve_checkpoint(config) is not None
        if pretrained or (not shared and config.specialized_init == "universal"):
            check_policy_space(resolve_checkpoint(config), full_space, robot, mixed)
        policy = policy_provenance(config, used=shared or config.specialized_init == "universal")
        if pretrained:
            no_critic, note = objectives_without_critic(
                config, resolve_checkpoint(config), objectives
            )
            notes += [note] if note else []
    if not shared:  # the factory builds each design's policy
        backend_factory = specialized_factory(config, backend_factory)
    # the optimizer starts from the designs the policy is trained on (Algorithm 4 line 10): a
    # throwaway copy is asked now, unless building one has side effects (a study kept in the
    # run's store: options the plugin declares `from_run`); the loop checks the real first round too
    keeps_study = any(spec.from_run for spec in getattr(optimizer_cls, "option_specs", ()))
    if shared and not keeps_study:
        population = 1 if optimizer_cls.sequential else config.population
        if population == config.population:
            note = initial_designs_note(
                optimizer_cls, space, population, len(objectives), config.optimizer_options
            )
            notes += [f"warning: {note}"] if note else []
    return LoopParts(
        full_space,
        space,
        nominal,
        objectives,
        optimizer_cls,
        backend_factory,
        pretrained,
        policy,
        notes,
        no_critic,
    )


def check_store_options(config: CoadaptConfig, optimizer_cls: type[Optimizer]) -> None:
    """A database URL given to an optimizer option the run would otherwise fill with its store
    (`from_run="store_url"`, e.g. a study kept there), checked now: a bad one is one line
    before a run folder exists, not an error after the first training phase."""
    from coadapt_core.results.storage import check_database_url

    for spec in getattr(optimizer_cls, "option_specs", ()):
        value = config.optimizer_options.get(spec.name)
        if spec.from_run == "store_url" and value:
            check_database_url(str(value), field=spec.alias or f"optimizer_options.{spec.name}")


def check_device(device: str) -> None:
    """A CUDA device asked for where there is none: one line now, before a run folder exists."""
    if str(device).startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise UserError(
                f"device '{device}' requested but no CUDA device is available; use --device cpu",
                field="device",
            )


def check_policy_space(checkpoint: str | None, space: DesignSpace, robot, mixed: bool) -> None:
    """The starting policy takes as many design values as the run's design space has: a
    policy of the mixed space (motor types too) on the continuous one, or the other way round,
    is one line naming both, before a run folder exists."""
    from pathlib import Path

    if (
        checkpoint is None or not Path(checkpoint).is_file()
    ):  # a missing one is resolve_checkpoint's line
        return
    from coadapt_core.learning.checkpoints import read_checkpoint

    try:
        state = read_checkpoint(checkpoint)
    except UserError:  # not a policy file: the learner's own line says so when it loads it
        return
    takes = (state.get("dims") or {}).get("num_design")
    if takes is None or int(takes) == space.dim:
        return
    kind = "mixed" if mixed else "continuous"
    hint = "a policy trained on this space"
    if robot is not None and robot.design_space(not mixed).dim == int(takes):
        hint = (
            "--mixed, or " if not mixed else "no --mixed (a continuous-space optimizer), or "
        ) + hint
    raise UserError(
        f"checkpoint '{checkpoint}' takes {takes} design values and the run's {kind} design space has "
        f"{space.dim} ({', '.join(space.names)}); give {hint} (`coadapt train --robot {getattr(robot, 'name', 'ROBOT')}"
        f"{' --mixed' if mixed else ''}`)",
        field="checkpoint",
    )


def objectives_without_critic(
    config: CoadaptConfig, checkpoint: str, objectives: Sequence[Objective]
) -> tuple[list[str], str | None]:
    """(names, note): the run's objectives the starting policy carries no pseudo-critic for
    (its checkpoint's `objectives`), and the line the run starts with about them.

    The learner gives such an objective a fresh, untrained pseudo-critic head, whose
    predictions mean nothing. So, defined behaviour: a surrogate round of the run waits until
    the pseudo-critics have been fitted to a real round of the current policy (`fit_surrogate`;
    before that, and always with `fit_surrogate` off, rounds are real); a method evaluating
    with the surrogate only (no real rounds to fit to) is refused."""
    from pathlib import Path

    from coadapt_core.learning.checkpoints import read_checkpoint

    method = get_method(config.method)
    if method.surrogate_probability == 0.0:
        return [], None  # a method that never asks the surrogate
    saved = read_checkpoint(checkpoint).get("objectives")
    if not isinstance(saved, list | tuple):
        return [], None  # a checkpoint that does not say
    missing = [o.name for o in objectives if o.name not in saved]
    if not missing:
        return [], None
    what = (
        f"objective{'s' if len(missing) > 1 else ''} {', '.join(repr(m) for m in missing)} "
        f"{'have' if len(missing) > 1 else 'has'} no pseudo-critic in the starting policy {Path(checkpoint).name} "
        f"(it has {', '.join(saved) or 'none'})"
    )
    if method.surrogate_probability == 1.0:
        raise UserError(
            f"{what}, and method '{config.method}' evaluates with the surrogate only; train a policy with one "
            f"(`coadapt train --robot {config.robot} --terrain {config.terrain} --objectives "
            f"{','.join([*saved, *missing])}`) and pass --checkpoint PATH, or use a method with real rounds",
            field="objective",
        )
    if config.fit_surrogate:
        then = (
            "a surrogate round of this run waits until the pseudo-critics are fitted to a real round of the "
            "current policy (fit_surrogate); until then rounds are real"
        )
    else:
        then = "every round of this run is real (no surrogate rounds: fit_surrogate is off)"
    return missing, f"note: {what}: {then} (docs/plugins.md, section 5)"


def initial_designs_note(
    optimizer_cls: type[Optimizer],
    space: DesignSpace,
    population: int,
    num_objectives: int,
    options: dict,
) -> str | None:
    """A warning when the optimizer's first `ask` does not return the `initial_designs` it was
    built with (a plugin written before they were a constructor argument ignores them: the
    run would still finish, its first round not the designs the policy was trained on). One
    throwaway optimizer on sampled designs, before any training; one with options filled from
    the run (a study kept in the run's store, `from_run`) is not probed: the loop checks its
    real first round. None when it complies or cannot be probed (its own errors are reported
    when the run builds it)."""
    initial = space.sample(population, np.random.default_rng(0))
    try:
        first = optimizer_cls(
            space,
            population=population,
            budget=2,
            seed=1,
            num_objectives=num_objectives,
            initial_designs=initial,
            **options,
        ).ask()
    except Exception:
        return None
    return first_round_note(optimizer_cls.name, initial, first)


def note_first_round(
    notes: list[str], optimizer_cls: type[Optimizer], initial: np.ndarray, designs: np.ndarray
) -> None:
    """Say (once per run: stderr and `notes`, the summary's) when the optimizer's first round
    `designs` is not the `initial` designs it was built with (`initial_designs_note` probes
    for it before training where it can)."""
    rows = 1 if optimizer_cls.sequential else len(initial)
    note = first_round_note(optimizer_cls.name, initial[:rows], designs)
    if note is not None and not any(n.startswith(f"warning: {note[:40]}") for n in notes):
        notes.append(f"warning: {note}")
        print(f"warning: {note}", file=sys.stderr)


def first_round_note(name: str, initial: np.ndarray, first: np.ndarray) -> str | None:
    """The warning (without its 'warning: ' prefix) when an optimizer's first proposals
    `first` are not the `initial` designs it was given; None when they are."""
    first = np.atleast_2d(np.asarray(first, dtype=float))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if first.shape == initial.shape and np.allclose(first, initial, atol=1e-9):
        return None
    return (
        f"optimizer '{name}' ignores `initial_designs`: its first round is not the {len(initial)} designs the "
        "policy is trained on (Algorithm 4 line 10), so this run does not follow the paper; the plugin needs "
        "updating (docs/plugins.md#migration; OptimizerConformance checks it)"
    )


def policy_provenance(config: CoadaptConfig, *, used: bool = True) -> dict:
    """Which policy the run starts from: `source` 'shipped' (the robot's, `Robot.shipped_policy`),
    'path' (--checkpoint PATH) or 'none' (from scratch), the file's name and absolute path
    and its SHA-256, recorded in config.yaml, the summary and the store."""
    import hashlib
    from pathlib import Path

    path = resolve_checkpoint(config) if used else None
    if path is None:
        return {"source": "none", "file": None, "path": None, "sha256": None}
    try:
        digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:  # resolve_checkpoint found it; gone since: nothing to vouch for
        digest = None
    source = "path" if config.checkpoint.strip() else "shipped"
    out = {
        "source": source,
        "file": Path(path).name,
        "path": str(Path(path).resolve()),
        "sha256": digest,
    }
    if source == "shipped":
        out["robot"] = config.robot
    return out


def universal_policy_factory(
    config: CoadaptConfig, robot, full_space: DesignSpace, objectives: Sequence[Objective]
) -> Callable[[int], CoadaptationBackend]:
    """The real backend: the learner's universal policy (`coadapt_core.learning.factory`) on
    the configured simulator and terrain."""
    from coadapt_core.plugins import get_registry

    simulator_cls = get_registry().get("simulator", config.sim)
    try:
        from coadapt_core.learning.factory import make_backend
    except ImportError as exc:
        raise CoadaptError(
            f"the universal-policy learner (coadapt_core.learning) is not available: {exc}"
        ) from None
    # a policy of one design (a method without a shared policy: the BO baseline) is trained
    # from scratch (the paper's), or fine-tuned from the universal policy (`specialized_init:
    # universal`), with the universal training's batch (K x agents environments) on that design
    per_design = not get_method(config.method).backend_kind.shared_policy
    checkpoint = (
        resolve_checkpoint(config)
        if not per_design or config.specialized_init == "universal"
        else None
    )
    agents = (
        config.population * config.agents_per_design if per_design else config.agents_per_design
    )
    learner = learner_settings(config, checkpoint)  # the run's train / task / randomization keys

    def factory(seed: int) -> CoadaptationBackend:
        return make_backend(
            robot,
            simulator_cls,
            list(objectives),
            terrain=config.terrain,
            design_space=full_space,
            agents_per_design=agents,
            device=config.device,
            seed=seed,
            checkpoint=checkpoint,
            **learner,
        )

    return factory


def learner_settings(config: CoadaptConfig, checkpoint: str | None) -> dict[str, Any]:
    """The backend's `train_config`, `task_config` and `randomization` where the run sets
    any of them: the starting policy's (the `checkpoint` file's; the defaults without one)
    with the run's keys applied. Sections the run leaves unset are not returned, so the
    backend takes them from the checkpoint as it always has."""
    changed = {name: overrides(getattr(config, name)) for name in SECTIONS}
    if not any(changed.values()):
        return {}
    saved = None
    if checkpoint:
        from coadapt_core.learning.trainer import read_checkpoint

        saved = read_checkpoint(checkpoint)
    return resolve_learner(saved, changed["train"], changed["task"], changed["randomization"])


def specialized_factory(
    config: CoadaptConfig, policy_factory: Callable[[int], CoadaptationBackend]
) -> Callable[[int], CoadaptationBackend]:
    """The backend of a method without a shared policy: `SpecializedPolicyBackend` training
    each design's policy (`policy_factory`) for `specialized_train_steps` interactions."""

    def factory(seed: int) -> CoadaptationBackend:
        return SpecializedPolicyBackend(
            policy_factory, train_steps=config.specialized_train_steps, seed=seed
        )

    return factory


def no_policy_message(robot: str, terrain: str, mixed: bool, why: str = "ships no policy") -> str:
    space = "mixed" if mixed else "continuous"
    return (
        f"robot '{robot}' {why} for terrain '{terrain}' and the {space} design space: train one with "
        f"`coadapt train --robot {robot} --terrain {terrain}{' --mixed' if mixed else ''}` and pass "
        "--checkpoint PATH, or pass --checkpoint none to train from scratch in this run (its result is "
        "then marked unreliable unless the real rounds pass the walking gate, docs/plugins.md)"
    )


def check_starting_policy(config: CoadaptConfig) -> None:
    """`resolve_checkpoint`'s one-line `UserError` when the run would start from a policy it
    cannot have (the robot ships none for the terrain and space, a path that is missing or
    another robot's, a policy of the other design space); nothing for a method whose policies
    are trained per design from scratch. `coadapt run --check` (and so every cell of `coadapt
    grid`) asks it before anything starts."""
    if (
        get_method(config.method).backend_kind.shared_policy
        or config.specialized_init == "universal"
    ):
        checkpoint = resolve_checkpoint(config)
        if checkpoint is not None:
            from coadapt_core.plugins import get_registry

            robot = get_registry().create("robot", config.robot)
            mixed = uses_mixed_space(config)
            check_policy_space(checkpoint, robot.design_space(mixed), robot, mixed)


def resolve_checkpoint(config: CoadaptConfig) -> str | None:
    """'' -> the policy the robot ships for the terrain and design space
    (`Robot.shipped_policy`), 'none' -> from scratch, else a path that must exist.

    No silent meaningless result: when the robot ships no fitting policy, this is a user
    error saying how to get one (a run from scratch must be asked for with 'none')."""
    from pathlib import Path

    text = config.checkpoint.strip()
    if text.lower() == "none":
        return None
    if text:
        if not Path(text).is_file():
            raise UserError(f"checkpoint '{text}' does not exist", field="checkpoint")
        from coadapt_core.learning.checkpoints import read_checkpoint

        trained_for = read_checkpoint(text).get(
            "robot"
        )  # weights_only; one line if not a checkpoint
        if trained_for != config.robot:
            raise UserError(
                f"checkpoint '{text}' was trained for robot '{trained_for}', not '{config.robot}'; "
                "give a policy of this robot or --checkpoint none",
                field="checkpoint",
            )
        return text
    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", config.robot)
    mixed = uses_mixed_space(config)
    path = robot.shipped_policy(config.terrain, mixed)
    if path is None:
        raise UserError(no_policy_message(config.robot, config.terrain, mixed), field="checkpoint")
    # a shipped policy takes the design input it was trained on; check it matches this space
    from coadapt_core.learning.checkpoints import read_checkpoint

    trained_dim = int(read_checkpoint(path)["dims"]["num_design"])
    wanted_dim = robot.design_space(mixed).dim
    if trained_dim != wanted_dim:
        why = f"ships a policy ({Path(path).name}) taking {trained_dim} design values, not {wanted_dim},"
        raise UserError(
            no_policy_message(config.robot, config.terrain, mixed, why), field="checkpoint"
        )
    return str(path)
