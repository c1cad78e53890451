"""The universal policy specialised to one design, as a deployable ONNX graph.

π(a | o, ξ) becomes a function of the observation alone: the design input ξ is a constant,
the running observation normaliser (mean, variance, clip) and the action clip are nodes of
the graph, and it returns the raw action (fed back into the next observation's action
history) and the joint position targets default + scale * action. Input `obs` [batch,
num_obs] float32; outputs `actions` and `joint_targets` [batch, num_joints] float32.
Exported with torch's own exporter (`torch.onnx.export(dynamo=True)`, which needs
onnxscript) and checked against the torch policy with onnxruntime before it is kept.
"""

from __future__ import annotations

import contextlib
import io
import logging
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from coadapt_core.errors import UserError

#: what `pip install` brings the handoff: the exporter's and the runtime's packages
DEPLOY_MODULES = ("onnx", "onnxscript", "onnxruntime")
DEPLOY_EXTRA = "coadapt[deploy]"
#: largest |onnxruntime action - torch action| accepted on the recorded observations
#: (actions are O(1) and the policy is float32: both run the same float32 operations)
ONNX_TOLERANCE = 1e-4
INPUT_NAME = "obs"
OUTPUT_NAMES = ("actions", "joint_targets")
#: ONNX operator set the graph is written in (onnxruntime >= 1.18 runs it)
OPSET = 20


def missing_deploy_modules() -> list[str]:
    """The packages of the `deploy` extra that cannot be imported here."""
    import importlib.util

    missing = []
    for name in DEPLOY_MODULES:
        try:
            found = (
                sys.modules[name] is not None
                if name in sys.modules
                else importlib.util.find_spec(name) is not None
            )
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.append(name)
    return missing


class SpecialisedPolicy(nn.Module):
    """The actor's mean for one design: obs [B, num_obs] -> (actions, joint_targets) [B, J].
    The mean itself is the learner's (`PPO.mean_actor`); this adds the design constant, the
    action clip and the joint targets."""

    def __init__(
        self,
        state: dict[str, Any],
        design_obs: np.ndarray,
        default_joint_pos: np.ndarray,
        action_scale: float,
        action_clip: float,
    ):
        super().__init__()
        from coadapt_core.learning.checkpoints import load_policy

        ppo = load_policy(state)
        self.num_obs = int(ppo.dims.num_obs)
        self.num_actions = int(ppo.dims.num_actions)
        num_design = int(ppo.dims.num_design)
        if len(design_obs) != num_design:
            raise UserError(
                f"the policy takes {num_design} design values, the design has {len(design_obs)}",
                field="design",
            )
        self.actor = ppo.mean_actor()
        self.register_buffer(
            "design_obs", torch.as_tensor(np.asarray(design_obs, dtype=np.float32))
        )  # [D]
        self.register_buffer(
            "default_joint_pos", torch.as_tensor(np.asarray(default_joint_pos, dtype=np.float32))
        )  # [J]
        self.action_scale = float(action_scale)
        self.action_clip = float(action_clip)
        self.eval()

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        xi = self.design_obs.unsqueeze(0).expand(obs.shape[0], -1)  # [B, D]
        actions = self.actor(obs, xi).clamp(-self.action_clip, self.action_clip)
        return actions, self.default_joint_pos + self.action_scale * actions


def torch_actions(state: dict[str, Any], obs: np.ndarray, design_obs: np.ndarray) -> np.ndarray:
    """[N, J] the policy mean exactly as the learner computes it (`PPO.act_inference`,
    then the task's action clip is applied by the caller): the reference the ONNX graph is
    checked against, the learner's own forward pass, not `SpecialisedPolicy`'s copy."""
    from coadapt_core.learning.checkpoints import load_policy

    ppo = load_policy(state)
    with torch.no_grad():
        x = torch.as_tensor(np.asarray(obs, dtype=np.float32))
        xi = torch.as_tensor(np.asarray(design_obs, dtype=np.float32)).expand(x.shape[0], -1)
        return ppo.act_inference(x, xi).numpy()


@contextlib.contextmanager
def _quiet_exporter():
    """The exporter logs its progress and optional-package notes (torchvision) on stderr and
    stdout; a command prints its own lines only."""
    loggers = [
        logging.getLogger(name)
        for name in ("torch.onnx", "torch.export", "torch._dynamo", "onnxscript")
    ]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    sink = io.StringIO()
    try:
        import warnings

        with warnings.catch_warnings(), contextlib.redirect_stdout(sink):
            warnings.simplefilter("ignore")
            yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def export_onnx(policy: SpecialisedPolicy, path: Path, metadata: dict[str, str]) -> Path:
    """Write `policy` as an ONNX file (batch dimension dynamic) with `metadata` in the
    model's metadata_props."""
    import onnx

    example = torch.zeros(1, policy.num_obs)
    with _quiet_exporter():
        program = torch.onnx.export(
            policy,
            (example,),
            None,
            dynamo=True,
            input_names=[INPUT_NAME],
            output_names=list(OUTPUT_NAMES),
            dynamic_shapes={INPUT_NAME: {0: torch.export.Dim("batch")}},
            opset_version=OPSET,
            verbose=False,
        )
    if program is None:  # pragma: no cover - the dynamo exporter always returns its program
        raise RuntimeError("torch.onnx.export returned no program")
    model = program.model_proto
    model.doc_string = metadata.get("description", "")
    for key, value in metadata.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = str(key), str(value)
    onnx.checker.check_model(model)
    path = Path(path)
    onnx.save_model(model, str(path))
    return path


def onnx_actions(path: Path, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(actions, joint_targets) [N, J] of the ONNX file at `path` under onnxruntime (CPU)."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.log_severity_level = 3
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    actions, targets = session.run(
        list(OUTPUT_NAMES), {INPUT_NAME: np.asarray(obs, dtype=np.float32)}
    )
    return np.asarray(actions), np.asarray(targets)


def verify_onnx(
    path: Path,
    state: dict[str, Any],
    obs: np.ndarray,
    design_obs: np.ndarray,
    default_joint_pos: np.ndarray,
    action_scale: float,
    action_clip: float,
) -> dict[str, float]:
    """Max |ONNX - torch| over the recorded observations `obs` [N, num_obs], for the actions
    and the joint targets; the torch side is the learner's own `act_inference`."""
    reference = np.clip(torch_actions(state, obs, design_obs), -action_clip, action_clip)
    targets = np.asarray(default_joint_pos, dtype=np.float32) + np.float32(action_scale) * reference
    actions, joint_targets = onnx_actions(path, obs)
    return {
        "max_abs_action_difference": float(np.max(np.abs(actions - reference))),
        "max_abs_target_difference": float(np.max(np.abs(joint_targets - targets))),
        "observations": int(len(obs)),
        "tolerance": ONNX_TOLERANCE,
    }
