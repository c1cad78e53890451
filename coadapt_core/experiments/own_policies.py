"""The policies of a run without a shared one (a method whose backend kind trains a policy per
design: the BO baseline), for the yardstick and the sim-to-sim check.

Such a run evaluates each design with that design's own policy, so its best and nominal
designs are re-evaluated each with its own. A run made since the BO baseline kept them left
them in its run folder (`OWN_POLICY_FILES`, looked up by name inside the folder, never by a
path read from a store). For an older run they are trained again, as the run trained them:
the same starting policy (checked by its SHA-256 against the run's record), the same
settings and the same seeds (`SpecializedPolicyBackend.policy_seeds` of the run's backend
seed and the design's exact value), into a folder the caller gives.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections import OrderedDict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.coadapt.specialized import (
    OWN_POLICY_FILES,
    SpecializedPolicyBackend,
    design_key,
    stack_fits,
)
from coadapt_core.errors import BackendUnavailable, UserError
from coadapt_core.fitness import CoadaptationBackend, RealFitness
from coadapt_core.results.rows import checkpoint_of

ROLES = ("best", "nominal")


def shares_policy(run: dict[str, Any]) -> bool:
    """Whether the run's method shares one policy between designs (an unknown method: yes,
    the run's last checkpoint then serves as before)."""
    from coadapt_core.methods import get_method

    name = run.get("method") or (run.get("config") or {}).get("method")
    try:
        return bool(get_method(str(name)).backend_kind.shared_policy)
    except (UserError, KeyError, ValueError):
        return True


def saved_policies(run: dict[str, Any]) -> dict[str, Path] | None:
    """The best and nominal designs' policies the run saved, inside its own folder; None when
    either is missing (a run made before they were kept)."""
    found = {role: checkpoint_of(run, OWN_POLICY_FILES[role]) for role in ROLES}
    if any(p is None or not p.is_file() for p in found.values()):
        return None
    return {role: Path(p) for role, p in found.items() if p is not None}


def retrain_policies(
    run: dict[str, Any],
    designs: dict[str, np.ndarray],
    folder: Path,
    *,
    policy_factory: Callable[[int], CoadaptationBackend] | None = None,
) -> dict[str, Path]:
    """Train each of `designs` (role -> design) its policy again as the run did, save it in
    `folder` as `policy-<role>.pt` and return the paths. `policy_factory(seed)` builds one
    policy (default: the run's learner, from its recorded config). BackendUnavailable when
    the run cannot be repeated (its starting policy is not the one it recorded)."""
    from coadapt_core.coadapt.config_loading import config_from_dict
    from coadapt_core.coadapt.loop import seed_at

    try:
        config = config_from_dict(dict(run.get("config") or {}))
    except (UserError, TypeError, ValueError) as exc:
        raise BackendUnavailable(
            f"the run's recorded config cannot be rebuilt ({' '.join(str(exc).split())})"
        ) from None
    if policy_factory is None:
        policy_factory = run_learner(config, run)
    # the loop builds its backend with seed_for(0) (CoadaptationLoop.get_backend)
    backend = SpecializedPolicyBackend(
        policy_factory,
        train_steps=config.specialized_train_steps,
        seed=seed_at(config.seed, 0),
        keep=1,
    )
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    try:
        for role, design in designs.items():
            out[role] = folder / f"policy-{role}.pt"
            backend.save_policy(np.asarray(design, dtype=float), str(out[role]))
    finally:
        backend.close()
    return out


def run_learner(config: Any, run: dict[str, Any]) -> Callable[[int], CoadaptationBackend]:
    """The per-design policy factory of the run (`backends.universal_policy_factory`), after
    checking that the starting policy it resolves to is the file the run recorded."""
    from coadapt_core.coadapt.backends import universal_policy_factory
    from coadapt_core.coadapt.search import make_objectives, uses_mixed_space
    from coadapt_core.coadapt.starting_policy import policy_provenance, resolve_checkpoint
    from coadapt_core.plugins import get_registry

    recorded = (
        (run.get("config") or {}).get("policy") or (run.get("summary") or {}).get("policy") or {}
    )
    checkpoint = None  # each design's policy from scratch (the paper's)
    if config.specialized_init == "universal":
        if config.checkpoint.strip():
            raise BackendUnavailable(
                "the run's policies started from a file it was given (--checkpoint), "
                "not one the robot ships; they cannot be trained again here"
            )
        checkpoint = resolve_checkpoint(config)
        now = policy_provenance(config, checkpoint)
        if recorded.get("sha256") and now.get("sha256") != recorded.get("sha256"):
            raise BackendUnavailable(
                f"the starting policy {now.get('file')} is not the one the run started from "
                "(SHA-256 differs); its policies cannot be trained again"
            )
    robot = get_registry().create("robot", config.robot)
    space = robot.design_space(uses_mixed_space(config))
    # only a run without a shared policy has its policies trained again
    return universal_policy_factory(
        config, robot, space, make_objectives(config), shared=False, checkpoint=checkpoint
    )


