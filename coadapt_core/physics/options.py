"""The rules of a simulator's options, shared by every backend (`Simulator.__init__` and
`Simulator.set_gain_law` apply them): the checks of the constructor's arguments, each a
one-line `UserError` naming the field, and the "nominal" PD gain law (`NominalGains`)."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from coadapt_core.errors import UserError

if TYPE_CHECKING:
    from coadapt_core.robot import Robot


def _whole(value: Any, least: int) -> bool:
    """Whether `value` is a whole number (not a bool) of at least `least`."""
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
    designs = np.asarray(designs, dtype=float)
    designs = designs.reshape(1, -1) if designs.ndim == 1 else designs
    if designs.ndim != 2 or designs.shape[0] < 1:
        raise UserError(
            f"designs must be a non-empty [num_envs, design_dim] array, got shape {designs.shape}",
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
