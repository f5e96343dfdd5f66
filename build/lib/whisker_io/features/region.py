"""The features of one whisk that the front end matches: PFH + SDA of a surface region.

A whisk of the array touches a surface region; WhiskerRatSLAM describes it by two
vectors (Sec 5.1.1.1): the point feature histogram of the whisk's contact points
(Sec 2.5.1.1, Eq 2.40-2.44) and the slope distribution array of its 18 whiskers
(Sec 5.1.1.1.3). :class:`RegionFeatures` holds both, validated, together with the
contact points they came from; :func:`region_features` builds one from contact
points and slopes, whatever produced them (the rigid sweep, the signal chain of
:mod:`whisker_io.sim.whisk_chain`, or a recorded session).

Conventions
-----------
* Contact points are in the **end-effector frame** E (metres). The PFH's
  viewpoint (Eq 2.40) is then E's origin, so the features do not depend on where
  the arm is: two whisks of the same region from the same relative pose give the
  same features wherever the object stands. World points are
  ``pose.apply(contact_points_m)``.
* One histogram per whisk over the pairs of contacts within the PFH radius
  ``r = 0.3 m`` (:class:`~whisker_io.features.pfh.PFHParams`), normals from the 3
  nearest contacts. (On a flat wall facing the array the tips of the 160-mm
  whiskers fan out over about 0.45 m, so about a quarter of the pairs fall outside
  ``r``.)
* The SDA is zero where a whisker has no contact (or no defined slope), as the
  thesis stores it; ``sda_mask`` says which entries are measured.
* Fewer than 3 contacts is a defined "no observation" whisk
  (:attr:`RegionFeatures.is_observation` is False, the PFH is all zero): the
  model then runs on odometry only. It is never an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.features.pfh import PFHParams, point_feature_histogram
from whisker_io.validation import finite_array, whole_number

__all__ = ["MIN_OBSERVATION_CONTACTS", "MAX_CONTACT_DISTANCE_M", "RegionFeatures", "region_features"]

#: Fewest contacts of a whisk that make an observation (3 points define a plane, Sec 2.5.1.1).
MIN_OBSERVATION_CONTACTS: int = 3
#: Largest distance of a contact point from the end-effector origin, m (the thesis array
#: reaches about 0.4 m; anything beyond this is corrupt data, not a contact).
MAX_CONTACT_DISTANCE_M: float = 10.0

_SUM_TOL = 1e-9


def _bool_vector(value: ArrayLike, name: str) -> NDArray[np.bool_]:
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a 1-D array of booleans, got {value!r}") from None
    if arr.ndim != 1:
        raise ShapeError(f"{name} must be a 1-D array of booleans (one per whisker), got shape {arr.shape}")
    if arr.dtype != np.bool_:
        if arr.size and not (np.issubdtype(arr.dtype, np.number) and np.all((arr == 0) | (arr == 1))):
            raise InvalidInputError(f"{name} must hold booleans (True where a whisker has a slope), got {arr!r}")
        arr = arr.astype(bool)
    return arr


def _check_reach(points: NDArray[np.float64], name: str) -> None:
    if points.size and not float(np.max(np.abs(points))) <= MAX_CONTACT_DISTANCE_M:
        raise InvalidInputError(
            f"{name} holds a point {float(np.max(np.abs(points))):.3g} m from the end-effector origin (more than "
            f"{MAX_CONTACT_DISTANCE_M:g} m); contact points must be in the end-effector frame, in metres")


def _read_only(arr: NDArray) -> NDArray:
    arr = np.array(arr)  # own copy
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False, init=False)
class RegionFeatures:
    """Features of one whisk: PFH + SDA (Sec 5.1.1.1), validated and read-only.

    Parameters
    ----------
    pfh : array_like, shape (B,)
        Point feature histogram (Eq 2.44), non-negative, summing to 1; all zero
        when the whisk has fewer than 3 contacts (or no usable pair of them).
        ``B = PFHParams().n_bins`` (81 with the default 3 bins per feature).
    sda : array_like, shape (N,)
        Slope distribution array (Sec 5.1.1.1.3), one slope per whisker in array
        order (N = 18 for the thesis array), dimensionless; 0 where ``sda_mask``
        is False.
    sda_mask : array_like of bool, shape (N,)
        True where the whisker touched and its slope is defined.
    n_contacts : int
        Contacts registered in the whisk, ``len(contact_points_m)``.
    contact_points_m : array_like, shape (n_contacts, 3)
        The contact points in the end-effector frame, metres.

    Raises
    ------
    ShapeError
        Wrong shapes (``sda`` and ``sda_mask`` of different lengths, points not (k, 3)).
    InvalidInputError
        NaN/inf anywhere, a contact point farther than :data:`MAX_CONTACT_DISTANCE_M`,
        a negative or unnormalised histogram, a histogram with
        mass for fewer than 3 contacts, a non-zero SDA entry outside the mask,
        more measured slopes than contacts, or ``n_contacts`` that disagrees with
        the points.

    Notes
    -----
    ``==`` compares every array exactly (a replayed session reproduces its
    features bit for bit). Instances are not hashable.
    """

    pfh: NDArray[np.float64]
    sda: NDArray[np.float64]
    sda_mask: NDArray[np.bool_]
    n_contacts: int
    contact_points_m: NDArray[np.float64]

    def __init__(
        self,
        pfh: ArrayLike,
        sda: ArrayLike,
        sda_mask: ArrayLike,
        n_contacts: int,
        contact_points_m: ArrayLike,
    ) -> None:
        h = finite_array(pfh, (None,), "pfh")
        s = finite_array(sda, (None,), "sda")
        m = _bool_vector(sda_mask, "sda_mask")
        pts = finite_array(contact_points_m, (None, 3), "contact_points_m")
        k = whole_number(n_contacts, "n_contacts", minimum=0)
        if h.size == 0:
            raise ShapeError("pfh must have at least one bin")
        if s.size == 0 or s.shape != m.shape:
            raise ShapeError(
                f"sda and sda_mask must have the same non-zero length (one entry per whisker), "
                f"got {s.shape} and {m.shape}")
        if k != len(pts):
            raise InvalidInputError(f"n_contacts is {k} but {len(pts)} contact points were given")
        _check_reach(pts, "contact_points_m")
        if np.any(h < 0):
            raise InvalidInputError("pfh must be non-negative (a normalised histogram)")
        total = float(h.sum())
        if total != 0.0 and not abs(total - 1.0) <= _SUM_TOL:
            raise InvalidInputError(f"pfh must sum to 1 (or be all zero for no observation), sums to {total!r}")
        if total != 0.0 and k < MIN_OBSERVATION_CONTACTS:
            raise InvalidInputError(
                f"a whisk with {k} contacts is no observation: its pfh must be all zero "
                f"(at least {MIN_OBSERVATION_CONTACTS} contacts make a histogram)")
        if np.any(s[~m] != 0.0):
            raise InvalidInputError("sda must be 0 where sda_mask is False (the thesis' no-contact value)")
        if int(m.sum()) > k:
            raise InvalidInputError(f"sda_mask marks {int(m.sum())} measured slopes but the whisk has {k} contacts")
        object.__setattr__(self, "pfh", _read_only(h + 0.0))
        object.__setattr__(self, "sda", _read_only(s + 0.0))
        object.__setattr__(self, "sda_mask", _read_only(m))
        object.__setattr__(self, "n_contacts", k)
        object.__setattr__(self, "contact_points_m", _read_only(pts + 0.0))

    @property
    def is_observation(self) -> bool:
        """True when the whisk has at least 3 contacts (otherwise: odometry only)."""
        return self.n_contacts >= MIN_OBSERVATION_CONTACTS

    @property
    def n_whiskers(self) -> int:
        """Length N of the SDA (18 for the thesis array)."""
        return int(self.sda.size)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RegionFeatures):
            return NotImplemented
        return (self.n_contacts == other.n_contacts
                and all(np.array_equal(getattr(self, f), getattr(other, f))
                        for f in ("pfh", "sda", "sda_mask", "contact_points_m")))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (f"RegionFeatures(n_contacts={self.n_contacts}, is_observation={self.is_observation}, "
                f"pfh_bins={self.pfh.size}, sda_measured={int(self.sda_mask.sum())}/{self.sda.size})")


def region_features(
    contact_points_ee_m: ArrayLike,
    slopes: ArrayLike,
    mask: ArrayLike,
    pfh_params: PFHParams = PFHParams(),
) -> RegionFeatures:
    """Region features of one whisk from its contact points and slopes (Sec 5.1.1.1).

    Parameters
    ----------
    contact_points_ee_m : array_like, shape (k, 3)
        The whisk's contact points in the end-effector frame, metres, one row per
        registered contact (k may be 0). The PFH (Eq 2.40-2.44) uses normals from
        each point's 3 nearest contacts oriented toward the end-effector origin
        (the viewpoint of Eq 2.40) and all pairs within ``pfh_params.radius_m``
        (0.3 m: one histogram per whisk).
    slopes : array_like, shape (N,)
        Slope per whisker in array order (Eq 6.14 in simulation, the y- against
        x-deflection gradient from signals), dimensionless. Entries outside
        ``mask`` are ignored (NaN allowed there) and stored as 0.
    mask : array_like of bool, shape (N,)
        True where the whisker has a contact with a defined slope.
    pfh_params : PFHParams
        Histogram parameters (default 3 bins per feature, 81 bins, r = 0.3 m).

    Returns
    -------
    RegionFeatures
        With an all-zero PFH and ``is_observation = False`` when k < 3.

    Raises
    ------
    ShapeError
        Points not of shape (k, 3); slopes and mask not 1-D of one length.
    InvalidInputError
        Non-finite contact points or one farther than :data:`MAX_CONTACT_DISTANCE_M`
        from the end-effector origin, a non-finite slope inside the mask, or
        ``pfh_params`` that is not a :class:`PFHParams`.

    Examples
    --------
    >>> import numpy as np
    >>> pts = np.array([[0.0, 0.25, 0.0], [0.05, 0.25, 0.0], [0.0, 0.25, 0.05], [0.05, 0.25, 0.05]])
    >>> f = region_features(pts, np.zeros(18), np.zeros(18, dtype=bool))
    >>> f.is_observation, round(float(f.pfh.sum()), 12), f.pfh.shape
    (True, 1.0, (81,))
    """
    if not isinstance(pfh_params, PFHParams):
        raise InvalidInputError(f"pfh_params must be a PFHParams, got {type(pfh_params).__name__}")
    pts = finite_array(contact_points_ee_m, (None, 3), "contact_points_ee_m")
    _check_reach(pts, "contact_points_ee_m")
    m = _bool_vector(mask, "mask")
    try:
        s_raw = np.asarray(slopes, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"slopes must be an array of numbers, got {slopes!r}") from None
    if s_raw.ndim != 1 or s_raw.shape != m.shape:
        raise ShapeError(f"slopes and mask must be 1-D of one length (one per whisker), got {s_raw.shape} and {m.shape}")
    s = np.zeros(m.shape)
    if m.any():
        s[m] = finite_array(s_raw[m], (None,), "slopes (inside the mask)")
    if len(pts) >= MIN_OBSERVATION_CONTACTS:
        hist = point_feature_histogram(pts, np.zeros(3), pfh_params).histogram
    else:
        hist = np.zeros(pfh_params.n_bins)
    return RegionFeatures(hist, s, m, len(pts), pts)
