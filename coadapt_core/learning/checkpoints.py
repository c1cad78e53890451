"""Policy checkpoints as files: their two formats (`Trainer.save`'s full checkpoint and
`Trainer.export_weights`' weights), reading one without unpickling anything
(`read_checkpoint`), its policy rebuilt for inference (`load_policy`), and the surgery a
saved state may need before it loads: pseudo-critic heads matched to objectives by name, a
wider design input (`widen_design_input`), command inputs that never varied opened for a
wider command box (`open_command_inputs`)."""

from __future__ import annotations

import pickle  # only for its exception type: nothing is unpickled here
import re
import sys
from collections.abc import Callable
from pathlib import Path

import torch

from coadapt_core.errors import UserError
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.networks import CriticBank
from coadapt_core.learning.ppo import PPO, Dims
from coadapt_core.task.config import CommandConfig
from coadapt_core.task.observations import policy_layout, slices

CHECKPOINT_FORMAT = "coadapt-policy-1"
WEIGHTS_FORMAT = "coadapt-policy-weights-1"


def read_checkpoint(path: str | Path) -> dict:
    """The dict saved by `Trainer.save` / `export_weights`; a one-line `UserError` otherwise.

    Loaded with `weights_only=True`: tensors, numbers, strings and containers only. A file
    carrying anything else (a pickled object, possibly planted to run code) is refused
    without running it."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"checkpoint '{path}' does not exist", field="checkpoint")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:
        raise UserError(
            f"checkpoint '{path}' holds objects other than tensors and plain values; refused "
            "(it is not a coadapt checkpoint, or was altered)",
            field="checkpoint",
        ) from None
    except Exception as exc:
        raise UserError(
            f"checkpoint '{path}' cannot be read ({type(exc).__name__}); "
            "it is damaged or not a checkpoint",
            field="checkpoint",
        ) from None
    if not isinstance(state, dict) or state.get("format") not in (
        CHECKPOINT_FORMAT,
        WEIGHTS_FORMAT,
    ):
        raise UserError(f"'{path}' is not a coadapt policy checkpoint", field="checkpoint")
    return state


def load_policy(state: dict) -> PPO:
    """A learner on the CPU holding the policy of a state `read_checkpoint` returned (either
    format): the actor and observation normaliser loaded and in eval mode (`PPO.load_actor`),
    for `act_inference` and `mean_actor`; the critics and optimizers are fresh."""
    config = TrainConfig.from_dict(state["train_config"])
    config.device = "cpu"
    dims = Dims(**{**state["dims"], "num_metrics": len(state["objectives"])})
    ppo = PPO(dims, config, torch.device("cpu"))
    ppo.load_actor(state["ppo"])
    return ppo


def match_objectives(ppo_state: dict, saved_names: list[str], names: list[str], ppo: PPO) -> dict:
    """A copy of a saved PPO state whose pseudo-critics (heads and target normaliser) follow
    the objectives `names` by name: each takes the saved one of the same objective, one
    whose name is new starts fresh (from `ppo`'s)."""
    out = dict(ppo_state)
    out["pseudo_critic"] = _remap_heads(out.get("pseudo_critic"), saved_names, names, ppo)
    out["pseudo_norm"] = _remap_norm(out["pseudo_norm"], saved_names, names, ppo)
    return out


def _remap_heads(
    saved: dict | None, saved_names: list[str], names: list[str], ppo: PPO
) -> dict | None:
    """The pseudo-critic bank's state with head i taken from the saved head of the same
    objective name (a fresh head where the name is new); the saved state may be of the
    per-head layout."""
    if ppo.pseudo_critic is None:
        return None
    out = {k: v.clone() for k, v in ppo.pseudo_critic.state_dict().items()}
    saved = CriticBank.convert_state_dict(saved)
    for i, name in enumerate(names):
        if saved is not None and name in saved_names:
            j = saved_names.index(name)
            for key in out:
                out[key][i] = saved[key][j]
    return out


def _remap_norm(saved: dict, saved_names: list[str], names: list[str], ppo: PPO) -> dict:
    out = {k: v.clone() for k, v in ppo.pseudo_norm.state_dict().items()}
    for i, name in enumerate(names):
        if name in saved_names:
            j = saved_names.index(name)
            out["mean"][i] = saved["mean"][j]
            out["var"][i] = saved["var"][j]
    out["count"] = saved["count"]
    return out


#: the first layers, which read the observation (the leading columns of their input) and the
#: design input xi (the last columns): the actor's trunk, the critic's and every
#: pseudo-critic's (per-head layout `heads.<h>.0.weight` [out, in], or the stacked bank's
#: `weight_0` [H, out, in])
_FIRST_LAYER = re.compile(r"^((body|heads\.\d+)\.0\.weight|weight_0)$")


def _map_first_layers(ppo: dict, fn: Callable[[torch.Tensor], torch.Tensor]) -> dict:
    """A copy of a PPO state dict whose first-layer weights (actor, critic, pseudo-critics)
    are replaced by fn(weight)."""
    ppo = dict(ppo)
    for net in ("actor", "critic", "pseudo_critic"):
        if ppo.get(net) is None:
            continue
        ppo[net] = {key: fn(t) if _FIRST_LAYER.match(key) else t for key, t in ppo[net].items()}
    return ppo


def widen_design_input(state: dict, num_design: int) -> dict:
    """A copy of checkpoint `state` whose networks take `num_design` design values instead of
    fewer: the new inputs (appended after the existing ones, as the design space appends its
    variables) get zero weights, so the widened policy, critic and pseudo-critics compute
    exactly what the original did whatever the new variables' values, and training then
    learns how much they matter. Optimizer states are dropped (their shapes change)."""
    old = int(state["dims"]["num_design"])
    if num_design < old:
        raise UserError(
            f"a policy taking {old} design values cannot be narrowed to {num_design}",
            field="checkpoint",
        )
    out = dict(state)
    out["dims"] = {**state["dims"], "num_design": int(num_design)}
    ppo = {k: v for k, v in state["ppo"].items() if k not in ("optimizer", "pseudo_optimizer")}
    extra = num_design - old
    out["ppo"] = _map_first_layers(
        ppo, lambda w: torch.cat([w, torch.zeros(*w.shape[:-1], extra, dtype=w.dtype)], dim=-1)
    )
    out["widened_from"] = old
    return out


#: below this running variance a normaliser channel counts as constant (never varied)
_CONSTANT_VAR = 1e-8
_COMMAND_NAMES = ("vx", "vy", "yaw-rate")


def open_command_inputs(state: dict, commands: CommandConfig) -> tuple[dict, list[str]]:
    """A copy of checkpoint `state` ready for a task whose commands vary where its training's
    did not (e.g. yaw rates in [-1, 1] for a policy trained at yaw 0), and the names of the
    channels opened.

    A channel that never varied has a running variance of 0, so its normalised input was 0
    throughout training: the weights that read it never learned anything, and the normaliser,
    whose count is the whole training's, would scale a new command by 1/sqrt(eps) and clip it
    at +-clip for millions of steps (a 0.5 rad/s yaw command read as 5 standard deviations,
    whatever its size). Such a channel gets zero first-layer weights in the actor, critic and
    pseudo-critics, so the policy acts exactly as before whatever the new command, and the
    mean and variance of a uniform draw from the new range in both normalisers, so training
    sees the command at its true scale and learns how to use it."""
    ranges = (commands.vx_range, commands.vy_range, commands.yaw_range)
    offset = slices(policy_layout(1, 1))["command"].start  # the same column in o and s
    obs_var = state["ppo"]["obs_norm"]["var"]
    opened = [
        j
        for j, (lo, hi) in enumerate(ranges)
        if hi > lo and float(obs_var[offset + j]) < _CONSTANT_VAR
    ]
    if not opened:
        return state, []
    out = dict(state)
    ppo = dict(state["ppo"])
    columns = [offset + j for j in opened]

    def zero_columns(w: torch.Tensor) -> torch.Tensor:
        w = w.clone()
        w[..., columns] = 0.0
        return w

    ppo = _map_first_layers(ppo, zero_columns)
    for norm in ("obs_norm", "critic_norm"):
        buffers = dict(ppo[norm])
        mean, var = buffers["mean"].clone(), buffers["var"].clone()
        for j in opened:
            lo, hi = ranges[j]
            mean[offset + j] = 0.5 * (lo + hi)
            var[offset + j] = (hi - lo) ** 2 / 12.0
        buffers["mean"], buffers["var"] = mean, var
        ppo[norm] = buffers
    out["ppo"] = ppo
    return out, [_COMMAND_NAMES[j] for j in opened]


def weights_of(ppo_state: dict) -> dict:
    """The weights export's share of a `PPO.state_dict`: the networks and normalisers as
    float32 on the CPU, and the learning rate reached."""
    keep = ("actor", "critic", "pseudo_critic", "obs_norm", "critic_norm", "pseudo_norm")
    weights = {
        k: {n: (t.float() if t.is_floating_point() else t).cpu() for n, t in ppo_state[k].items()}
        for k in keep
        if ppo_state.get(k) is not None
    }
    # the KL-adapted learning rate reached: fine-tuning from this file starts there, not at
    # the configured initial rate (a fresh Adam at 1e-3 knocks a trained policy over)
    weights["learning_rate"] = float(ppo_state["learning_rate"])
    return weights


def fit_to_trainer(
    path: str | Path, state: dict, widen_to: int | None, commands: CommandConfig
) -> tuple[dict, bool]:
    """(the state read from `path` after its surgery, whether its design input was widened):
    widened to `widen_to` design values when it takes fewer (`widen_design_input`; None
    leaves it), its command inputs opened for the box of `commands` (`open_command_inputs`,
    with a note on stderr)."""
    widened = widen_to is not None and int(state["dims"]["num_design"]) < widen_to
    if widened:
        state = widen_design_input(state, widen_to)
    state, opened = open_command_inputs(state, commands)
    if opened:
        print(
            f"note: '{path}' never saw {' or '.join(opened)} commands vary; their inputs "
            "start with zero weights and the new range's scale",
            file=sys.stderr,
        )
    return state, widened
