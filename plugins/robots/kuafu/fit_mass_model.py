"""Regenerate `mass_model.json`: sample the parametric solid model of the thigh and shank
over the design range of lengths and fit one cubic polynomial per quantity (numpy.polyfit).

    python -m coadapt_plugins.robots.kuafu.fit_mass_model [--check]

`--check` refits and exits 1 if the stored coefficients differ (used by the tests).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
from coadapt_plugins.robots.kuafu.constants import NOMINAL_LINK_LENGTH, SCALE_BOUNDS
from coadapt_plugins.robots.kuafu.mass_model import (
    LINKS,
    MASS_MODEL_FILE,
    QUANTITIES,
    solid_link_quantities,
)

DEGREE = 3
SAMPLES = 41


def fit() -> dict:
    lengths = np.linspace(SCALE_BOUNDS[0], SCALE_BOUNDS[1], SAMPLES) * NOMINAL_LINK_LENGTH
    out: dict = {
        "description": (
            "cubic fits of the Kuafu link solid model (mass_model.py) over link length in m"
        ),
        "degree": DEGREE,
        "lengths": [float(lengths[0]), float(lengths[-1]), SAMPLES],
        "links": {},
    }
    for name, spec in LINKS.items():
        samples = [solid_link_quantities(spec, float(length)) for length in lengths]
        coefficients, r2 = {}, {}
        for q in QUANTITIES:
            y = np.array([s[q] for s in samples])
            c = np.polyfit(lengths, y, DEGREE)
            residual = y - np.polyval(c, lengths)
            total = y - y.mean()
            r2[q] = float(1.0 - (residual @ residual) / (total @ total))
            coefficients[q] = [float(x) for x in c]
        out["links"][name] = {"coefficients": coefficients, "r2": r2}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check", action="store_true", help="compare with the stored file instead of writing"
    )
    args = parser.parse_args(argv)
    data = fit()
    if args.check:
        stored = json.loads(MASS_MODEL_FILE.read_text())
        for name, entry in data["links"].items():
            for q in QUANTITIES:
                if not np.allclose(
                    entry["coefficients"][q],
                    stored["links"][name]["coefficients"][q],
                    rtol=1e-9,
                    atol=1e-12,
                ):
                    print(
                        f"{name}.{q}: stored coefficients are stale; rerun without --check",
                        file=sys.stderr,
                    )
                    return 1
        return 0
    MASS_MODEL_FILE.write_text(json.dumps(data, indent=2) + "\n")
    for name, entry in data["links"].items():
        for q in QUANTITIES:
            coeffs = ", ".join(f"{c:.6g}" for c in entry["coefficients"][q])
            print(f"{name:6s} {q:19s} [{coeffs}]  R^2 = {entry['r2'][q]:.8f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