#: policies trained again in this process, (run id, role, design) -> file bytes, so the
#: yardstick and the sim-to-sim check of one report train each once; the last few are kept
_RETRAINED: OrderedDict[tuple[str, str, bytes], bytes] = OrderedDict()
RETRAINED_KEPT = 8


@contextlib.contextmanager
def policy_files(run: dict[str, Any], designs: dict[str, np.ndarray]) -> Iterator[dict[str, Path]]:
    """role -> policy file: the run's saved policies, else the same trained again (or kept
    from an earlier call) in a temporary folder that lasts as long as the `with` block."""
    saved = saved_policies(run)
    if saved is not None:
        yield saved
        return
    with tempfile.TemporaryDirectory(prefix="coadapt-own-policies-") as tmp:
        folder = Path(tmp)
        keys = {role: (str(run.get("id")), role, design_key(d)) for role, d in designs.items()}
        missing = {role: designs[role] for role, key in keys.items() if key not in _RETRAINED}
        for role, path in retrain_policies(run, missing, folder).items() if missing else ():
            _RETRAINED[keys[role]] = path.read_bytes()
        while len(_RETRAINED) > RETRAINED_KEPT:
            _RETRAINED.popitem(last=False)
        out = {}
        for role, key in keys.items():
            out[role] = folder / f"policy-{role}.pt"
            if not out[role].exists():
                out[role].write_bytes(_RETRAINED[key])
        yield out


def run_nominal(robot: Any, run: dict[str, Any], dim: int) -> np.ndarray:
    """The nominal design the run compared against: its summary's, else the robot's of the
    design space with the run's dimension."""
    recorded = (run.get("summary") or {}).get("nominal_design")
    if isinstance(recorded, list) and len(recorded) == dim:
        return np.asarray(recorded, dtype=float)
    for mixed in (False, True):
        nominal = np.asarray(robot.nominal_design(mixed=mixed), dtype=float)
        if nominal.shape[0] == dim:
            return nominal
    raise BackendUnavailable(f"robot '{robot.name}' has no design space of {dim} variables")


def run_backend(
    run: dict[str, Any],
    dim: int,
    simulator: str | None,
    agents: int,
    checkpoint: str,
    factory: Callable[..., CoadaptationBackend] | None = None,
) -> tuple[CoadaptationBackend, list, np.ndarray]:
    """(backend on `simulator` for the run's robot, terrain and design space of dimension `dim`
    with the policy in `checkpoint`, the run's objectives, its nominal design); the yardstick
    passes the run's own simulator, the sim-to-sim check a second one."""
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    cfg = run.get("config") or {}
    robot_name = run.get("robot") or cfg.get("robot")
    if not robot_name or not simulator:
        raise BackendUnavailable("the run recorded no robot or simulator")
    robot, sim_cls, objectives = resolve_plugins(
        str(robot_name), str(simulator), list(run["objectives"])
    )
    nominal = run_nominal(robot, run, dim)
    space = next(
        (s for s in (robot.design_space(False), robot.design_space(True)) if s.dim == dim), None
    )
    backend = (factory or make_backend)(
        robot,
        sim_cls,
        objectives,
        terrain=run.get("terrain") or "flat",
        design_space=space,
        agents_per_design=agents,
        device=str(cfg.get("device", "cpu")),
        seed=int(run.get("seed") or 0),
        checkpoint=checkpoint,
    )
    return backend, objectives, nominal


def run_objectives(run: dict[str, Any], simulator: str | None = None) -> list:
    """The run's objectives as `run_backend` makes them (registered names, default options);
    `BackendUnavailable` when the run's robot or `simulator` cannot be had here."""
    from coadapt_core.learning.factory import resolve_plugins

    cfg = run.get("config") or {}
    robot_name = run.get("robot") or cfg.get("robot")
    if not robot_name or not simulator:
        raise BackendUnavailable("the run recorded no robot or simulator")
    return resolve_plugins(str(robot_name), str(simulator), list(run["objectives"]))[2]


def nominal_of(run: dict[str, Any], dim: int) -> np.ndarray:
    """The run's nominal design (its summary's, else its robot's of dimension `dim`)."""
    from coadapt_core.plugins import get_registry

    cfg = run.get("config") or {}
    return run_nominal(
        get_registry().create("robot", str(run.get("robot") or cfg.get("robot"))), run, dim
    )


def each_own_policy(
    make: Callable[[Path], CoadaptationBackend],
    files: dict[str, Path],
    designs: dict[str, np.ndarray],
    evaluate: Callable[[CoadaptationBackend, np.ndarray], list[RealFitness]],
) -> list[RealFitness]:
    """`evaluate(backend, design[None])` for the best and the nominal design, each on a
    backend `make(policy file)` built from its own policy; returns one fit per call with the
    two designs as rows (best 0, nominal 1), as a shared policy's evaluation of both gives."""
    parts = []
    for role in ROLES:
        backend = make(files[role])
        try:
            parts.append(evaluate(backend, np.asarray(designs[role], dtype=float)[None, :]))
        finally:
            close = getattr(backend, "close", None)
            if callable(close):
                close()
    return [stack_fits(pair) for pair in zip(*parts, strict=True)]
