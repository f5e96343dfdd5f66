"""Region features of one whisk (whisker_io.features.region): PFH + SDA, Sec 5.1.1.1.

Hand-computed flat-wall histograms, the no-observation case, validation and
property-based checks (rotation invariance about the end-effector origin, bad input).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.distance import pdist
from scipy.spatial.transform import Rotation

from whisker_io.errors import CansimError, InvalidInputError, ShapeError
from whisker_io.features.pfh import PFHParams
from whisker_io.features.region import MIN_OBSERVATION_CONTACTS, RegionFeatures, region_features

N = 18
NO_SLOPES = np.zeros(N)
NO_MASK = np.zeros(N, dtype=bool)


def _wall_grid(n: int = 4, spacing: float = 0.03, y: float = 0.25) -> np.ndarray:
    """An n x n grid of contacts on the plane y = const of the end-effector frame."""
    u = (np.arange(n) - (n - 1) / 2) * spacing
    xx, zz = np.meshgrid(u, u)
    return np.column_stack([xx.ravel(), np.full(n * n, y), zz.ravel()])


# ------------------------------------------------------------- hand-computed
def _wall_random(n: int = 12, seed: int = 3, y: float = 0.25) -> np.ndarray:
    """Contacts scattered on the plane y = const (no three nearest neighbours collinear, which
    would leave a PCA normal undefined)."""
    rng = np.random.default_rng(seed)
    xz = rng.uniform(-0.08, 0.08, (n, 2))
    return np.column_stack([xz[:, 0], np.full(n, y), xz[:, 1]])


def test_flat_wall_puts_all_mass_in_the_coplanar_bins():
    """Coplanar contacts share one normal: alpha = v.n = 0, phi = n.dp/d = 0, theta =
    atan2(w.n, u.n) = atan2(0, 1) = 0 for every pair (Eq 2.43). With 3 bins per feature over
    alpha, phi in [-1, 1], theta in [-pi, pi] those are the middle bins (index 1), so the joint
    bin is 1 + 1*3 + 1*9 + b_d*27 = 13 + 27 b_d with b_d = floor(3 d / 0.3) (Eq 2.44)."""
    pts = _wall_random(16)  # pair distances up to ~0.2 m
    f = region_features(pts, NO_SLOPES, NO_MASK)
    d = pdist(pts)
    expected = np.zeros(81)
    expected[13] = np.mean(d < 0.1)
    expected[40] = np.mean((d >= 0.1) & (d < 0.2))
    np.testing.assert_allclose(f.pfh, expected, atol=1e-12)
    assert f.pfh[13] > 0 and f.pfh[40] > 0  # both distance bins used: a real check of b_d
    assert f.is_observation and f.n_contacts == 16


def _fold_theta_wrap(h: np.ndarray, bins: int = 3) -> np.ndarray:
    """Merge the first and last theta bins (theta = -pi and +pi are one angle; Eq 2.43's
    atan2 returns either for a pair whose target normal lies in the source's (u, v) plane)."""
    h4 = h.reshape(bins, bins, bins, bins).copy()  # axes (d, phi, theta, alpha): index = sum b_i bins^i
    h4[:, :, 0, :] += h4[:, :, -1, :]
    h4[:, :, -1, :] = 0.0
    return h4.ravel()


def test_flat_wall_anywhere_around_the_origin_gives_the_same_histogram():
    """The features are rotation-invariant and the normals face the origin (Eq 2.40), so
    turning the wall about the end-effector origin changes nothing; all mass stays in the
    coplanar bins 13 + 27 b_d."""
    pts = _wall_random()
    ref = region_features(pts, NO_SLOPES, NO_MASK).pfh
    assert ref[13] + ref[40] == pytest.approx(1.0)
    for seed in range(5):
        R = Rotation.random(random_state=seed)
        np.testing.assert_allclose(region_features(R.apply(pts), NO_SLOPES, NO_MASK).pfh, ref, atol=1e-12)


def test_sda_is_zero_outside_the_mask_and_copied_inside():
    slopes = np.arange(N, dtype=float) - 4.0
    slopes[[1, 5]] = np.nan  # undefined slopes of whiskers without contact are ignored
    mask = np.zeros(N, dtype=bool)
    mask[[0, 2, 3]] = True
    f = region_features(_wall_grid(2), slopes, mask)
    expected = np.zeros(N)
    expected[[0, 2, 3]] = [-4.0, -2.0, -1.0]
    np.testing.assert_array_equal(f.sda, expected)
    np.testing.assert_array_equal(f.sda_mask, mask)


@pytest.mark.parametrize("k", [0, 1, 2])
def test_fewer_than_three_contacts_is_no_observation(k):
    pts = _wall_grid(2)[:k]
    mask = np.zeros(N, dtype=bool)
    mask[:k] = True
    f = region_features(pts, np.ones(N), mask)
    assert not f.is_observation and f.n_contacts == k < MIN_OBSERVATION_CONTACTS
    assert not f.pfh.any() and f.pfh.shape == (81,)
    assert f.contact_points_m.shape == (k, 3)


def test_three_contacts_are_an_observation():
    f = region_features(_wall_grid(2)[:3], NO_SLOPES, NO_MASK)
    assert f.is_observation and f.pfh.sum() == pytest.approx(1.0)
    # three coplanar points, pair distances 0.03, 0.03, 0.042 m: all in bin 13
    assert f.pfh[13] == pytest.approx(1.0)


def test_other_bin_count_follows_pfh_params():
    f = region_features(_wall_grid(3), NO_SLOPES, NO_MASK, PFHParams(bins_per_feature=2))
    assert f.pfh.shape == (16,) and f.pfh.sum() == pytest.approx(1.0)


def test_features_are_read_only_copies_and_compare_exactly():
    pts = _wall_grid(2)
    f = region_features(pts, NO_SLOPES, NO_MASK)
    pts[0, 0] = 9.0
    assert f.contact_points_m[0, 0] != 9.0
    for name in ("pfh", "sda", "sda_mask", "contact_points_m"):
        with pytest.raises(ValueError):
            getattr(f, name)[0] = 1
    g = region_features(_wall_grid(2), NO_SLOPES, NO_MASK)
    assert f == g and not (f != g)
    h = region_features(_wall_grid(2) * 1.001, NO_SLOPES, NO_MASK)
    assert f != h
    with pytest.raises(TypeError):
        hash(f)


# ------------------------------------------------------------- validation
def test_bad_input_raises_typed_errors():
    pts = _wall_grid(2)
    bad = pts.copy()
    bad[1, 2] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        region_features(bad, NO_SLOPES, NO_MASK)
    with pytest.raises(ShapeError):
        region_features(pts[:, :2], NO_SLOPES, NO_MASK)
    with pytest.raises(ShapeError):
        region_features([], NO_SLOPES, NO_MASK)  # an empty set must still be (0, 3)
    with pytest.raises(ShapeError):
        region_features(pts, np.zeros(17), NO_MASK)
    with pytest.raises(ShapeError):
        region_features(pts, NO_SLOPES, np.zeros((3, 6), dtype=bool))
    slopes = NO_SLOPES.copy()
    slopes[0] = np.inf
    mask = NO_MASK.copy()
    mask[0] = True
    with pytest.raises(InvalidInputError, match="inside the mask"):
        region_features(pts, slopes, mask)
    with pytest.raises(InvalidInputError, match="booleans"):
        region_features(pts, NO_SLOPES, np.full(N, 2))
    with pytest.raises(InvalidInputError, match="PFHParams"):
        region_features(pts, NO_SLOPES, NO_MASK, pfh_params={"bins_per_feature": 3})  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        region_features(pts, ["a"] * N, NO_MASK)
    with pytest.raises(InvalidInputError, match="end-effector frame"):
        region_features(pts * 1e3, NO_SLOPES, NO_MASK)  # millimetres, or world coordinates far away


def test_region_features_constructor_checks_its_invariants():
    pfh = np.zeros(81)
    pfh[13] = 1.0
    pts = _wall_grid(2)
    RegionFeatures(pfh, NO_SLOPES, NO_MASK, 4, pts)  # valid
    with pytest.raises(InvalidInputError, match="sum to 1"):
        RegionFeatures(pfh * 0.5, NO_SLOPES, NO_MASK, 4, pts)
    with pytest.raises(InvalidInputError, match="non-negative"):
        RegionFeatures(np.where(pfh > 0, 2.0, -1.0 / 80), NO_SLOPES, NO_MASK, 4, pts)
    with pytest.raises(InvalidInputError, match="no observation"):
        RegionFeatures(pfh, NO_SLOPES, NO_MASK, 2, pts[:2])
    with pytest.raises(InvalidInputError, match="n_contacts"):
        RegionFeatures(pfh, NO_SLOPES, NO_MASK, 3, pts)
    with pytest.raises(InvalidInputError, match="sda must be 0"):
        RegionFeatures(pfh, np.ones(N), NO_MASK, 4, pts)
    with pytest.raises(InvalidInputError, match="measured slopes"):
        RegionFeatures(pfh, NO_SLOPES, np.ones(N, dtype=bool), 4, pts)
    with pytest.raises(ShapeError):
        RegionFeatures(pfh, NO_SLOPES, NO_MASK[:5], 4, pts)
    with pytest.raises(ShapeError):
        RegionFeatures(np.zeros(0), NO_SLOPES, NO_MASK, 0, np.zeros((0, 3)))
    with pytest.raises(InvalidInputError):
        RegionFeatures(np.full(81, np.nan), NO_SLOPES, NO_MASK, 4, pts)
    with pytest.raises(InvalidInputError):
        RegionFeatures(pfh, NO_SLOPES, NO_MASK, -1, pts)


# ------------------------------------------------------------- properties
@settings(max_examples=60, deadline=None)
@given(st.integers(0, N), st.integers(0, 2**32 - 1))
@example(k=3, seed=2507)  # three contacts all farther apart than radius_m: no pair, an all-zero PFH
def test_random_whisks_give_consistent_features(k, seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-0.15, 0.15, (k, 3)) + [0.0, 0.25, 0.0]
    slopes = rng.normal(0.0, 1.0, N)
    mask = np.zeros(N, dtype=bool)
    mask[rng.choice(N, size=min(k, N), replace=False)] = True
    f = region_features(pts, slopes, mask)
    assert f.is_observation == (k >= 3) and f.n_contacts == k
    assert f.pfh.min() >= 0.0
    # the histogram is over the pairs within radius_m (Eq 2.44); with none it is all zero
    paired = k >= 3 and bool(np.any(pdist(pts) <= PFHParams().radius_m))
    assert (f.pfh.sum() == pytest.approx(1.0)) if paired else not f.pfh.any()
    np.testing.assert_array_equal(f.sda[mask], slopes[mask])
    assert not f.sda[~mask].any()
    # invariant under a rotation about the end-effector origin (Eq 2.40-2.43), up to the
    # theta = +-pi wrap of pairs of mutual nearest neighbours
    R = Rotation.random(random_state=seed % 1000)
    g = region_features(R.apply(pts) if k else pts, slopes, mask)
    np.testing.assert_allclose(_fold_theta_wrap(g.pfh), _fold_theta_wrap(f.pfh), atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, st.sampled_from([(0, 3), (4, 3), (5, 2), (3,), (2, 3, 3)]),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       arrays(np.float64, st.sampled_from([(18,), (17,)]),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       arrays(np.bool_, st.sampled_from([(18,), (4,)])))
def test_bad_input_is_typed_or_valid(points, slopes, mask):
    try:
        f = region_features(points, slopes, mask)
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    assert points.ndim == 2 and points.shape[1] == 3 and np.all(np.isfinite(points))
    assert slopes.shape == mask.shape and np.all(np.isfinite(slopes[mask]))
    assert np.all(np.isfinite(f.pfh)) and np.all(np.isfinite(f.sda))
    total = f.pfh.sum()
    assert total == 0.0 or math.isclose(total, 1.0, rel_tol=1e-9)
