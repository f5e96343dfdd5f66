"""Compiled scans of contact detection (:mod:`whisker_io.contact.detection`, Sec 5.1.1.1.1).

Each kernel replaces a handful of whole-signal numpy passes (sign flip, cumulative
minima, comparisons, ``flatnonzero``) of one module's smoothed y-deflection by one
scan, with the same IEEE operations on every sample (exact sign flips, subtractions
and comparisons), so detection finds the same indices; ``tests/test_contact_detection.py``
compares them with the numpy formulas on random signals.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["prominence_bound", "contact_extent"]


@njit(cache=True)
def prominence_bound(y: np.ndarray, sign: float) -> np.ndarray:  # pragma: no cover - compiled
    """``z - max(cummin(z), reversed cummin of reversed z)`` for ``z = sign * y``: an upper bound
    of the prominence a peak at each sample can have."""
    n = y.size
    out = np.empty(n)
    lo = np.inf
    for k in range(n):  # prefix minimum
        z = sign * y[k]
        lo = z if k == 0 else (lo if lo <= z else z)  # np.minimum
        out[k] = lo
    hi = np.inf
    for k in range(n - 1, -1, -1):  # suffix minimum, then the bound
        z = sign * y[k]
        hi = z if k == n - 1 else (hi if hi <= z else z)
        m = out[k] if out[k] >= hi else hi  # np.maximum
        out[k] = z - m
    return out


@njit(cache=True)
def contact_extent(
    y: np.ndarray, sign: float, top: int, plateau_level: float, half_level: float
) -> tuple[int, int, int, int, int, int]:  # pragma: no cover - compiled
    """Indices around the peak ``top`` of ``z = sign * y``: (first, last) of the run above
    ``plateau_level`` and of the run above ``half_level`` containing ``top``, the sign change
    of ``diff(z)`` before the rise (last ``k < rise_mid`` with ``diff <= 0``, plus one; 0 if none)
    and after the fall (first ``k >= fall_mid`` with ``diff >= 0``; ``size - 1`` if none)."""
    n = y.size
    bounds = np.empty(4, np.int64)
    for j in range(2):
        level = plateau_level if j == 0 else half_level
        first = 0
        for k in range(top - 1, -1, -1):
            if sign * y[k] <= level:
                first = k + 1
                break
        last = n - 1
        for k in range(top + 1, n):
            if sign * y[k] <= level:
                last = k - 1
                break
        bounds[2 * j] = first
        bounds[2 * j + 1] = last
    rise_mid = bounds[2]
    fall_mid = bounds[3]
    onset = 0
    for k in range(min(rise_mid, n - 1) - 1, -1, -1):
        if sign * y[k + 1] - sign * y[k] <= 0.0:
            onset = k + 1
            break
    offset = n - 1
    for k in range(fall_mid, n - 1):
        if sign * y[k + 1] - sign * y[k] >= 0.0:
            offset = k
            break
    return bounds[0], bounds[1], rise_mid, fall_mid, onset, offset


@njit(cache=True)
def bounded_maxima(y: np.ndarray, sign: float, bound: np.ndarray, min_bound: float) -> np.ndarray:  # pragma: no cover
    """The local maxima of ``z = sign * y`` as ``scipy.signal.find_peaks(z)`` returns them (a flat
    top gives its middle sample, rounded down; the end samples are never peaks), keeping those
    with ``bound >= min_bound``."""
    n = y.size
    out = np.empty(max(n // 2, 1), np.int64)
    count = 0
    i = 1
    i_max = n - 1
    while i < i_max:
        zi = sign * y[i]
        if sign * y[i - 1] < zi:
            i_ahead = i + 1
            while i_ahead < i_max and sign * y[i_ahead] == zi:
                i_ahead += 1
            if sign * y[i_ahead] < zi:
                mid = (i + i_ahead - 1) // 2
                if bound[mid] >= min_bound:
                    out[count] = mid
                    count += 1
                i = i_ahead
        i += 1
    return out[:count]


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
