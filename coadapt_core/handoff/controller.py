"""The handoff's controller: the run's policy specialised to the design, exported to ONNX and
checked against torch on recorded observations (the run's evaluation buffer and the design's
own rollout), refused beyond the tolerance; reference.npz holds rows of both for check.py."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import __version__
from coadapt_core.errors import CoadaptError
from coadapt_core.handoff.measure import buffer_observations, rollout
from coadapt_core.handoff.resolve import ResolvedRun

#: rows of (observation, torch action) kept in reference.npz for check.py
REFERENCE_ROWS = 256


class HandoffRefused(CoadaptError):
    """The controller failed its own check (ONNX against torch): nothing is handed off."""


def export_controller(
    run: ResolvedRun, partial: Path, say: Callable[[str], None]
) -> tuple[dict[str, Any], dict[str, Any], Path]:
    """The policy specialised to the design, exported to ONNX and checked against torch on
    recorded observations (refused beyond the tolerance), with reference.npz for check.py:
    (rollout, verification, ONNX path)."""
    from coadapt_core.handoff.policy import ONNX_TOLERANCE, export_onnx, torch_actions, verify_onnx

    walked = rollout(run.robot, run.sim_cls, run.design, run.state, run.terrain, run.seed)
    task = walked["task"]
    num_obs = int(run.state["dims"]["num_obs"])
    recorded = np.concatenate([buffer_observations(run.run_dir, num_obs), walked["obs"]])
    metadata = {
        "description": f"coadapt universal policy specialised to {run.robot.name} design "
        + ", ".join(f"{n}={x:g}" for n, x in zip(run.space.names, run.design, strict=True)),
        "robot": run.robot.name,
        "design": json.dumps([float(x) for x in run.design]),
        "run_id": str(run.summary.get("run_id")),
        "coadapt_version": __version__,
        "observation_layout": "see policy.json",
    }
    onnx_path = export_onnx(walked["policy"], partial / "policy.onnx", metadata)
    verification = verify_onnx(
        onnx_path,
        run.state,
        recorded,
        walked["design_obs"],
        walked["default_joint_pos"],
        task.action_scale,
        task.action_clip,
    )
    say(
        f"ONNX vs torch on {verification['observations']} recorded observations: max |action "
        f"difference| {verification['max_abs_action_difference']:.2e} (tolerance "
        f"{ONNX_TOLERANCE:g})"
    )
    if not verification["max_abs_action_difference"] <= ONNX_TOLERANCE:
        raise HandoffRefused(
            "the ONNX controller differs from the torch policy by "
            f"{verification['max_abs_action_difference']:.2e} > {ONNX_TOLERANCE:g} on the "
            "recorded observations; not handed off"
        )
    pick = np.random.default_rng(0).choice(
        len(recorded), min(REFERENCE_ROWS, len(recorded)), replace=False
    )
    reference_obs = recorded[np.sort(pick)]
    reference_actions = np.clip(
        torch_actions(run.state, reference_obs, walked["design_obs"]),
        -task.action_clip,
        task.action_clip,
    ).astype(np.float32)
    np.savez(partial / "reference.npz", obs=reference_obs, actions=reference_actions)
    return walked, verification, onnx_path
