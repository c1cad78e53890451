"""Batched rotations of the base frame: world vectors expressed in the frame of each
environment's base (torch), for `SimState.base_frame` (what the robot's IMU reads)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch


def quat_rotate_inverse(quat: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """World vectors vec [N, 3] expressed in the base frame of unit quaternions quat [N, 4]
    (w, x, y, z): R^T v = v (2w^2 - 1) - 2 w (q x v) + 2 q (q . v)."""
    import torch

    w = quat[:, 0:1]
    xyz = quat[:, 1:4]
    a = vec * (2.0 * w * w - 1.0)
    b = torch.cross(xyz, vec, dim=-1) * (2.0 * w)
    c = xyz * (2.0 * (xyz * vec).sum(dim=-1, keepdim=True))
    return a - b + c
