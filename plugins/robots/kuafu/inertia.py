"""Rigid-body mass properties of simple solids and their composition (parallel-axis
theorem), used by the solid model of the links and by the generator."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Part:
    """A solid: its mass, centre of mass and inertia tensor about that centre (3 x 3), all
    in the frame of the body it belongs to."""

    mass: float
    com: np.ndarray  # [3]
    inertia: np.ndarray  # [3, 3] about com

    def shifted(self, offset: np.ndarray) -> Part:
        return Part(self.mass, self.com + np.asarray(offset, dtype=float), self.inertia)


def box(mass: float, size: np.ndarray, centre: np.ndarray) -> Part:
    """Solid box with full edge lengths `size` (x, y, z)."""
    a, b, c = (float(s) for s in size)
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return Part(mass, np.asarray(centre, dtype=float), inertia)


def cylinder(
    mass: float,
    radius: float,
    length: float,
    centre: np.ndarray,
    axis: str = "z",
    inner_radius: float = 0.0,
) -> Part:
    """Solid (or hollow, with `inner_radius`) cylinder whose axis is `axis`."""
    r2 = radius * radius + inner_radius * inner_radius
    axial = 0.5 * mass * r2
    transverse = mass * (3.0 * r2 + length * length) / 12.0
    diag = np.full(3, transverse)
    diag[_AXES[axis]] = axial
    return Part(mass, np.asarray(centre, dtype=float), np.diag(diag))


def sphere(mass: float, radius: float, centre: np.ndarray) -> Part:
    return Part(mass, np.asarray(centre, dtype=float), np.eye(3) * 0.4 * mass * radius * radius)


def point_line(mass: float, start: np.ndarray, end: np.ndarray) -> Part:
    """A thin uniform rod (cables, push rods): inertia m L^2 / 12 across its length."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    d = end - start
    length2 = float(d @ d)
    u = d / np.sqrt(length2) if length2 > 0 else np.zeros(3)
    inertia = mass * length2 / 12.0 * (np.eye(3) - np.outer(u, u))
    return Part(mass, 0.5 * (start + end), inertia)


def combine(parts: list[Part]) -> Part:
    """One part with the total mass, the common centre of mass and the inertia about it."""
    mass = sum(p.mass for p in parts)
    com = sum(p.mass * p.com for p in parts) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        r = p.com - com
        inertia += p.inertia + p.mass * (float(r @ r) * np.eye(3) - np.outer(r, r))
    return Part(mass, com, inertia)


def rotation_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def inertia_about_axis(
    part: Part, rotation: np.ndarray, position: np.ndarray, point: np.ndarray, axis: np.ndarray
) -> float:
    """Moment of inertia of `part` (placed with `rotation`, `position` in some frame) about
    the line through `point` along unit `axis` (same frame)."""
    com = position + rotation @ part.com
    inertia = rotation @ part.inertia @ rotation.T
    r = com - point
    r_perp = r - (r @ axis) * axis
    return float(axis @ inertia @ axis + part.mass * (r_perp @ r_perp))
