"""The policy a run starts from: the one its robot ships for the terrain and design space, a
file given with --checkpoint, or none (from scratch). Checked before a run folder exists (the
robot it was trained for, the design values it takes, the pseudo-critics it carries) and
recorded with its SHA-256 (`policy_provenance`)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.search import uses_mixed_space
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.methods import Method, get_method
from coadapt_core.objective import Objective
from coadapt_core.robot import Robot


@dataclass
class StartingPolicy:
    """The starting policy of a run, resolved once (`starting_policy`)."""

    checkpoint: str | None  # the file the learner starts from; None: from scratch
    pretrained: bool  # the shared policy starts from a trained one
    provenance: dict  # `policy_provenance`: recorded in config.yaml, the summary and the store
    #: the run's objectives the policy has no pseudo-critic for (`objectives_without_critic`)
    no_critic: list[str] = field(default_factory=list)
    note: str | None = None  # the line the run starts with about them


def starting_policy(
    config: CoadaptConfig,
    method: Method,
    robot: Robot,
    space: DesignSpace,
    mixed: bool,
    objectives: Sequence[Objective],
) -> StartingPolicy:
    """Resolve and check the policy a run of `method` starts from on `robot`'s design
    `space`: the universal policy a shared one starts from, or the one each design's policy
    is fine-tuned from (`specialized_init: universal`); none for policies from scratch."""
    shared = method.backend_kind.shared_policy
    used = shared or config.specialized_init == "universal"
    checkpoint = find_checkpoint(config, robot, mixed) if used else None
    pretrained = shared and checkpoint is not None
    if checkpoint is not None:
        check_policy_space(checkpoint, space, robot, mixed)
    provenance = policy_provenance(config, checkpoint)
    if not pretrained:
        return StartingPolicy(checkpoint, pretrained, provenance)
    no_critic, note = objectives_without_critic(config, method, checkpoint, objectives)
    return StartingPolicy(checkpoint, pretrained, provenance, no_critic, note)


def resolve_checkpoint(config: CoadaptConfig) -> str | None:
    """The starting policy's file of a config (`find_checkpoint` on its robot and space)."""
    text = config.checkpoint.strip()
    if text.lower() == "none" or text:
        return find_checkpoint(config, None, False)
    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", config.robot)
    return find_checkpoint(config, robot, uses_mixed_space(config))


def find_checkpoint(config: CoadaptConfig, robot: Robot | None, mixed: bool) -> str | None:
    """'' -> the policy `robot` ships for the terrain and (`mixed`) design space
    (`Robot.shipped_policy`), 'none' -> from scratch, else a path that must exist.

    No silent meaningless result: when the robot ships no fitting policy, this is a user
    error saying how to get one (a run from scratch must be asked for with 'none')."""
    text = config.checkpoint.strip()
    if text.lower() == "none":
        return None
    if text:
        if not Path(text).is_file():
            raise UserError(f"checkpoint '{text}' does not exist", field="checkpoint")
        from coadapt_core.learning.checkpoints import read_checkpoint

        # weights only; one line if not a checkpoint
        trained_for = read_checkpoint(text).get("robot")
        if trained_for != config.robot:
            raise UserError(
                f"checkpoint '{text}' was trained for robot '{trained_for}', not "
                f"'{config.robot}'; give a policy of this robot or --checkpoint none",
                field="checkpoint",
            )
        return text
    assert robot is not None, "a shipped policy is looked up on the run's robot"
    from coadapt_core.learning.checkpoints import read_checkpoint

    path = robot.shipped_policy(config.terrain, mixed)
    why = "ships no policy"
    if path is not None:
        # a shipped policy takes the design input it was trained on; check it matches this space
        trained_dim = int(read_checkpoint(path)["dims"]["num_design"])
        wanted_dim = robot.design_space(mixed).dim
        if trained_dim == wanted_dim:
            return str(path)
        why = (
            f"ships a policy ({Path(path).name}) taking {trained_dim} design values, "
            f"not {wanted_dim},"
        )
    raise UserError(no_policy_message(config.robot, config.terrain, mixed, why), field="checkpoint")


def no_policy_message(robot: str, terrain: str, mixed: bool, why: str = "ships no policy") -> str:
    space = "mixed" if mixed else "continuous"
    return (
        f"robot '{robot}' {why} for terrain '{terrain}' and the {space} design space: train "
        f"one with `coadapt train --robot {robot} --terrain {terrain}"
        f"{' --mixed' if mixed else ''}` and pass --checkpoint PATH, or pass --checkpoint none "
        "to train from scratch in this run (its result is then marked unreliable unless the "
        "real rounds pass the walking gate, docs/plugins.md)"
    )


