"""The finished run a handoff starts from, resolved: its plugins (robot, simulator), the
policy handed off and the one that judges the nominal design, and the design handed off
(the best one unless --design gives another), checked against the policy and the space."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.errors import UserError


@dataclass
class ResolvedRun:
    """A finished run as the handoff resolved it: plugins, policy and the design handed off."""

    run_dir: Path
    config: dict[str, Any]
    summary: dict[str, Any]
    registry: Any
    robot: Any
    sim_name: str
    sim_cls: type
    terrain: str
    seed: int
    checkpoint: Path  # the policy handed off, the one that judges the design
    nominal_checkpoint: (
        Path  # the one that judges the nominal design (the same for a shared policy)
    )
    own_policies: bool  # a run without a shared policy: each design judged by its own
    state: dict[str, Any]
    design: np.ndarray
    nominal: np.ndarray
    space: Any
    is_best: bool
    #: "universal" (the run's own policy) or "specialist" (`coadapt verify`'s, --policy)
    policy: str = "universal"


def _specialists(
    run_dir: Path, summary: dict[str, Any], design: np.ndarray | None
) -> dict[str, Path]:
    """--policy specialist: the specialists of the design (the run's best unless --design or
    --pick names another verified one) and of the nominal design, from the run's
    verification with the largest budget (`coadapt verify`)."""
    from coadapt_core.coadapt.verify import VERIFY_DIR, read_verifications

    found = read_verifications(run_dir)
    if not found:
        raise UserError(
            f"--policy specialist: run {run_dir.name} has no verification; run `coadapt verify "
            f"{run_dir}` first",
            field="policy",
        )
    wanted = np.asarray(summary["best_design"] if design is None else design, dtype=float)
    for result in reversed(found):
        specs = result.get("specialists") or {}
        for role, spec in specs.items():
            if role == "nominal" or len(spec["design"]) != len(wanted):
                continue
            if np.allclose(spec["design"], wanted) and "nominal" in specs:
                folder = run_dir / VERIFY_DIR / str(result["key"])
                return {
                    "best": folder / str(spec["checkpoint"]),
                    "nominal": folder / str(specs["nominal"]["checkpoint"]),
                }
    raise UserError(
        f"--policy specialist: no verification of run {run_dir.name} has a specialist for "
        f"design {', '.join(f'{x:g}' for x in wanted)}",
        field="policy",
    )


def _policies(
    run_dir: Path,
    config: dict[str, Any],
    summary: dict[str, Any],
    design: np.ndarray | None,
    policy: str,
) -> tuple[dict[str, Path] | None, str]:
    """(role -> policy file, why there is none): the run's own policies, or with
    `policy` "specialist" the design's and the nominal design's specialists."""
    from coadapt_core.viz.video import run_policies

    if policy == "specialist":
        return _specialists(run_dir, summary, design), ""
    return run_policies(run_dir, config)


def resolve_run(
    run_dir: Path,
    config: dict[str, Any],
    summary: dict[str, Any],
    design: np.ndarray | None,
    policy: str = "universal",
) -> ResolvedRun:
    """The run's plugins, final policy and the design (the best one unless --design gives
    another, checked against the policy's design input and the design space). A run without
    a shared policy hands off its best design's own policy and judges the nominal design by
    the nominal design's own; it has no policy for any other design."""
    from coadapt_core.experiments.own_policies import shares_policy
    from coadapt_core.learning.trainer import read_checkpoint
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    robot = registry.create("robot", config.get("robot") or registry.default("robot"))
    sim_name = str(config.get("sim") or registry.default("simulator"))
    sim_cls = registry.get("simulator", sim_name)
    policies, why = _policies(run_dir, config, summary, design, policy)
    if policies is None:
        again = (
            ""
            if shares_policy({"config": config})
            else "; coadapt report trains them again for its yardstick, the handoff does not"
        )
        raise UserError(
            f"run {run_dir.name}: {why}; there is no controller to hand off{again}", field="run"
        )
    own = policies["best"] != policies["nominal"]
    state = read_checkpoint(policies["best"])
    if state.get("robot") != robot.name:
        raise UserError(
            f"the run's checkpoint was trained for robot '{state.get('robot')}', not "
            f"'{robot.name}'",
            field="run",
        )
    best = np.asarray(summary["best_design"], dtype=float)
    design = best if design is None else np.asarray(design, dtype=float)
    if own and (design.shape != best.shape or not np.allclose(design, best)):
        raise UserError(
            f"--design: run {run_dir.name} shares no policy between designs and kept a policy of "
            "its own only for its best and nominal designs, none for another design; leave out "
            "--design to hand off the best one",
            field="design",
        )
    nominal = summary.get("nominal_design")
    if not isinstance(nominal, list) or len(nominal) != len(design):
        nominal = robot.nominal_design(robot.design_space_for(design).is_mixed)
    num_design = int(state["dims"]["num_design"])
    if len(design) != num_design:
        raise UserError(
            f"--design has {len(design)} values; the run's policy takes {num_design} "
            f"({', '.join(robot.design_space_for(best).names)})",
            field="design",
        )
    space = robot.design_space_for(design)
    design = space.validate(design)
    return ResolvedRun(
        run_dir=run_dir,
        config=config,
        summary=summary,
        registry=registry,
        robot=robot,
        sim_name=sim_name,
        sim_cls=sim_cls,
        terrain=str(config.get("terrain") or "flat"),
        seed=int(config.get("seed") or 0),
        checkpoint=policies["best"],
        nominal_checkpoint=policies["nominal"],
        own_policies=own,
        state=state,
        design=design,
        nominal=np.asarray(nominal, dtype=float),
        space=space,
        is_best=bool(np.allclose(design, best)),
        policy=policy,
    )


def judges(run: ResolvedRun) -> dict[str, Any]:
    """Which policy judged which design (design.json, policy.json, design.md)."""

    def name(path: Path) -> str:
        return str(path.relative_to(run.run_dir)) if run.run_dir in path.parents else path.name

    note = (
        "specialists fine-tuned from the run's universal policy by `coadapt verify`: the design "
        "is judged, and handed off, with its own specialist, the nominal design with the "
        "nominal design's"
        if run.policy == "specialist"
        else "the run shares no policy between designs: the design is judged, and handed off, "
        "with its own policy, the nominal design with the nominal design's own"
        if run.own_policies
        else "one universal policy (the run's final) judges both designs and is the one handed off"
    )
    return {
        "policy": run.policy,
        "shared": not run.own_policies,
        "design": name(run.checkpoint),
        "nominal": name(run.nominal_checkpoint),
        "note": note,
    }
