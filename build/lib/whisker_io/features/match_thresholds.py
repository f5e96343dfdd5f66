"""Region-matching thresholds T_pfh and T_sda from repeated whisks at the same poses.

The thesis does not print the thresholds of Eq 5.5 (a stored region is a candidate when
its PFH chi-squared distance, Eq 2.45, is below T_pfh and its SDA NMSE, Eq 5.3-5.4,
below T_sda). This module calibrates them on the sensor itself: whisk twice at every
pose of a loop (independent noise) and once more at the next pose of the loop; a
threshold is the ``quantile`` quantile of the same-pose distances, so that fraction of
true revisits of a region are candidates. The distances between neighbouring poses
tell how many false candidates the thresholds let in
(:attr:`ThresholdCalibration.next_chi2_below_threshold`).

Only poses where all three whisks (the pair and the next pose's first whisk) are
observations (:attr:`~whisker_io.features.region.RegionFeatures.is_observation`, at least
3 contacts) count. The loop is closed: the pose after the last is the first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any, TypeVar

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.features.pfh import chi_squared
from whisker_io.features.region import RegionFeatures
from whisker_io.features.sda import nmse
from whisker_io.validation import finite_scalar

__all__ = ["ThresholdCalibration", "calibrate_match_thresholds"]

P = TypeVar("P")


@dataclass(frozen=True)
class ThresholdCalibration:
    """T_pfh and T_sda and the distance statistics behind them.

    Attributes
    ----------
    quantile : float
        Quantile of the same-pose distances taken as the thresholds.
    n_pairs : int
        Poses that counted (all three whisks observations).
    pfh_threshold, sda_threshold : float
        T_pfh (chi-squared, Eq 2.45) and T_sda (NMSE, Eq 5.3-5.4), dimensionless.
    same_chi2_median, next_chi2_median : float
        Median chi-squared between two whisks at one pose, and between a pose and the next.
    same_nmse_median, next_nmse_median : float
        The same for the SDA NMSE.
    next_chi2_below_threshold, next_nmse_below_threshold : float
        Fraction of next-pose pairs under T_pfh and under T_sda (false candidates).
    """

    quantile: float
    n_pairs: int
    pfh_threshold: float
    sda_threshold: float
    same_chi2_median: float
    next_chi2_median: float
    same_nmse_median: float
    next_nmse_median: float
    next_chi2_below_threshold: float
    next_nmse_below_threshold: float

    def as_row(self) -> dict[str, Any]:
        """The fields as a dict in declaration order (one CSV row)."""
        return asdict(self)


def _quantile(x: Sequence[float], q: float) -> float:
    """``np.quantile(x, q)`` (linear), ``inf`` where it would interpolate into an infinite distance."""
    a = np.asarray(x, dtype=np.float64)
    inf = np.isinf(a)
    if not inf.any():
        return float(np.quantile(a, q))
    big = np.finfo(np.float64).max
    v = float(np.quantile(np.where(inf, big, a), q))
    return v if not inf.all() and v <= a[~inf].max() else float("inf")


def _distances(first: RegionFeatures, second: RegionFeatures, use_sda_mask: bool) -> tuple[float, float]:
    e = (nmse(first.sda, second.sda, first.sda_mask, second.sda_mask) if use_sda_mask
         else nmse(first.sda, second.sda))
    return float(chi_squared(first.pfh, second.pfh)), float(e)


def calibrate_match_thresholds(
    sensor: Callable[[P], RegionFeatures],
    poses: Sequence[P],
    quantile: float = 0.75,
    *,
    use_sda_mask: bool = False,
) -> ThresholdCalibration:
    """Whisk twice at every pose and calibrate T_pfh and T_sda (see the module docstring).

    Parameters
    ----------
    sensor : callable
        ``sensor(pose) -> RegionFeatures``, one whisk per call (the simulated
        :meth:`whisker_io.sim.whisk_chain.WhiskChain.features` with its generator bound,
        or a recorded/real array). Called in order: pose 0 twice, pose 1 twice, ...
    poses : sequence
        At least 2 poses of a closed loop, whatever ``sensor`` takes (e.g.
        :class:`~whisker_io.pose.Pose` s of ``object_trajectory(mesh, "A", 1)``).
    quantile : float, default 0.75
        In (0, 1]: the fraction of same-pose pairs that fall under the thresholds.
    use_sda_mask : bool, default False
        Compare SDAs only where both whisks touched, as the front end does with its
        ``use_sda_mask`` (default False: the thesis' comparison over all whiskers).

    Returns
    -------
    ThresholdCalibration

    Raises
    ------
    InvalidInputError
        Fewer than 2 poses, a quantile outside (0, 1], a sensor that returns something
        other than :class:`RegionFeatures`, or no pose where all three whisks had at
        least 3 contacts (move the poses closer to the surface).
    """
    q = finite_scalar(quantile, "quantile")
    if not 0.0 < q <= 1.0:
        raise InvalidInputError(f"quantile must lie in (0, 1], got {quantile!r}")
    if not isinstance(use_sda_mask, (bool, np.bool_)):
        raise InvalidInputError(f"use_sda_mask must be a bool, got {use_sda_mask!r}")
    if not callable(sensor):
        raise InvalidInputError(f"sensor must be callable (pose -> RegionFeatures), got {type(sensor).__name__}")
    try:
        n = len(poses)
    except TypeError:
        raise InvalidInputError(f"poses must be a sequence, got {type(poses).__name__}") from None
    if n < 2:
        raise InvalidInputError(f"calibration needs at least 2 poses of a loop, got {n}")
    whisks = []
    for p in poses:
        pair = (sensor(p), sensor(p))
        if not all(isinstance(f, RegionFeatures) for f in pair):
            raise InvalidInputError(f"sensor must return RegionFeatures, got {type(pair[0]).__name__}")
        whisks.append(pair)
    same_c, same_e, next_c, next_e = [], [], [], []
    for k, (a, b) in enumerate(whisks):
        c = whisks[(k + 1) % n][0]
        if a.is_observation and b.is_observation and c.is_observation:
            sc, se = _distances(a, b, bool(use_sda_mask))
            nc, ne = _distances(a, c, bool(use_sda_mask))
            same_c.append(sc)
            same_e.append(se)
            next_c.append(nc)
            next_e.append(ne)
    if not same_c:
        raise InvalidInputError(f"none of the {n} poses gave 3 or more contacts in all three whisks; "
                                "calibrate on poses closer to the surface")
    t_pfh, t_sda = _quantile(same_c, q), _quantile(same_e, q)
    if not (np.isfinite(t_pfh) and np.isfinite(t_sda)):
        raise InvalidInputError(f"the {q:g} quantile of the same-pose distances is infinite (SDAs with no slope in "
                                "common); lower the quantile or set use_sda_mask=False")
    return ThresholdCalibration(
        quantile=q, n_pairs=len(same_c), pfh_threshold=t_pfh, sda_threshold=t_sda,
        same_chi2_median=_quantile(same_c, 0.5), next_chi2_median=_quantile(next_c, 0.5),
        same_nmse_median=_quantile(same_e, 0.5), next_nmse_median=_quantile(next_e, 0.5),
        next_chi2_below_threshold=float(np.mean(np.asarray(next_c) < t_pfh)),
        next_nmse_below_threshold=float(np.mean(np.asarray(next_e) < t_sda)),
    )
