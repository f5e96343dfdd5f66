"""Whisk front end of WhiskerRatSLAM: regions by point feature histogram and slope distribution (Eq 5.5).

A *region* is what one whisk of the array feels: the point feature histogram (PFH,
Sec 2.5.1.1) of its contact points and the slope distribution array (SDA, Sec
5.1.1.1.3) of its 18 whiskers. The front end keeps the stored regions - one local-view
cell each - and matches a new whisk against them (Eq 5.5, Sec 5.1.1.1.4):

* every stored region ``o_i = (f_i, s_i)`` gives ``[chi2(f_n, f_i), NMSE(s_n, s_i)]``
  (Eq 2.45 and Eq 5.3-5.4; NMSE is asymmetric, the current whisk ``s_n`` is the
  reference);
* the candidates are the regions with ``chi2 < pfh_threshold`` AND
  ``NMSE < sda_threshold``; the match is the candidate with the smallest
  ``chi2 + NMSE``;
* with no candidate the whisk becomes a new stored region.

``features`` selects the terms (Table 5.1): ``"pfh"`` (one threshold, one term),
``"sda"``, or ``"both"``. ``feature_update=True`` ("feature update ON" in Table 5.1)
replaces a matched region's stored vectors by the running mean of every whisk matched
to it; off (default) keeps the first whisk's features, the thesis' best configuration.
The thresholds were tuned by hand in the thesis and are not printed; the defaults here
were calibrated on the simulator (see :class:`WhiskFrontEndConfig`).

A whisk with fewer than 3 contacts has no PFH and is not an observation; the model
runs odometry only for it (the front end is not called).

Pose prior (optional, :attr:`WhiskFrontEnd.pose_prior`): a callable the model sets that
returns, for the stored regions, which are consistent with the current pose estimate and
a non-negative pose cost for each. :meth:`WhiskFrontEnd.match` then keeps only the
consistent candidates and picks the smallest ``chi2 + NMSE + cost`` - the RatSLAM
principle that a place is recognised from the view *and* the pose belief together
(:class:`cansim.models.whisker_ratslam.WhiskerRatSLAMConfig`, ``pose_gate_m``). Without a
prior (default) the match is Eq 5.5's. :meth:`WhiskFrontEnd.scores` never applies it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from whisker_io.errors import CorruptFileError, InvalidInputError, ShapeError
from cansim.frontends.store import ViewMatch
from whisker_io.features._distances_numba import chi2_columns, nmse_columns
from whisker_io.validation import ConfigDataclass, checked, validate_fields
from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["WhiskFrontEnd", "WhiskFrontEndConfig", "RegionScores", "PosePrior", "FEATURES"]

FEATURES = ("pfh", "sda", "both")


@dataclass(frozen=True)
class WhiskFrontEndConfig(ConfigDataclass):
    """Parameters of the whisk front end.

    Parameters
    ----------
    features : {"pfh", "sda", "both"}
        Which terms of Eq 5.5 decide (Table 5.1).
    pfh_threshold : float
        ``T_pfh``: chi-squared distance (Eq 2.45) below which a stored region is a
        candidate. Histograms sum to 1, so chi2 lies in [0, 2].
    sda_threshold : float
        ``T_sda``: NMSE (Eq 5.3) below which a stored region is a candidate.
    feature_update : bool
        Average a matched region's stored vectors with every new whisk matched to it.
    use_sda_mask : bool
        Compare SDAs only on whiskers in contact in both whisks; False (the thesis):
        whiskers without contact count with slope 0.
    n_bins : int
        PFH length (81 for 3 bins per feature, Eq 2.44).
    n_whiskers : int
        SDA length (18 on the thesis' array).
    """

    features: str = checked("both", str, choices=FEATURES)
    pfh_threshold: float = checked(0.4, float, above=0)
    sda_threshold: float = checked(0.5, float, above=0)
    feature_update: bool = checked(False, bool)
    use_sda_mask: bool = checked(False, bool)
    n_bins: int = checked(81, int, minimum=1)
    n_whiskers: int = checked(18, int, minimum=1)

    def __post_init__(self) -> None:
        validate_fields(self)  # the declared fields; numpy scalars -> Python numbers (saved as JSON with the model)


@dataclass(frozen=True)
class RegionScores:
    """Eq 5.5 against every stored region (for inspection and Ch.6's similarity matrix).

    Attributes
    ----------
    chi2 : ndarray (m,)
        PFH chi-squared distance to each stored region (zeros when PFH is not used).
    nmse : ndarray (m,)
        SDA NMSE to each stored region (zeros when SDA is not used).
    candidates : ndarray (k,) int64
        Regions under both thresholds (and consistent with the pose prior, when one is set).
    best : int or None
        The match (smallest ``chi2 + nmse`` among the candidates, plus the pose cost with a prior).
    """

    chi2: np.ndarray
    nmse: np.ndarray
    candidates: np.ndarray
    best: int | None


def _vector(value: Any, n: int, name: str, bounded: Callable[[np.ndarray], bool], problem: str) -> np.ndarray:
    """``value`` as a new float64 (n,) array; ``bounded(arr)`` False (it must be False for non-finite
    entries) raises: "must be finite" when an entry is not, else ``problem``."""
    try:
        arr = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be {n} real numbers, got {type(value).__name__}") from None
    if arr.shape != (n,):
        raise ShapeError(f"{name} must have {n} entries, got {arr.size}")
    if not bounded(arr):  # one test for the usual, valid case
        if not np.isfinite(arr).all():
            raise InvalidInputError(f"{name} must be finite")
        raise InvalidInputError(problem)
    return arr


def _histogram(f: np.ndarray) -> bool:
    return bool(f.min() >= 0 and 0.999 < f.sum() < 1.001)  # False for NaN and infinities


def _slopes(s: np.ndarray) -> bool:
    return bool(np.abs(s).max(initial=0.0) <= 1e6)  # False for NaN and infinities


def _grow(arr: np.ndarray, needed: int) -> np.ndarray:
    """``arr`` with room for ``needed`` regions along its last axis (one column per region)."""
    have = arr.shape[-1]
    if needed <= have:
        return arr
    new = np.zeros(arr.shape[:-1] + (max(needed, 2 * have, 16),), dtype=arr.dtype)
    new[..., :have] = arr
    return new


@njit(cache=True)
def _candidates(chi2: np.ndarray, nmse: np.ndarray, t_pfh: float, t_sda: float) -> tuple[np.ndarray, int]:  # pragma: no cover
    """Eq 5.5's candidates (``chi2 < t_pfh`` and ``nmse < t_sda``) in order, and the first one with the
    smallest ``chi2 + nmse`` (-1 when there is none), in one compiled pass."""
    cand = np.empty(chi2.shape[0], np.int64)
    k = 0
    best = -1
    low = math.inf
    for r in range(chi2.shape[0]):
        if chi2[r] < t_pfh and nmse[r] < t_sda:
            cand[k] = r
            k += 1
            total = chi2[r] + nmse[r]
            if best < 0 or total < low:
                best, low = r, total
    return cand[:k].copy(), best


PosePrior = Callable[[int], tuple[np.ndarray, np.ndarray]]
"""``prior(n_regions) -> (consistent (n,) bool, cost (n,) float >= 0)``: see the module docstring."""


class WhiskFrontEnd:
    """Stored regions and Eq 5.5 matching (see the module docstring).

    Parameters
    ----------
    config : WhiskFrontEndConfig, optional
    pose_prior : callable, optional
        ``prior(n_regions) -> (consistent, cost)``, consulted by :meth:`match` (module
        docstring); also settable as the attribute :attr:`pose_prior`.

    Notes
    -----
    :meth:`match` takes a region observation: any object with ``pfh`` (n_bins,) and
    ``sda`` (n_whiskers,) attributes and optionally ``sda_mask`` (such as
    :class:`whisker_io.features.region.RegionFeatures`), or a ``(pfh, sda)`` /
    ``(pfh, sda, sda_mask)`` tuple.
    """

    def __init__(self, config: WhiskFrontEndConfig | None = None, pose_prior: PosePrior | None = None) -> None:
        self.config = config if config is not None else WhiskFrontEndConfig()
        self.pose_prior: PosePrior | None = pose_prior
        c = self.config
        self._n = 0
        # stored regions column-wise, one column per region: the distance kernels run
        # along contiguous rows (whisker_io.features._distances_numba)
        self._pfh = np.zeros((c.n_bins, 16))
        self._sda = np.zeros((c.n_whiskers, 16))
        self._mask = np.ones((c.n_whiskers, 16), dtype=bool)
        self._count = np.zeros(16, dtype=np.int64)
        self.last_scores: RegionScores | None = None

    def __len__(self) -> int:
        return self._n

    @property
    def pfh(self) -> np.ndarray:
        """Stored histograms, (n_regions, n_bins) (a copy)."""
        return self._pfh[:, : self._n].T.copy()

    @property
    def sda(self) -> np.ndarray:
        """Stored SDAs, (n_regions, n_whiskers) (a copy)."""
        return self._sda[:, : self._n].T.copy()

    # ------------------------------------------------------------- input
    def parse(self, observation: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Validate a region observation -> (pfh, sda, sda_mask) arrays."""
        c = self.config
        mask: Any = None
        if isinstance(observation, tuple):
            if len(observation) not in (2, 3):
                raise InvalidInputError(f"a region observation tuple is (pfh, sda) or (pfh, sda, sda_mask), got {len(observation)} entries")
            pfh, sda = observation[0], observation[1]
            mask = observation[2] if len(observation) == 3 else None
        elif hasattr(observation, "pfh") and hasattr(observation, "sda"):
            pfh, sda, mask = observation.pfh, observation.sda, getattr(observation, "sda_mask", None)
        else:
            raise InvalidInputError(
                f"a whisk observation has pfh and sda (e.g. whisker_io.features.region.RegionFeatures), got {type(observation).__name__}"
            )
        f = _vector(pfh, c.n_bins, "pfh", _histogram, "pfh must be a normalised histogram (entries >= 0 summing to 1)")
        s = _vector(sda, c.n_whiskers, "sda", _slopes, "sda slopes beyond 1e6 are not physical; check the gradient fit")
        if mask is None:
            return f, s, np.ones(c.n_whiskers, dtype=bool)
        m = np.asarray(mask)
        if m.shape != (c.n_whiskers,) or m.dtype != bool:
            raise ShapeError(f"sda_mask must be {c.n_whiskers} booleans, got {m.shape} {m.dtype}")
        return f, s, m.copy()

    # ------------------------------------------------------------ matching
    def scores(self, pfh: np.ndarray, sda: np.ndarray, mask: np.ndarray) -> RegionScores:
        """Eq 5.5 of a parsed observation against every stored region (no state change)."""
        c, n = self.config, self._n
        if n == 0:
            zero = np.zeros(0)
            return RegionScores(zero, zero, np.zeros(0, dtype=np.int64), None)
        use_pfh, use_sda = c.features in ("pfh", "both"), c.features in ("sda", "both")
        zero = None if use_pfh and use_sda else np.zeros(n)
        # the parsed observation and the stored regions are validated: call the compiled
        # kernels behind whisker_io's chi_squared (Eq 2.45) and nmse (Eq 5.3) directly
        chi2 = chi2_columns(pfh, self._pfh, n) if use_pfh else zero
        e = nmse_columns(sda, self._sda, mask, self._mask, n, c.use_sda_mask) if use_sda else zero
        cand, best = _candidates(chi2, e, c.pfh_threshold if use_pfh else math.inf, c.sda_threshold if use_sda else math.inf)
        return RegionScores(chi2, e, cand, None if best < 0 else int(best))

    def match(self, observation: Any) -> ViewMatch:
        """Match a whisk: the best stored region, or a new one (validates first).

        Returns
        -------
        ViewMatch
            ``view_id`` = the region, ``error`` = its ``chi2 + NMSE`` (inf when new).

        Raises
        ------
        InvalidInputError, ShapeError
            A malformed observation; nothing is stored.
        """
        f, s, m = self.parse(observation)
        sc = self.scores(f, s, m)
        if self.pose_prior is not None and sc.candidates.size:
            sc = self._with_prior(sc)
        self.last_scores = sc
        if sc.best is None:
            rid = self._n
            self._pfh, self._sda = _grow(self._pfh, rid + 1), _grow(self._sda, rid + 1)
            self._mask, self._count = _grow(self._mask, rid + 1), _grow(self._count, rid + 1)
            self._pfh[:, rid], self._sda[:, rid], self._mask[:, rid], self._count[rid] = f, s, m, 1
            self._n = rid + 1
            return ViewMatch(rid, True, math.inf, None)
        rid = sc.best
        if self.config.feature_update:
            k = self._count[rid]
            self._pfh[:, rid] = (self._pfh[:, rid] * k + f) / (k + 1)
            self._sda[:, rid] = (self._sda[:, rid] * k + s) / (k + 1)
            self._mask[:, rid] |= m
            self._count[rid] = k + 1
        return ViewMatch(rid, False, float(sc.chi2[rid] + sc.nmse[rid]), None)

    def _with_prior(self, sc: RegionScores) -> RegionScores:
        """Keep the pose-consistent candidates; the match minimises ``chi2 + NMSE + cost``."""
        n = self._n
        consistent, cost = self.pose_prior(n)  # type: ignore[misc]
        consistent, cost = np.asarray(consistent), np.asarray(cost, dtype=np.float64)
        if consistent.shape != (n,) or consistent.dtype != bool or cost.shape != (n,):
            raise ShapeError(f"a pose prior returns ({n},) booleans and ({n},) costs, got {consistent.shape} {consistent.dtype} and {cost.shape}")
        cand = sc.candidates[consistent[sc.candidates]]
        if cand.size and not (np.isfinite(cost[cand]).all() and cost[cand].min() >= 0):
            raise InvalidInputError("a pose prior's costs must be finite and >= 0 for consistent regions")
        best = int(cand[np.argmin(sc.chi2[cand] + sc.nmse[cand] + cost[cand])]) if cand.size else None
        return RegionScores(sc.chi2, sc.nmse, cand, best)

    def extend(self, other: "WhiskFrontEnd") -> int:
        """Append ``other``'s stored regions after this front end's (an object library, Fig 5.16).

        Returns
        -------
        int
            The id offset of ``other``'s regions here (the number stored before).
        """
        if not isinstance(other, WhiskFrontEnd) or (other.config.n_bins, other.config.n_whiskers) != (
            self.config.n_bins, self.config.n_whiskers
        ):
            raise InvalidInputError("extend needs a WhiskFrontEnd with the same PFH length and number of whiskers")
        offset, m = self._n, other._n
        n = offset + m
        self._pfh, self._sda = _grow(self._pfh, n), _grow(self._sda, n)
        self._mask, self._count = _grow(self._mask, n), _grow(self._count, n)
        self._pfh[:, offset:n], self._sda[:, offset:n] = other._pfh[:, :m], other._sda[:, :m]
        self._mask[:, offset:n], self._count[offset:n] = other._mask[:, :m], other._count[:m]
        self._n = n
        return offset

    # --------------------------------------------------------- persistence
    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """State as named arrays (bit exact)."""
        n = self._n
        return {
            f"{prefix}pfh": self._pfh[:, :n].T.copy(), f"{prefix}sda": self._sda[:, :n].T.copy(),
            f"{prefix}sda_mask": self._mask[:, :n].T.copy(), f"{prefix}count": self._count[:n].copy(),
        }

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str) -> None:
        """Restore :meth:`to_arrays` output; raises CorruptFileError naming a bad field."""
        c = self.config
        got = {}
        for name, kind, width in (("pfh", "f", c.n_bins), ("sda", "f", c.n_whiskers), ("sda_mask", "b", c.n_whiskers), ("count", "i", None)):
            key = prefix + name
            if key not in arrays:
                raise CorruptFileError("missing", field=key)
            arr = np.asarray(arrays[key])
            shape_ok = arr.ndim == (1 if width is None else 2) and (width is None or arr.shape[1] == width)
            if arr.dtype.kind != kind or not shape_ok or (kind == "f" and not np.isfinite(arr).all()):
                raise CorruptFileError(f"dtype {arr.dtype} / shape {arr.shape} is not a stored-region array", field=key)
            got[name] = arr
        n = got["pfh"].shape[0]
        if any(a.shape[0] != n for a in got.values()) or (n and got["count"].min() < 1):
            raise CorruptFileError("stored-region arrays disagree in length or hold a count < 1", field=prefix + "count")
        self._n = n
        self._pfh = _grow(np.ascontiguousarray(got["pfh"].T, dtype=np.float64), n)
        self._sda = _grow(np.ascontiguousarray(got["sda"].T, dtype=np.float64), n)
        self._mask = _grow(np.ascontiguousarray(got["sda_mask"].T, dtype=bool), n)
        self._count = _grow(got["count"].astype(np.int64), n)


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
