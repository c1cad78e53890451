"""Design spaces: the box of continuous variables and the sets of discrete choices a design
lives in, with sampling, the optimizer encoding and the range narrowing of Algorithm 4.

A design is a float vector ordered as `DesignSpace.names`; a discrete variable holds the
chosen value itself (a motor type 1, 2 or 3), not its index. A batch is `[n, dim]`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from coadapt_core.errors import DesignError, UserError

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np


def parse_numbers(text: str, *, what: str) -> list[float]:
    """'1.2, 0.8,2' -> [1.2, 0.8, 2.0]; a `DesignError` naming `what` (e.g. "design '1,x' must
    be 2 comma-separated numbers (thigh_scale, shank_scale)") otherwise."""
    try:
        return [float(p) for p in (p.strip() for p in str(text).split(",")) if p]
    except ValueError:
        raise DesignError(what, field="design") from None


def parse_range_pairs(text: str, *, field: str = "design_ranges") -> list[tuple[float, float]]:
    """'0.5:1.5,0.6:1.2' -> [(0.5, 1.5), (0.6, 1.2)]; malformed, infinite or inverted ranges
    are one-line user errors naming `field`."""
    out = []
    for part in [p.strip() for p in str(text).split(",") if p.strip()]:
        try:
            lo_s, hi_s = part.split(":")
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise UserError(
                f"design range '{part}' must look like low:high, e.g. 0.5:1.5", field=field
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise UserError(f"design range '{part}' must have finite bounds", field=field)
        if lo > hi:
            raise UserError(
                f"design range '{part}' has inverted bounds; the lower bound must not exceed the "
                "upper",
                field=field,
            )
        out.append((lo, hi))
    return out


@dataclass(frozen=True)
class Continuous:
    """A real variable in [low, high]."""

    name: str
    low: float
    high: float
    unit: str = ""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            raise UserError(
                f"design variable '{self.name}': bounds must be finite numbers, got [{self.low}, "
                f"{self.high}]",
                field=self.name,
            )
        if self.low > self.high:
            raise UserError(
                f"design variable '{self.name}': inverted bounds [{self.low}, {self.high}]; "
                "the lower bound must not exceed the upper",
                field=self.name,
            )

    def describe(self) -> str:
        return f"[{self.low:g}, {self.high:g}]"


@dataclass(frozen=True)
class Discrete:
    """A variable taking one value out of an ordered set of numeric choices."""

    name: str
    choices: tuple[float, ...]
    unit: str = ""

    def __post_init__(self) -> None:
        if len(self.choices) == 0:
            raise UserError(f"design variable '{self.name}': empty set of choices", field=self.name)
        object.__setattr__(self, "choices", tuple(sorted({float(c) for c in self.choices})))

    def describe(self) -> str:
        return "{" + ", ".join(f"{c:g}" for c in self.choices) + "}"


Variable = Continuous | Discrete


class DesignSpace:
    """An ordered tuple of continuous and discrete variables."""

    def __init__(self, variables: Sequence[Variable]):
        if len(variables) == 0:
            raise UserError("a design space needs at least one variable", field="design_space")
        names = [v.name for v in variables]
        if len(set(names)) != len(names):
            raise UserError(f"duplicate design variable names in {names}", field="design_space")
        self.variables: tuple[Variable, ...] = tuple(variables)

    # -- description ---------------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        return [v.name for v in self.variables]

    @property
    def dim(self) -> int:
        return len(self.variables)

    @property
    def continuous_mask(self) -> np.ndarray:
        """[dim] bool: True where the variable is continuous."""
        import numpy as np

        return np.array([isinstance(v, Continuous) for v in self.variables])

    @property
    def is_mixed(self) -> bool:
        return not bool(self.continuous_mask.all())

    @property
    def lower(self) -> np.ndarray:
        """[dim] smallest value of each variable (smallest choice for discrete ones)."""
        import numpy as np

        return np.array(
            [v.low if isinstance(v, Continuous) else v.choices[0] for v in self.variables]
        )

    @property
    def upper(self) -> np.ndarray:
        """[dim] largest value of each variable (largest choice for discrete ones)."""
        import numpy as np

        return np.array(
            [v.high if isinstance(v, Continuous) else v.choices[-1] for v in self.variables]
        )

    def describe(self) -> str:
        return ", ".join(f"{v.name} in {v.describe()}" for v in self.variables)

    def __repr__(self) -> str:
        return f"DesignSpace({self.describe()})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, DesignSpace) and self.variables == other.variables

    def __hash__(self) -> int:
        return hash(self.variables)

    # -- serialisation -------------------------------------------------------------------
    def to_dict(self) -> dict:
        out = []
        for v in self.variables:
            if isinstance(v, Continuous):
                out.append(
                    {
                        "name": v.name,
                        "type": "continuous",
                        "low": v.low,
                        "high": v.high,
                        "unit": v.unit,
                    }
                )
            else:
                out.append(
                    {"name": v.name, "type": "discrete", "choices": list(v.choices), "unit": v.unit}
                )
        return {"variables": out}

    @classmethod
    def from_dict(cls, data: dict) -> DesignSpace:
        variables: list[Variable] = []
        for item in data["variables"]:
            if item["type"] == "continuous":
                variables.append(
                    Continuous(
                        item["name"], float(item["low"]), float(item["high"]), item.get("unit", "")
                    )
                )
            else:
                variables.append(
                    Discrete(item["name"], tuple(item["choices"]), item.get("unit", ""))
                )
        return cls(variables)

    # -- membership ----------------------------------------------------------------------
    def validate(self, design: Iterable[float] | np.ndarray, *, tol: float = 1e-9) -> np.ndarray:
        """Return `design` as a float vector [dim], or raise `DesignError` naming the variable."""
        import numpy as np

        values = np.asarray(
            list(design) if not isinstance(design, np.ndarray) else design, dtype=float
        )
        if values.ndim != 1 or values.shape[0] != self.dim:
            raise DesignError(
                f"design needs {self.dim} values ({', '.join(self.names)}), got {values.size}",
                field="design",
            )
        for value, var in zip(values, self.variables, strict=True):
            if not math.isfinite(value):
                raise DesignError(
                    f"design variable '{var.name}' is not a finite number", field=var.name
                )
            if isinstance(var, Continuous):
                if value < var.low - tol or value > var.high + tol:
                    raise DesignError(
                        f"design variable '{var.name}' = {value:g} is outside its bounds "
                        f"{var.describe()}",
                        field=var.name,
                    )
            elif not any(abs(value - c) <= tol for c in var.choices):
                raise DesignError(
                    f"design variable '{var.name}' = {value:g} is not one of {var.describe()}",
                    field=var.name,
                )
        return values

    def validate_batch(self, designs: np.ndarray) -> np.ndarray:
        import numpy as np

        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        return np.stack([self.validate(d) for d in designs])

    def contains(self, design: Iterable[float]) -> bool:
        try:
            self.validate(design)
        except DesignError:
            return False
        return True

    def parse(self, text: str) -> np.ndarray:
        """Parse '1.2,0.8[,2,3]' into a validated design."""
        what = (
            f"design '{text}' must be {self.dim} comma-separated numbers ({', '.join(self.names)})"
        )
        return self.validate(parse_numbers(text, what=what))

    def format(self, design: Iterable[float]) -> str:
        out = []
        for value, var in zip(design, self.variables, strict=True):
            out.append(f"{round(value)}" if isinstance(var, Discrete) else f"{value:.3f}")
        return ",".join(out)

    # -- sampling ------------------------------------------------------------------------
    def sample(self, n: int, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """[n, dim] designs drawn uniformly (continuous) and uniformly among choices (discrete)."""
        import numpy as np

        if n < 0:
            raise UserError(f"number of designs must be >= 0, got {n}", field="n")
        rng = np.random.default_rng(rng)
        out = np.empty((n, self.dim))
        for j, var in enumerate(self.variables):
            if isinstance(var, Continuous):
                out[:, j] = rng.uniform(var.low, var.high, size=n)
            else:
                out[:, j] = rng.choice(np.asarray(var.choices), size=n)
        return out

    # -- optimizer encoding --------------------------------------------------------------
    def encode(self, designs: np.ndarray) -> np.ndarray:
        """Map designs [n, dim] to the unit cube. A discrete variable with m choices maps its
        i-th choice to the centre (i + 0.5) / m of the i-th of m equal bins, so `decode` of
        any point in that bin gives the choice back (the relaxation used by mixed PSO)."""
        import numpy as np

        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        out = np.empty_like(designs)
        for j, var in enumerate(self.variables):
            if isinstance(var, Continuous):
                width = var.high - var.low
                out[:, j] = 0.5 if width == 0 else (designs[:, j] - var.low) / width
            else:
                choices = np.asarray(var.choices)
                index = np.abs(designs[:, j, None] - choices[None, :]).argmin(axis=1)
                out[:, j] = (index + 0.5) / len(choices)
        return out

    def decode(self, unit: np.ndarray) -> np.ndarray:
        """Inverse of `encode`: unit-cube points [n, dim] (clipped to [0, 1]) to designs."""
        import numpy as np

        unit = np.clip(np.atleast_2d(np.asarray(unit, dtype=float)), 0.0, 1.0)
        out = np.empty_like(unit)
        for j, var in enumerate(self.variables):
            if isinstance(var, Continuous):
                out[:, j] = var.low + unit[:, j] * (var.high - var.low)
            else:
                choices = np.asarray(var.choices)
                index = np.minimum((unit[:, j] * len(choices)).astype(int), len(choices) - 1)
                out[:, j] = choices[index]
        return out

    # -- Algorithm 4, line 22 ------------------------------------------------------------
    def narrow(
        self,
        points: np.ndarray,
        *,
        margin: float,
        min_width_fraction: float,
        reference: DesignSpace | None = None,
    ) -> DesignSpace:
        """The design range for the next outer iteration, around the final particles.

        Rule (ours; the paper does not give one): per continuous variable, take the span
        [min, max] of the points, widen it by `margin` times that span on each side, make it
        at least `min_width_fraction` of the width of `reference` (default: this space)
        (a run's `narrow_margin` and `narrow_min_width`, coadapt_core/coadapt/config.py)
        centred on the points' mean, and clip to this space's bounds. A discrete variable
        keeps the choices that some point uses. The result is always inside `self`.
        """
        import numpy as np

        points = np.atleast_2d(np.asarray(points, dtype=float))
        if points.shape[0] == 0 or points.shape[1] != self.dim:
            raise UserError(
                f"narrowing needs at least one point of {self.dim} values, got shape "
                f"{points.shape}",
                field="points",
            )
        if margin < 0 or not (0 < min_width_fraction <= 1):
            raise UserError(
                "narrowing needs margin >= 0 and 0 < min_width_fraction <= 1",
                field="narrowing",
            )
        reference = reference or self
        variables: list[Variable] = []
        for j, var in enumerate(self.variables):
            column = points[:, j]
            if isinstance(var, Continuous):
                ref = reference.variables[j]
                ref_width = (
                    (ref.high - ref.low) if isinstance(ref, Continuous) else var.high - var.low
                )
                lo, hi = float(column.min()), float(column.max())
                span = hi - lo
                lo, hi = lo - margin * span, hi + margin * span
                min_width = min(min_width_fraction * ref_width, var.high - var.low)
                if hi - lo < min_width:
                    centre = float(column.mean())
                    lo, hi = centre - min_width / 2, centre + min_width / 2
                    # keep the minimum width when the centre is close to a bound
                    if lo < var.low:
                        lo, hi = var.low, var.low + min_width
                    if hi > var.high:
                        lo, hi = var.high - min_width, var.high
                variables.append(
                    Continuous(var.name, max(lo, var.low), min(hi, var.high), var.unit)
                )
            else:
                used = [c for c in var.choices if np.any(np.abs(column - c) < 1e-9)]
                variables.append(Discrete(var.name, tuple(used or var.choices), var.unit))
        return DesignSpace(variables)

    def with_bounds(self, bounds: dict[str, tuple[float, float]]) -> DesignSpace:
        """A copy with some continuous variables' bounds replaced (each must lie inside the
        current bounds), e.g. from `--designs 0.5:1.0,0.5:1.5`."""
        variables: list[Variable] = []
        for var in self.variables:
            if var.name in bounds and isinstance(var, Continuous):
                lo, hi = bounds[var.name]
                if lo > hi:
                    raise UserError(
                        f"design variable '{var.name}': inverted bounds [{lo:g}, {hi:g}]",
                        field=var.name,
                    )
                if lo < var.low - 1e-9 or hi > var.high + 1e-9:
                    raise UserError(
                        f"design variable '{var.name}': range [{lo:g}, {hi:g}] leaves its bounds "
                        f"{var.describe()}",
                        field=var.name,
                    )
                variables.append(Continuous(var.name, lo, hi, var.unit))
            else:
                variables.append(var)
        return DesignSpace(variables)

    def parse_ranges(self, text: str, *, field: str = "designs") -> DesignSpace:
        """Parse '0.5:1.5,0.5:1.0' (one low:high per continuous variable, in order)."""
        cont = [v for v in self.variables if isinstance(v, Continuous)]
        pairs = parse_range_pairs(text, field=field)
        if len(pairs) != len(cont):
            raise UserError(
                f"design ranges '{text}' need one low:high per continuous variable "
                f"({', '.join(v.name for v in cont)})",
                field=field,
            )
        return self.with_bounds({var.name: pair for var, pair in zip(cont, pairs, strict=True)})