def check_policy_space(checkpoint: str, space: DesignSpace, robot: Robot, mixed: bool) -> None:
    """The starting policy takes as many design values as the run's design space has: a
    policy of the mixed space (motor types too) on the continuous one, or the other way round,
    is one line naming both, before a run folder exists."""
    if not Path(checkpoint).is_file():  # a missing one is find_checkpoint's line
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
    if robot.design_space(not mixed).dim == int(takes):
        other = "no --mixed (a continuous-space optimizer)" if mixed else "--mixed"
        hint = f"{other}, or {hint}"
    raise UserError(
        f"checkpoint '{checkpoint}' takes {takes} design values and the run's {kind} design "
        f"space has {space.dim} ({', '.join(space.names)}); give {hint} (`coadapt train "
        f"--robot {robot.name}{' --mixed' if mixed else ''}`)",
        field="checkpoint",
    )


def policy_provenance(config: CoadaptConfig, path: str | None) -> dict:
    """Which policy the run starts from (`path`, the starting policy's file; None: from
    scratch): `source` 'shipped' (the robot's, `Robot.shipped_policy`), 'path' (--checkpoint
    PATH) or 'none', the file's name and absolute path and its SHA-256, recorded in
    config.yaml, the summary and the store."""
    if path is None:
        return {"source": "none", "file": None, "path": None, "sha256": None}
    try:
        digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:  # found when resolved; gone since: nothing to vouch for
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


def objectives_without_critic(
    config: CoadaptConfig, method: Method, checkpoint: str, objectives: Sequence[Objective]
) -> tuple[list[str], str | None]:
    """(names, note): the run's objectives the starting policy carries no pseudo-critic for
    (its checkpoint's `objectives`), and the line the run starts with about them.

    The learner gives such an objective a fresh, untrained pseudo-critic head, whose
    predictions mean nothing. So, defined behaviour: a surrogate round of the run waits until
    the pseudo-critics have been fitted to a real round of the current policy (`fit_surrogate`;
    before that, and always with `fit_surrogate` off, rounds are real); a method evaluating
    with the surrogate only (no real rounds to fit to) is refused."""
    if method.surrogate_probability == 0.0:
        return [], None  # a method that never asks the surrogate
    from coadapt_core.learning.checkpoints import read_checkpoint

    saved = read_checkpoint(checkpoint).get("objectives")
    if not isinstance(saved, list | tuple):
        return [], None  # a checkpoint that does not say
    missing = [o.name for o in objectives if o.name not in saved]
    if not missing:
        return [], None
    many = len(missing) > 1
    what = (
        f"objective{'s' if many else ''} {', '.join(repr(m) for m in missing)} "
        f"{'have' if many else 'has'} no pseudo-critic in the starting policy "
        f"{Path(checkpoint).name} (it has {', '.join(saved) or 'none'})"
    )
    if method.surrogate_probability == 1.0:
        raise UserError(
            f"{what}, and method '{method.name}' evaluates with the surrogate only; train a "
            f"policy with one (`coadapt train --robot {config.robot} --terrain {config.terrain} "
            f"--objectives {','.join([*saved, *missing])}`) and pass --checkpoint PATH, or use "
            "a method with real rounds",
            field="objective",
        )
    if config.fit_surrogate:
        then = (
            "a surrogate round of this run waits until the pseudo-critics are fitted to a real "
            "round of the current policy (fit_surrogate); until then rounds are real"
        )
    else:
        then = "every round of this run is real (no surrogate rounds: fit_surrogate is off)"
    return missing, f"note: {what}: {then} (docs/plugins.md, section 5)"


def check_starting_policy(config: CoadaptConfig) -> None:
    """`find_checkpoint`'s one-line `UserError` when the run would start from a policy it
    cannot have (the robot ships none for the terrain and space, a path that is missing or
    another robot's, a policy of the other design space); nothing for a method whose policies
    are trained per design from scratch. `coadapt run --check` (and so every cell of `coadapt
    grid`) asks it before anything starts."""
    shared = get_method(config.method).backend_kind.shared_policy
    if not (shared or config.specialized_init == "universal"):
        return
    checkpoint = resolve_checkpoint(config)
    if checkpoint is not None:
        from coadapt_core.plugins import get_registry

        robot = get_registry().create("robot", config.robot)
        mixed = uses_mixed_space(config)
        check_policy_space(checkpoint, robot.design_space(mixed), robot, mixed)
