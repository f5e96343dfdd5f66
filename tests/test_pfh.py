"""Point feature histogram (Sec 2.5.1.1, Sec 2.5.1.1) and region matching (Eq 5.5)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import pdist
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError
from whisker_io.sim.objects import make_object
from whisker_io.features.pfh import (
    PFHParams,
    chi_squared,
    estimate_normals,
    feature_bins,
    pair_features,
    point_feature_histogram,
)


def test_pair_features_hand_example_no_swap():
    """p_s = 0, n_s = z; p_t = (2,0,0), n_t = (0, .6, .8). Both normals are perpendicular
    to the joining line (tie, no swap): u = z, v = dp x u / |.| = (0,-1,0), w = u x v = (1,0,0);
    alpha = v.n_t = -0.6, theta = atan2(w.n_t, u.n_t) = atan2(0, .8) = 0, phi = 0, d = 2."""
    f, ok = pair_features([0, 0, 0], [0, 0, 1], [2, 0, 0], [0, 0.6, 0.8])
    assert ok.all()
    np.testing.assert_allclose(f[0], [-0.6, 0.0, 0.0, 2.0], atol=1e-15)


def test_pair_features_hand_example_with_swap():
    """p1 = 0, n1 = z; p2 = (1,0,0), n2 = (.6,0,.8). |n2.dp| = .6 > |n1.dp| = 0, so p2 is
    the source (Eq 2.41): u = n2, dp = (-1,0,0), phi = -0.6, v = dp x u/|.| = (0,1,0),
    w = u x v = (-.8,0,.6); alpha = v.z = 0, theta = atan2(w.z, u.z) = atan2(.6,.8), d = 1."""
    f, ok = pair_features([0, 0, 0], [0, 0, 1], [1, 0, 0], [0.6, 0, 0.8])
    np.testing.assert_allclose(f[0], [0.0, np.arctan2(0.6, 0.8), -0.6, 1.0], atol=1e-15)
    # the result does not depend on the order the pair is given in
    g, _ = pair_features([1, 0, 0], [0.6, 0, 0.8], [0, 0, 0], [0, 0, 1])
    np.testing.assert_allclose(g, f, atol=1e-15)


def test_degenerate_pairs_flagged():
    f, ok = pair_features([[0, 0, 0], [0, 0, 0]], [[0, 0, 1], [1, 0, 0]], [[0, 0, 0], [1, 0, 0]], [[0, 0, 1], [0, 1, 0]])
    assert ok.tolist() == [False, False]  # coincident; source normal along the line
    np.testing.assert_array_equal(f, 0.0)


def test_bin_index_hand_example():
    """(alpha, theta, phi, d) = (-0.6, 0, 0, 0.15) with 3 bins: alpha -> floor(3*0.4/2) = 0,
    theta -> floor(3*pi/(2pi)) = 1, phi -> 1, d -> floor(3*0.15/0.3) = 1;
    idx = 0 + 1*3 + 1*9 + 1*27 = 39. Range tops fall in the last bin."""
    assert feature_bins([[-0.6, 0.0, 0.0, 0.15]])[0] == 39
    assert feature_bins([[1.0, np.pi, 1.0, 0.3]])[0] == 80
    assert feature_bins([[-1.0, -np.pi, -1.0, 0.0]])[0] == 0


def test_normals_smallest_eigenvector_and_oriented():
    """Points on the plane z = 1 seen from the origin: normals are -z (toward the viewpoint)."""
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-1, 1, (12, 2)), np.ones(12)])
    n = estimate_normals(pts, viewpoint=(0, 0, 0))
    np.testing.assert_allclose(n, np.tile([0, 0, -1.0], (12, 1)), atol=1e-9)
    n = estimate_normals(pts, viewpoint=(0, 0, 5))
    np.testing.assert_allclose(n, np.tile([0, 0, 1.0], (12, 1)), atol=1e-9)


def test_normal_orientation_consistent_under_noise():
    """Fig 2.18: normals of a mesh's vertices (right half, seen from a viewpoint on that side)
    recomputed after vertex noise keep their direction when oriented by Eq 2.40."""
    mesh = make_object("blob")
    v = mesh.vertices[mesh.vertices[:, 0] > 0.02]
    vp = np.array([0.6, 0.0, 0.17])
    k = 6
    ref = estimate_normals(v, vp, k)
    ref_raw = estimate_normals(v, vp, k, orient=False)
    rng = np.random.default_rng(1)
    dots, dots_raw = [], []
    for _ in range(5):
        noisy = v + rng.normal(0, 0.001, v.shape)
        n = estimate_normals(noisy, vp, k)
        assert np.all(np.einsum("ij,ij->i", vp - noisy, n) >= 0)  # Eq 2.40 holds
        dots.append(np.einsum("ij,ij->i", ref, n))
        dots_raw.append(np.einsum("ij,ij->i", ref_raw, estimate_normals(noisy, vp, k, orient=False)))
    dots, dots_raw = np.concatenate(dots), np.concatenate(dots_raw)
    assert np.mean(dots > 0) > 0.97
    assert dots.mean() >= dots_raw.mean()


def _cloud(seed: int, n: int = 18):
    """A whisker-like cloud: points on a bumpy surface patch in front of the viewpoint."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-0.12, 0.12, (n, 2))
    z = 0.25 + 0.05 * np.sin(8 * xy[:, 0]) * np.cos(6 * xy[:, 1]) + rng.normal(0, 0.005, n)
    return np.column_stack([xy, z])


