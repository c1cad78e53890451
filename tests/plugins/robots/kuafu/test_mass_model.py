"""The mass regression: fitted to the parametric solid model, up to date, monotonic."""

from __future__ import annotations

import numpy as np
import pytest
from coadapt_plugins.robots.kuafu import fit_mass_model
from coadapt_plugins.robots.kuafu.mass_model import (
    LINKS,
    QUANTITIES,
    load_mass_models,
    solid_link_quantities,
)

LENGTHS = np.linspace(0.175, 0.525, 23)


def test_stored_coefficients_match_a_fresh_fit():
    assert fit_mass_model.main(["--check"]) == 0


@pytest.mark.parametrize("link", ["thigh", "shank"])
def test_regression_reproduces_the_solid_model(link):
    fitted = load_mass_models()[link]
    for q in QUANTITIES:
        assert fitted.r2[q] > 0.9999, (q, fitted.r2[q])
    for length in LENGTHS:
        solid = solid_link_quantities(LINKS[link], float(length))
        poly = fitted.quantities(float(length))
        for q in QUANTITIES:
            # cubic fits: mass and CoM within 0.1 %, inertias within 1 % (worst at the
            # shortest links, where they are smallest)
            rel = 1e-3 if q in ("mass", "com_depth") else 1e-2
            assert poly[q] == pytest.approx(solid[q], rel=rel), (q, length)


@pytest.mark.parametrize("link", ["thigh", "shank"])
def test_link_mass_and_inertia_grow_with_length(link):
    fitted = load_mass_models()[link]
    values = [fitted.quantities(float(x)) for x in LENGTHS]
    for q in ("mass", "com_depth", "inertia_transverse"):
        series = np.array([v[q] for v in values])
        assert np.all(np.diff(series) > 0), q


def test_total_mass_monotonic_in_each_length(kuafu):
    scales = np.linspace(0.5, 1.5, 11)
    for other in (0.5, 1.0, 1.5):
        thigh = [kuafu.build(np.array([s, other])).total_mass for s in scales]
        shank = [kuafu.build(np.array([other, s])).total_mass for s in scales]
        assert np.all(np.diff(thigh) > 0) and np.all(np.diff(shank) > 0)
    light, heavy = (
        kuafu.build(np.array([0.5, 0.5])).total_mass,
        kuafu.build(np.array([1.5, 1.5])).total_mass,
    )
    assert 39.0 < light < 42.0 < heavy < 46.0
