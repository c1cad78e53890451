"""Mass and inertia of the thigh and shank as functions of their length.

The paper fits polynomials to SolidWorks CAD data; the Kuafu CAD is not public, so we fit
polynomials to a documented parametric solid model of each link (`solid_link`), and the
generator uses only the fitted polynomials (`LinkMassModel`). `fit_mass_model.py` rebuilds
`mass_model.json` from the solid model; the README lists the coefficients and R^2.

Link frame: origin at the proximal joint centre, the link along -z, its distal joint at
(0, 0, -length). The structure only: actuators are added by the generator, as they depend
on the motor type.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
from coadapt_plugins.robots.kuafu.constants import NOMINAL_LINK_LENGTH
from coadapt_plugins.robots.kuafu.inertia import Part, box, combine, cylinder, point_line

MASS_MODEL_FILE = Path(__file__).with_name("mass_model.json")

#: quantities fitted per link, each a polynomial in the link length (m)
QUANTITIES = ("mass", "com_depth", "inertia_transverse", "inertia_axial")

ALUMINIUM_7075 = 2810.0  # kg / m^3


@dataclass(frozen=True)
class LinkSpec:
    """Parametric solid model of one leg link (all assumptions, see README)."""

    name: str
    tube_radius_nominal: float  # m, outer radius of the tube at the nominal length
    tube_wall: float  # m
    proximal_fitting_mass: float  # kg, clevis / actuator output flange at the proximal joint
    distal_fitting_mass: float  # kg, bearing housing / actuator mount at the distal joint
    fitting_size: tuple[float, float, float]  # m, square-section block at each end
    harness_per_metre: float  # kg / m, cables and sleeve along the link
    fasteners: float  # kg, bolts and inserts, half at each end
    pushrod_per_metre: float = 0.0  # kg / m, ankle push rod (shank only)
    pushrod_start: float = 0.0  # m below the proximal joint where the rod starts


THIGH = LinkSpec(
    name="thigh",
    tube_radius_nominal=0.032,
    tube_wall=0.003,
    proximal_fitting_mass=0.45,
    distal_fitting_mass=0.40,
    fitting_size=(0.07, 0.07, 0.05),
    harness_per_metre=0.30,
    fasteners=0.10,
)
SHANK = LinkSpec(
    name="shank",
    tube_radius_nominal=0.026,
    tube_wall=0.0025,
    proximal_fitting_mass=0.35,
    distal_fitting_mass=0.30,
    fitting_size=(0.06, 0.06, 0.05),
    harness_per_metre=0.15,
    fasteners=0.08,
    pushrod_per_metre=0.25,  # 6 mm aluminium rod with rod ends, ankle actuator -> ankle
    pushrod_start=0.07,
)
LINKS = {"thigh": THIGH, "shank": SHANK}


def solid_link(spec: LinkSpec, length: float) -> Part:
    """Mass properties of the link structure of `length` m, in the link frame.

    The tube spans the gap between the two end fittings. Its outer radius grows as
    sqrt(length / 0.35) so the bending stress at its root under the same foot load stays
    constant (sigma = F L / (pi r^2 t) with the wall t fixed): longer links get thicker.
    """
    fx, fy, fz = spec.fitting_size
    tube_length = max(length - 2.0 * fz, 1e-3)
    radius = spec.tube_radius_nominal * np.sqrt(length / NOMINAL_LINK_LENGTH)
    inner = radius - spec.tube_wall
    tube_mass = ALUMINIUM_7075 * np.pi * (radius**2 - inner**2) * tube_length
    mid = np.array([0.0, 0.0, -0.5 * length])
    top = np.array([0.0, 0.0, -0.5 * fz])
    bottom = np.array([0.0, 0.0, -(length - 0.5 * fz)])
    parts = [
        cylinder(tube_mass, radius, tube_length, mid, axis="z", inner_radius=inner),
        box(spec.proximal_fitting_mass + 0.5 * spec.fasteners, (fx, fy, fz), top),
        box(spec.distal_fitting_mass + 0.5 * spec.fasteners, (fx, fy, fz), bottom),
        point_line(spec.harness_per_metre * length, np.zeros(3), np.array([0.0, 0.0, -length])),
    ]
    if spec.pushrod_per_metre > 0:
        rod_length = max(length - spec.pushrod_start, 1e-3)
        parts.append(
            point_line(
                spec.pushrod_per_metre * rod_length,
                np.array([0.0, 0.0, -spec.pushrod_start]),
                np.array([0.0, 0.0, -length]),
            )
        )
    return combine(parts)


def solid_link_quantities(spec: LinkSpec, length: float) -> dict[str, float]:
    """The fitted quantities of the solid model at one length. The link is symmetric about
    its axis, so its inertia about the CoM is diag(transverse, transverse, axial)."""
    part = solid_link(spec, length)
    return {
        "mass": part.mass,
        "com_depth": -float(part.com[2]),
        "inertia_transverse": float(part.inertia[0, 0]),
        "inertia_axial": float(part.inertia[2, 2]),
    }


@dataclass(frozen=True)
class LinkMassModel:
    """Fitted polynomials (numpy.polyfit coefficients, highest power first) per quantity."""

    name: str
    coefficients: dict[str, tuple[float, ...]]
    r2: dict[str, float]

    def quantities(self, length: float) -> dict[str, float]:
        out = {}
        for q in QUANTITIES:
            value = 0.0
            for c in self.coefficients[q]:  # Horner, highest power first (as numpy.polyval)
                value = value * length + c
            out[q] = value
        return out

    def part(self, length: float) -> Part:
        """The link structure as a `Part` in the link frame, from the regression."""
        v = self.quantities(length)
        inertia = np.diag([v["inertia_transverse"], v["inertia_transverse"], v["inertia_axial"]])
        return Part(v["mass"], np.array([0.0, 0.0, -v["com_depth"]]), inertia)


@cache
def load_mass_models(path: str | None = None) -> dict[str, LinkMassModel]:
    """{"thigh": ..., "shank": ...} from `mass_model.json`."""
    data = json.loads(Path(path or MASS_MODEL_FILE).read_text())
    return {
        name: LinkMassModel(
            name,
            {q: tuple(entry["coefficients"][q]) for q in QUANTITIES},
            {q: float(entry["r2"][q]) for q in QUANTITIES},
        )
        for name, entry in data["links"].items()
    }
