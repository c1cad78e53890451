"""Terrains (paper section 4.4), defined once so every backend builds the same ground.

- flat: the plane z = 0.
- slope: a plane rising along +x at SLOPE_DEGREES (10 degrees), through the origin.
- random: a height field over a square of side `size` centred on the origin, each cell of
  side `resolution` at a height drawn uniformly from [0, RANDOM_MAX_HEIGHT] (5 cm), from
  the simulator's seed. Backends hand the same grid to MuJoCo (hfield) and PyBullet
  (heightfield shape); `height_at` interpolates it bilinearly, as both engines do between
  grid vertices.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

from coadapt_core.errors import UserError
from coadapt_core.terrains import TERRAINS  # the names, declared once (also read from here)

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: slope terrain inclination, degrees (rising along +x)
SLOPE_DEGREES = 10.0
#: random terrain: uniform height noise in [0, RANDOM_MAX_HEIGHT] m
RANDOM_MAX_HEIGHT = 0.05


@dataclass(frozen=True)
class Terrain:
    name: str
    seed: int = 0
    size: float = 20.0  # m, side of the square height field (random terrain)
    resolution: float = 0.1  # m, grid spacing (random terrain)
    max_height: float = RANDOM_MAX_HEIGHT

    @property
    def slope_radians(self) -> float:
        import numpy as np

        return float(np.radians(SLOPE_DEGREES)) if self.name == "slope" else 0.0

    @property
    def samples(self) -> int:
        """Grid vertices per side (random terrain)."""
        return int(round(self.size / self.resolution)) + 1

    def height_grid(self) -> np.ndarray:
        """[samples, samples] heights in m; row index along y, column index along x, the
        grid spanning [-size/2, size/2] on both axes. Zeros except for random terrain."""
        return _grid(self.name, self.seed, self.samples, self.max_height)

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Heights [...] at world points xy [..., 2]."""
        import numpy as np

        xy = np.asarray(xy, dtype=float)
        if self.name == "flat":
            return np.zeros(xy.shape[:-1])
        if self.name == "slope":
            return xy[..., 0] * np.tan(self.slope_radians)
        grid = self.height_grid()
        n = self.samples
        half = self.size / 2
        u = np.clip((xy[..., 0] + half) / self.resolution, 0, n - 1 - 1e-9)
        v = np.clip((xy[..., 1] + half) / self.resolution, 0, n - 1 - 1e-9)
        i0, j0 = np.floor(v).astype(int), np.floor(u).astype(int)
        fv, fu = v - i0, u - j0
        h00 = grid[i0, j0]
        h01 = grid[i0, j0 + 1]
        h10 = grid[i0 + 1, j0]
        h11 = grid[i0 + 1, j0 + 1]
        return (1 - fv) * ((1 - fu) * h00 + fu * h01) + fv * ((1 - fu) * h10 + fu * h11)

    def max_height_near(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """Highest terrain point (`height_at`) in the square of half-side `radius` around
        each point xy [..., 2] (for spawning a robot clear of the ground).

        Exact for the random terrain: within each grid cell `height_at` is bilinear, so its
        maximum over the square is at a corner of some cell-square intersection, i.e. on
        the product of {square edges, grid lines inside} along x and along y."""
        import numpy as np

        xy = np.asarray(xy, dtype=float)
        if self.name == "flat":
            return np.zeros(xy.shape[:-1])
        if self.name == "slope":
            return (xy[..., 0] + radius) * np.tan(self.slope_radians)
        half = self.size / 2
        lines = int(np.ceil(2 * radius / self.resolution)) + 1  # grid lines a window can hold

        def candidates(centre: np.ndarray) -> np.ndarray:
            lo, hi = centre - radius, centre + radius  # [...]
            first = np.floor((lo + half) / self.resolution) * self.resolution - half
            grid = first[..., None] + self.resolution * np.arange(1, lines + 1)  # [..., lines]
            inner = np.clip(grid, lo[..., None], hi[..., None])
            return np.concatenate(
                [lo[..., None], inner, hi[..., None]], axis=-1
            )  # [..., lines + 2]

        xs, ys = candidates(xy[..., 0]), candidates(xy[..., 1])
        pts = np.stack(
            np.broadcast_arrays(xs[..., :, None], ys[..., None, :]), axis=-1
        )  # [..., k, k, 2]
        return self.height_at(pts).reshape(*xy.shape[:-1], -1).max(axis=-1)


@lru_cache(maxsize=16)
def _grid(name: str, seed: int, samples: int, max_height: float) -> np.ndarray:
    import numpy as np

    if name != "random":
        return np.zeros((samples, samples))
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7E2A]))
    grid = rng.uniform(0.0, max_height, size=(samples, samples))
    grid.setflags(write=False)
    return grid


def make_terrain(name: str, seed: int = 0) -> Terrain:
    if name not in TERRAINS:
        raise UserError(
            f"unknown terrain '{name}'; available: {', '.join(TERRAINS)}", field="terrain"
        )
    return Terrain(name=name, seed=seed)