def _bin_edge_margin(points, vp, params):
    """Smallest distance of any binned feature, and of any normal's orientation test, to its
    decision edge. (The source/target choice needs no margin: when both normals are
    perpendicular to the joining line, as within one 3-point neighbourhood, either choice
    gives the same features.)"""
    n = estimate_normals(points, vp, params.normal_neighbours)
    i, j = np.triu_indices(len(points), 1)
    f, ok = pair_features(points[i], n[i], points[j], n[j])
    f = f[ok]
    nb = params.bins_per_feature
    r = params.ranges
    scaled = nb * (f - r[:, 0]) / (r[:, 1] - r[:, 0])
    margins = [np.min(np.abs(scaled[:, :3] - np.round(scaled[:, :3])) * (r[:3, 1] - r[:3, 0]) / nb)]
    margins.append(np.min(np.abs(np.einsum("ij,ij->i", vp - points, n))))
    return min(margins)


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_pfh_invariant_to_rigid_motion(seed):
    params = PFHParams()
    pts, vp = _cloud(seed), np.zeros(3)
    assert _bin_edge_margin(pts, vp, params) > 1e-9  # no feature sits on a bin edge
    h = point_feature_histogram(pts, vp, params)
    assert h.valid and np.isclose(h.histogram.sum(), 1.0)
    assert h.n_pairs == np.sum(pdist(pts) <= 0.3)
    R = Rotation.random(random_state=seed + 100).as_matrix()
    t = np.random.default_rng(seed).uniform(-2, 2, 3)
    h2 = point_feature_histogram(pts @ R.T + t, R @ vp + t, params)
    np.testing.assert_array_equal(h2.histogram, h.histogram)
    np.testing.assert_allclose(h2.normals, h.normals @ R.T, atol=1e-9)
    assert chi_squared(h.histogram, h2.histogram) == 0.0


def test_histogram_counts_pairs_by_hand():
    """4 points at the corners of a 0.12 m square in z = 1 seen from the origin: normals -z,
    perpendicular to every joining line, so alpha = v.n_t = 0, theta = atan2(0, 1) = 0 and
    phi = 0 (each bin 1 of 3); d = 0.12 (sides) and 0.17 (diagonals) -> bin floor(3 d / 0.3)
    = 1. All 6 pairs land in bin 1 + 1*3 + 1*9 + 1*27 = 40."""
    pts = np.array([[0, 0, 1], [0.12, 0, 1], [0, 0.12, 1], [0.12, 0.12, 1]], dtype=float)
    h = point_feature_histogram(pts)
    assert h.n_pairs == 6
    expected = np.zeros(81)
    expected[1 + 3 + 9 + 27] = 1.0
    np.testing.assert_array_equal(h.histogram, expected)


def test_radius_limits_pairs():
    pts = np.array([[0, 0, 1], [0.1, 0, 1], [0, 0.1, 1], [5, 0, 1.0]])
    h = point_feature_histogram(pts, params=PFHParams(radius_m=0.3))
    assert h.n_pairs == 3  # the far point pairs with nobody


@pytest.mark.parametrize("n", [0, 1, 2])
def test_fewer_than_three_points_defined(n):
    pts = _cloud(0)[:n]
    h = point_feature_histogram(pts.reshape(n, 3))
    assert not h.valid and h.n_pairs == 0
    assert h.histogram.shape == (81,) and not h.histogram.any()
    full = point_feature_histogram(_cloud(0)).histogram
    assert chi_squared(h.histogram, h.histogram) == 0.0
    assert np.isclose(chi_squared(h.histogram, full), 1.0)


def test_nan_rows_are_missing_contacts():
    pts = _cloud(3)
    with_nan = np.vstack([pts, np.full((4, 3), np.nan)])
    np.testing.assert_array_equal(point_feature_histogram(with_nan).histogram, point_feature_histogram(pts).histogram)
    with pytest.raises(InvalidInputError):
        point_feature_histogram(np.full((3, 3), np.inf))
    with pytest.raises(InvalidInputError):
        point_feature_histogram(np.zeros((3, 2)))


def test_chi_squared_hand_values():
    q = np.array([0.5, 0.5, 0.0, 0.0])
    v = np.array([0.25, 0.25, 0.5, 0.0])
    # (0.25^2/0.75) * 2 + 0.5^2/0.5, last bin skipped
    assert np.isclose(chi_squared(q, v), 2 * 0.0625 / 0.75 + 0.5)
    assert chi_squared(q, q) == 0.0
    np.testing.assert_allclose(chi_squared(q, np.stack([q, v])), [0.0, 2 * 0.0625 / 0.75 + 0.5])


# ------------------------------------------------- issue 17: typed errors
@pytest.mark.parametrize(("q", "v"), [
    (np.array(0), np.ones(3)),            # a scalar has no bin axis (was IndexError)
    (np.ones(3), np.array(1.0)),
    (np.ones(3), np.ones(4)),
    (np.ones((2, 3)), np.ones((3, 3))),   # leading axes do not broadcast
    (np.array([1.0, np.nan, 0.0]), np.ones(3)),
    (np.array([1.0, -0.5, 0.0]), np.ones(3)),
    ("abc", np.ones(3)),
])
def test_chi_squared_bad_input_is_typed(q, v):
    with pytest.raises(InvalidInputError):
        chi_squared(q, v)


@pytest.mark.parametrize("kwargs", [{"bins_per_feature": 0}, {"bins_per_feature": 2.5}, {"bins_per_feature": "3"},
                                    {"radius_m": "0.3"}, {"radius_m": np.nan}, {"normal_neighbours": 2},
                                    {"bins_per_feature": 1e300}])
def test_pfh_params_bad_values_are_typed(kwargs):
    with pytest.raises(InvalidInputError):
        PFHParams(**kwargs)
