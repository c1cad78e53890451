import numpy as np
import pytest

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import DesignError, UserError


@pytest.fixture
def mixed():
    return DesignSpace(
        [
            Continuous("thigh", 0.5, 1.5),
            Continuous("shank", 0.5, 1.5),
            Discrete("hip_motor", (1, 2, 3)),
        ]
    )


def test_inverted_bounds_rejected_with_field_name():
    with pytest.raises(UserError, match=r"'thigh'.*inverted"):
        Continuous("thigh", 1.5, 0.5)


def test_empty_choices_rejected():
    with pytest.raises(UserError, match="empty"):
        Discrete("motor", ())


def test_sample_inside_bounds_and_choices(mixed):
    d = mixed.sample(500, rng=0)
    assert d.shape == (500, 3)
    assert d[:, :2].min() >= 0.5 and d[:, :2].max() <= 1.5
    assert set(np.unique(d[:, 2])) == {1.0, 2.0, 3.0}
    # uniform: each motor type about a third
    counts = np.bincount(d[:, 2].astype(int))[1:]
    assert counts.min() > 130


def test_encode_decode_round_trip(mixed):
    d = mixed.sample(50, rng=1)
    u = mixed.encode(d)
    assert u.min() >= 0 and u.max() <= 1
    np.testing.assert_allclose(mixed.decode(u), d)


def test_decode_bins_discrete(mixed):
    u = np.array([[0.0, 1.0, 0.0], [0.5, 0.5, 0.34], [1.0, 0.0, 0.999], [0.2, 0.2, 0.66]])
    d = mixed.decode(u)
    np.testing.assert_allclose(d[:, 2], [1, 2, 3, 2])
    np.testing.assert_allclose(d[:, 0], [0.5, 1.0, 1.5, 0.7])


def test_validate_names_variable_and_bounds(mixed):
    with pytest.raises(DesignError, match=r"'shank' = 1.7 is outside its bounds \[0.5, 1.5\]"):
        mixed.validate([1.0, 1.7, 1])
    with pytest.raises(DesignError, match=r"'hip_motor' = 4 is not one of \{1, 2, 3\}"):
        mixed.validate([1.0, 1.0, 4])
    with pytest.raises(DesignError, match="needs 3 values"):
        mixed.validate([1.0, 1.0])


def test_parse(mixed):
    np.testing.assert_allclose(mixed.parse("1.2, 0.8,2"), [1.2, 0.8, 2])
    with pytest.raises(DesignError, match="comma-separated"):
        mixed.parse("1.2,abc,2")


def test_narrow_around_points_stays_inside(mixed):
    pts = np.array([[0.55, 1.0, 2], [0.65, 1.1, 2], [0.6, 1.05, 3]])
    narrowed = mixed.narrow(pts, margin=0.25, min_width_fraction=0.1)
    thigh, shank, motor = narrowed.variables
    # span 0.1 widened by 0.025 each side
    assert thigh.low == pytest.approx(0.525) and thigh.high == pytest.approx(0.675)
    assert shank.low == pytest.approx(0.975) and shank.high == pytest.approx(1.125)
    assert motor.choices == (2.0, 3.0)
    for p in pts:
        assert narrowed.contains(p)


def test_narrow_enforces_minimum_width_at_bound(mixed):
    pts = np.array([[0.5, 1.5, 1], [0.5, 1.5, 1]])
    narrowed = mixed.narrow(pts, margin=0.25, min_width_fraction=0.2)
    thigh, shank, _ = narrowed.variables
    assert (thigh.low, thigh.high) == pytest.approx((0.5, 0.7))
    assert (shank.low, shank.high) == pytest.approx((1.3, 1.5))


def test_narrow_rejects_empty_points(mixed):
    with pytest.raises(UserError):
        mixed.narrow(np.zeros((0, 3)), margin=0.25, min_width_fraction=0.1)


def test_parse_ranges_and_dict_round_trip(mixed):
    sub = mixed.parse_ranges("0.5:1.0,0.8:1.2")
    assert sub.variables[0].high == 1.0 and sub.variables[1].low == 0.8
    assert DesignSpace.from_dict(sub.to_dict()) == sub
    with pytest.raises(UserError, match="inverted"):
        mixed.parse_ranges("1.0:0.5,0.5:1.5")
    with pytest.raises(UserError, match="leaves its bounds"):
        mixed.parse_ranges("0.2:1.0,0.5:1.5")
