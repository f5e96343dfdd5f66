"""Point feature histogram of a whisk's contact points (Sec 2.5.1.1, Sec 2.5.1.1).

Pipeline for one whisk (at most 18 contact points):

1. **Normals** (Sec 2.5.1.1): for each point, PCA of its ``k = 3`` nearest points
   (the point itself included, the PCL convention; three points are the minimum
   that define a plane, which is why the thesis switched from a radius to the
   three closest points). The normal is the eigenvector of the *smallest*
   eigenvalue of the neighbourhood covariance (the thesis text says largest,
   a slip: Sec 2.5.1.1). Each normal is flipped to face the viewpoint (Eq 2.40;
   the viewpoint is the origin of the end-effector frame).
2. **Pairs**: every unordered pair closer than ``radius_m`` (0.3 m: all contacts
   of a whisk, Sec 2.5.1.1).
3. **Pair features** (Eq 2.41-2.43), computed exactly as PCL's
   ``computePairFeatures`` and Open3D's ``ComputePairFeatures``: the source is
   the point whose normal makes the smaller angle with the line joining the
   pair (``acos|n.dp|``, Eq 2.41 in PCL's form); Darboux frame ``u = n_s``,
   ``v = (p_t - p_s) x u / |...|``, ``w = u x v`` (Eq 2.42); features
   ``alpha = v . n_t``, ``theta = atan2(w . n_t, u . n_t)``,
   ``phi = u . (p_t - p_s) / d``, ``d = |p_t - p_s|`` (Eq 2.43).
   Degenerate pairs (``d = 0``, or ``n_s`` parallel to the joining line) have
   no Darboux frame. Decision - this project departs from PCL here: they are
   left out of the histogram, which is normalised over the pairs counted
   (:attr:`PointFeatureHistogram.n_pairs`). PCL's ``PFHEstimation`` instead
   counts such a pair with all-zero features, which puts its mass in the
   centre bins; two whiskers touching one point would then add mass to a bin
   that describes no surface.
4. **Histogram** (Eq 2.44): each feature is cut into ``bins_per_feature``
   equal bins over a fixed range (alpha, phi in [-1, 1]; theta in [-pi, pi];
   d in [0, radius_m]); the joint bin ``sum_i b_i * bins**i`` over
   ``(alpha, theta, phi, d)`` is incremented; the histogram is normalised to
   sum 1 (the thesis' ``k(k+1)/2`` divisor is not the pair count; Sec 2.5.1.1).
   Default 3 bins per feature (81 bins), the only value the thesis names
   (Sec 2.5.1.1 example); 153 pairs of 18 points fill that reasonably.
5. **Similarity**: chi-squared, Eq 2.45, skipping bins with ``q + v = 0``.

Fewer than 3 usable points is a defined case: an all-zero histogram with
``valid = False`` (chi-squared against it equals the other histogram's mass).

Region matching (Eq 5.5), which combines this chi-squared with the slope
distribution array's NMSE, is the whisk front end's job:
:mod:`cansim.frontends.whisk`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_scalar, finite_vector, validate_fields, whole_number

__all__ = [
    "FEATURE_NAMES",
    "PFHParams",
    "PointFeatureHistogram",
    "estimate_normals",
    "pair_features",
    "feature_bins",
    "point_feature_histogram",
    "chi_squared",
]

_BRUTE_FORCE_MAX = 256  # neighbour search by full distance matrix up to this many points

FEATURE_NAMES: tuple[str, ...] = ("alpha", "theta", "phi", "d")
"""Order of the pair features in :func:`pair_features` output and in the bin index (Eq 2.44)."""


@dataclass(frozen=True)
class PFHParams(ConfigDataclass):
    """Parameters of the point feature histogram (Sec 2.5.1.1).

    Attributes
    ----------
    bins_per_feature : int
        ``d`` of Eq 2.44; the histogram has ``d**4`` bins. Default 3.
    radius_m : float
        Pair radius ``r_beta`` in metres; also the top of the distance range.
        Default 0.3 (Sec 2.5.1.1).
    normal_neighbours : int
        Points used for each normal, the point itself included. Default 3.
    orient_to_viewpoint : bool
        Apply Eq 2.40. Default True (switch off only to reproduce Fig 2.18's
        "without orientation" case).
    """

    bins_per_feature: int = checked(3, int, minimum=1, error=InvalidInputError, reader=whole_number)
    radius_m: float = checked(0.3, float, above=0, error=InvalidInputError, reader=finite_scalar,
                              message="{name} must be positive, got {value!r}")
    normal_neighbours: int = checked(3, int, minimum=3, error=InvalidInputError, reader=whole_number,
                                     message="{name} must be >= 3 (a plane needs 3 points), got {value!r}")
    orient_to_viewpoint: bool = True

    def __post_init__(self) -> None:
        validate_fields(self)
        if self.bins_per_feature > 64:  # not declared as maximum: its message differs from the minimum's
            raise InvalidInputError(
                f"bins_per_feature must be <= 64 (the histogram has bins**4 entries), got {self.bins_per_feature!r}")

    @property
    def n_bins(self) -> int:
        """Number of histogram bins, ``bins_per_feature ** 4``."""
        return int(self.bins_per_feature) ** 4

    @property
    def ranges(self) -> NDArray[np.float64]:
        """Fixed (min, max) of each feature in :data:`FEATURE_NAMES` order, shape (4, 2)."""
        return np.array([[-1.0, 1.0], [-np.pi, np.pi], [-1.0, 1.0], [0.0, self.radius_m]])


@dataclass(frozen=True, eq=False)
class PointFeatureHistogram:
    """A whisk's point feature histogram.

    Attributes
    ----------
    histogram : ndarray (bins**4,)
        Normalised to sum 1; all zeros when ``valid`` is False.
    normals : ndarray (n, 3)
        Unit normals of the usable points (viewpoint-oriented).
    points : ndarray (n, 3)
        The usable (finite) points, metres.
    n_pairs : int
        Pairs that contributed to the histogram.
    valid : bool
        False when fewer than 3 usable points or no usable pair.
    """

    histogram: NDArray[np.float64]
    normals: NDArray[np.float64]
    points: NDArray[np.float64]
    n_pairs: int
    valid: bool


def _as_points(points: ArrayLike) -> NDArray[np.float64]:
    try:
        p = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"points must be an (n, 3) array of numbers, got {points!r}") from None
    if p.ndim != 2 or p.shape[1] != 3:
        raise InvalidInputError(f"points must have shape (n, 3), got {p.shape}")
    if np.isinf(p).any():
        raise InvalidInputError("points contain inf; use NaN rows for missing contacts")
    return p[np.all(np.isfinite(p), axis=1)]


def estimate_normals(
    points: ArrayLike,
    viewpoint: ArrayLike = (0.0, 0.0, 0.0),
    k: int = 3,
    orient: bool = True,
) -> NDArray[np.float64]:
    """Normals by PCA of each point's ``k`` nearest points, oriented to the viewpoint.

    Parameters
    ----------
    points : array_like (n, 3), n >= k
        Finite points, metres.
    viewpoint : array_like (3,)
        Eq 2.40: a normal with ``(v - p) . n < 0`` is flipped. Default origin.
    k : int
        Neighbourhood size including the point itself (>= 3).
    orient : bool
        Apply Eq 2.40 (default True).

    Returns
    -------
    ndarray (n, 3)
        Unit normals: eigenvector of the smallest covariance eigenvalue.
    """
    p = np.asarray(points, dtype=float)
    n = len(p)
    if p.ndim != 2 or p.shape[1] != 3 or n < k or k < 3:
        raise InvalidInputError(f"need at least k = {k} >= 3 points of shape (n, 3); got {p.shape}")
    if n <= _BRUTE_FORCE_MAX:
        d2 = np.sum((p[:, None, :] - p[None, :, :]) ** 2, axis=-1)
        nbr = np.argsort(d2, axis=1, kind="stable")[:, :k]
    else:  # large clouds (e.g. mesh vertices): a k-d tree instead of the n x n matrix
        from scipy.spatial import cKDTree

        nbr = cKDTree(p).query(p, k=k)[1]
    nb = p[nbr]  # (n, k, 3)
    c = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", c, c) / k
    _, vec = np.linalg.eigh(cov)
    normals = vec[:, :, 0]
    if orient:
        v = np.asarray(viewpoint, dtype=float)
        flip = np.einsum("ni,ni->n", v - p, normals) < 0.0
        normals[flip] *= -1.0
    return normals


def pair_features(
    p1: ArrayLike, n1: ArrayLike, p2: ArrayLike, n2: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """PFH pair features (Eq 2.41-2.43), vectorised; same as PCL/Open3D ``computePairFeatures``.

    Parameters
    ----------
    p1, n1, p2, n2 : array_like (m, 3) or (3,)
        Point and unit normal of each end of each pair.

    Returns
    -------
    features : ndarray (m, 4)
        ``(alpha, theta, phi, d)`` per pair (:data:`FEATURE_NAMES`), radians/metres.
    ok : ndarray (m,) bool
        False for degenerate pairs (coincident points, or the source normal
        parallel to the joining line); their features are 0.
    """
    p1, n1, p2, n2 = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (p1, n1, p2, n2))
    dp = p2 - p1
    d = np.linalg.norm(dp, axis=1)
    ok = d > 0.0
    ds = np.where(ok, d, 1.0)
    a1 = np.einsum("ij,ij->i", n1, dp) / ds
    a2 = np.einsum("ij,ij->i", n2, dp) / ds
    # Eq 2.41 (PCL form): source = the end whose normal is closer to the joining line
    swap = np.arccos(np.clip(np.abs(a1), 0, 1)) > np.arccos(np.clip(np.abs(a2), 0, 1))
    u = np.where(swap[:, None], n2, n1)
    nt = np.where(swap[:, None], n1, n2)
    dp = np.where(swap[:, None], -dp, dp)
    phi = np.where(swap, -a2, a1)
    v = np.cross(dp, u)
    vn = np.linalg.norm(v, axis=1)
    ok &= vn > 0.0
    v = v / np.where(vn > 0, vn, 1.0)[:, None]
    w = np.cross(u, v)
    alpha = np.einsum("ij,ij->i", v, nt)
    theta = np.arctan2(np.einsum("ij,ij->i", w, nt), np.einsum("ij,ij->i", u, nt))
    feats = np.column_stack([alpha, theta, phi, d])
    feats[~ok] = 0.0
    return feats, ok


def feature_bins(features: ArrayLike, params: PFHParams = PFHParams()) -> NDArray[np.int64]:
    """Joint histogram bin of each feature vector (Eq 2.44).

    ``b_i = floor(bins * (f_i - min_i) / (max_i - min_i))`` clipped to
    ``[0, bins - 1]`` (values at a range's top fall in the last bin), and
    ``idx = sum_i b_i * bins**i`` over ``(alpha, theta, phi, d)``.

    Parameters
    ----------
    features : array_like (m, 4)

    Returns
    -------
    ndarray (m,) int in ``[0, bins**4)``
    """
    f = np.atleast_2d(np.asarray(features, dtype=float))
    nb = int(params.bins_per_feature)
    rng = params.ranges
    b = np.floor(nb * (f - rng[:, 0]) / (rng[:, 1] - rng[:, 0])).astype(np.int64)
    b = np.clip(b, 0, nb - 1)
    return b @ (nb ** np.arange(4, dtype=np.int64))


def point_feature_histogram(
    points: ArrayLike,
    viewpoint: ArrayLike = (0.0, 0.0, 0.0),
    params: PFHParams = PFHParams(),
) -> PointFeatureHistogram:
    """Point feature histogram of one whisk's contact points (Sec 2.5.1.1, Eq 2.40-2.44).

    Parameters
    ----------
    points : array_like (n, 3)
        Contact points in metres, any frame; rows containing NaN are missing
        contacts and are ignored.
    viewpoint : array_like (3,)
        Origin of the end-effector frame in the same frame as ``points``
        (Eq 2.40). Default the origin, i.e. points given in the end-effector frame.
    params : PFHParams

    Returns
    -------
    PointFeatureHistogram
        ``valid = False`` and an all-zero histogram when fewer than 3 points
        (or no non-degenerate pair) are available; never raises for that.
    """
    p = _as_points(points)
    vp = finite_vector(viewpoint, 3, "viewpoint")
    hist = np.zeros(params.n_bins)
    k = int(params.normal_neighbours)
    if len(p) < max(3, k):
        return PointFeatureHistogram(hist, np.zeros((len(p), 3)), p, 0, False)
    normals = estimate_normals(p, vp, k, params.orient_to_viewpoint)
    i, j = np.triu_indices(len(p), k=1)
    close = np.sum((p[i] - p[j]) ** 2, axis=1) <= params.radius_m**2
    i, j = i[close], j[close]
    feats, ok = pair_features(p[i], normals[i], p[j], normals[j])
    feats = feats[ok]
    if len(feats) == 0:
        return PointFeatureHistogram(hist, normals, p, 0, False)
    hist = np.bincount(feature_bins(feats, params), minlength=params.n_bins).astype(float)
    hist /= len(feats)
    return PointFeatureHistogram(hist, normals, p, len(feats), True)


def chi_squared(q: ArrayLike, v: ArrayLike) -> NDArray[np.float64] | float:
    """Chi-squared distance of histograms (Eq 2.45), bins with ``q + v = 0`` skipped.

    ``sum_i (q_i - v_i)**2 / (q_i + v_i)``; broadcasts over leading axes, so
    ``chi_squared(h, stored)`` with ``stored`` of shape (m, B) gives (m,).

    Parameters
    ----------
    q, v : array_like (..., B)
        Non-negative histograms (B >= 1 bins along the last axis).

    Raises
    ------
    ShapeError
        A histogram that is a scalar (no bin axis), lengths that differ, or
        leading axes that do not broadcast.
    InvalidInputError
        Non-numeric, NaN/inf or negative entries.
    """
    q = finite_array(q, None, "q")
    v = finite_array(v, None, "v")
    if q.ndim == 0 or v.ndim == 0:
        raise ShapeError(f"histograms need a bin axis; got shapes {q.shape} and {v.shape} "
                         "(pass arrays of shape (..., B))")
    if q.shape[-1] != v.shape[-1]:
        raise ShapeError(f"histograms differ in length: {q.shape[-1]} vs {v.shape[-1]}")
    if q.shape[-1] == 0:
        raise ShapeError("histograms need at least one bin")
    try:
        np.broadcast_shapes(q.shape, v.shape)
    except ValueError:
        raise ShapeError(f"histogram shapes {q.shape} and {v.shape} do not broadcast") from None
    if np.any(q < 0) or np.any(v < 0):
        raise InvalidInputError("histograms must be non-negative (bin counts or fractions)")
    from whisker_io.features._distances_numba import chi2_rows

    lead = np.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    if q.ndim == 1:
        out = chi2_rows(q, np.ascontiguousarray(v.reshape(-1, v.shape[-1]))).reshape(lead)
    else:
        qb = np.broadcast_to(q, lead + q.shape[-1:]).reshape(-1, q.shape[-1])
        vb = np.broadcast_to(v, lead + v.shape[-1:]).reshape(-1, v.shape[-1])
        out = np.array([chi2_rows(qr, vr[None, :])[0] for qr, vr in zip(qb, vb)]).reshape(lead)
    return float(out) if np.ndim(out) == 0 else out

