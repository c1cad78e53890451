"""The rules of a simulator's options and arguments, shared by every backend (the `Simulator`
base applies them): the checks of the constructor's arguments, of the task settings a
backend offers, of environment ids and new designs, each a one-line error naming the field,
and the "nominal" PD gain law (`NominalGains`). Torch is imported by the checks that need it,
not with the module (docs/architecture.md, "Start-up")."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

from coadapt_core.errors import DesignError, UserError

if TYPE_CHECKING:
    import numpy as np
    import torch

    from coadapt_core.robot import Robot


def _whole(value: Any, least: int) -> bool:
    """Whether `value` is a whole number (not a bool) of at least `least`."""
    import numpy as np

    return not isinstance(value, bool) and isinstance(value, int | np.integer) and value >= least


def check_options(
    name: str,
    terrains: tuple[str, ...],
    *,
    terrain: str,
    physics_dt: float,
    decimation: int,
    seed: int,
    device: str,
    num_threads: int | None,
) -> torch.device:
    """Check a simulator's scalar options (`name` is the backend's, `terrains` those it
    offers); the torch device that `device` names."""
    import numpy as np

    if terrain not in terrains:
        raise UserError(
            f"unknown terrain '{terrain}'; {name} offers: {', '.join(terrains)}", field="terrain"
        )
    if not _whole(decimation, 1):
        raise UserError(
            f"decimation must be a whole number >= 1, got {decimation!r}", field="decimation"
        )
    if isinstance(physics_dt, bool) or not (
        isinstance(physics_dt, int | float | np.number)
        and math.isfinite(physics_dt)
        and physics_dt > 0
    ):
        raise UserError(
            f"physics_dt must be a positive number of seconds, got {physics_dt!r}",
            field="physics_dt",
        )
    if num_threads is not None and not _whole(num_threads, 1):
        raise UserError(
            f"num_threads must be a whole number >= 1, got {num_threads!r}", field="num_threads"
        )
    if not _whole(seed, 0):
        raise UserError(f"seed must be a whole number >= 0, got {seed!r}", field="seed")
    import torch

    try:
        return torch.device(device)
    except (RuntimeError, TypeError) as exc:
        raise UserError(
            f"device must be a torch device such as 'cpu' or 'cuda', got {device!r}",
            field="device",
        ) from exc


def design_array(designs: np.ndarray) -> np.ndarray:
    """`designs` as a float [num_envs, design_dim] array (one design may be given flat);
    anything else is a `UserError`."""
    import numpy as np

    designs = np.asarray(designs, dtype=float)
    designs = designs.reshape(1, -1) if designs.ndim == 1 else designs
    if designs.ndim != 2 or designs.shape[0] < 1:
        raise UserError(
            f"designs must be a non-empty [num_envs, design_dim] array, got shape {designs.shape}",
            field="designs",
        )
    return designs


def check_offered(choice: str, offered: tuple[str, ...], name: str, setting: str) -> str:
    """`choice` of the task setting `setting` when the simulator `name` offers it."""
    if choice not in offered:
        raise UserError(
            f"task.{setting}: the {name} simulator offers {', '.join(offered)}, got '{choice}'",
            field=setting,
        )
    return choice


def env_id_array(env_ids: torch.Tensor | np.ndarray | None, num_envs: int) -> np.ndarray:
    """Environment ids [n] (int numpy) from None (all), an index tensor or array, or a
    boolean mask; ids outside [0, num_envs) are a `UserError`."""
    import numpy as np

    if env_ids is None:
        return np.arange(num_envs)
    import torch

    if isinstance(env_ids, torch.Tensor):
        env_ids = env_ids.detach().cpu().numpy()
    ids = np.asarray(env_ids)
    if ids.dtype == bool:
        ids = np.flatnonzero(ids)
    ids = ids.astype(int).reshape(-1)
    if ids.size and (ids.min() < 0 or ids.max() >= num_envs):
        raise UserError(
            f"env_ids must lie in [0, {num_envs - 1}], got {ids.tolist()}", field="env_ids"
        )
    return ids


def new_design_array(designs: np.ndarray, count: int, width: int) -> np.ndarray:
    """`designs` as `count` designs of `width` values each (one may be given flat), for
    `Simulator.set_designs`; any other shape is a `DesignError`."""
    import numpy as np

    designs = np.asarray(designs, dtype=float)
    designs = designs.reshape(1, -1) if designs.ndim == 1 else designs
    if designs.shape != (count, width):
        raise DesignError(
            f"set_designs needs one design of {width} values per env id ({count} ids), "
            f"got an array of shape {designs.shape}",
            field="designs",
        )
    return designs


class NominalGains:
    """A robot whose every design gets the nominal design's PD gains (kp, kd; the nominal
    design of the space the design's arity names), everything else its own: the "nominal"
    gain law of `Simulator.set_gain_law`, for any robot."""

    def __init__(self, robot: Robot):
        self._robot = robot
        self._gains: dict[bool, tuple[np.ndarray, np.ndarray]] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self._robot, name)

    def build(self, design: np.ndarray):
        import numpy as np

        model = self._robot.build(design)
        mixed = len(np.atleast_1d(design)) != self._robot.design_space(False).dim
        if mixed not in self._gains:
            nominal = self._robot.build(self._robot.nominal_design(mixed))
            self._gains[mixed] = (
                np.array(nominal.kp, dtype=float),
                np.array(nominal.kd, dtype=float),
            )
        kp, kd = self._gains[mixed]
        return dataclasses.replace(model, kp=kp.copy(), kd=kd.copy())
