"""Quaternion helpers for batched base states; quaternions are (w, x, y, z), base to world."""

from __future__ import annotations

import torch


def quat_rotate_inverse(quat: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """World vectors vec [N, 3] expressed in the base frame of quat [N, 4] (R^T v)."""
    return _rotate(quat, vec, inverse=True)


def quat_rotate(quat: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """Base vectors vec [N, 3] expressed in the world frame (R v)."""
    return _rotate(quat, vec, inverse=False)


def _rotate(quat: torch.Tensor, vec: torch.Tensor, inverse: bool) -> torch.Tensor:
    # R v = v (2w^2 - 1) + 2 w (q x v) + 2 q (q . v) for a unit quaternion; R^T v flips the
    # middle term's sign
    w = quat[:, 0:1]
    xyz = quat[:, 1:4]
    a = vec * (2.0 * w * w - 1.0)
    b = torch.cross(xyz, vec, dim=-1) * (2.0 * w)
    c = xyz * (2.0 * (xyz * vec).sum(dim=-1, keepdim=True))
    return a - b + c if inverse else a + b + c


def yaw_quat(yaw: torch.Tensor) -> torch.Tensor:
    """[N, 4] rotation by yaw [N] about world z."""
    half = 0.5 * yaw
    zeros = torch.zeros_like(half)
    return torch.stack([torch.cos(half), zeros, zeros, torch.sin(half)], dim=-1)
