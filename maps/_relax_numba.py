"""Numba kernel of the experience-map relaxation (Eq 2.25); imported lazily by ``maps.experience_map``."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from whisker_io.angles import wrap_scalar
from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["relax_links"]


_wrap = njit(cache=True)(wrap_scalar)


@njit(cache=True)
def _clip180(a: float) -> float:  # pragma: no cover - compiled
    # An angle already in (-pi, pi] is returned as it is, which is what the C++ loops (and
    # _wrap) return for it: none of their conditional subtractions fires. The test is two
    # well-predicted comparisons; _wrap's unrolled compare-and-subtract chains are a
    # latency chain on the Gauss-Seidel dependency path (about half of an update's time).
    if -math.pi < a <= math.pi:
        return a
    return _wrap(a, -math.pi, True)


@njit(cache=True)
def _clip360(a: float) -> float:  # pragma: no cover - compiled
    if 0.0 <= a < 2.0 * math.pi:  # already in [0, 2 pi): unchanged, as in _wrap (see _clip180)
        return a
    return _wrap(a, 0.0, False)


@njit(cache=True)
def relax_links(
    order: np.ndarray, ends: np.ndarray, ldata: np.ndarray, pose: np.ndarray, c: float, n_updates: int, start: int
) -> int:  # pragma: no cover - compiled
    """Apply ``n_updates`` single-link Eq 2.25 corrections in place, Gauss-Seidel.

    Parameters
    ----------
    order : int64 (m,)
        Link ids in relaxation order (OpenRatSLAM: by source id, then creation).
    ends : int64 (>= m, 2)
        (from, to) experience ids per link.
    ldata : float64 (>= m, 4)
        (d m, heading rad, facing rad, dt s) per link.
    pose : float64 (>= n, 3)
        Map poses (x m, y m, theta rad), corrected in place.
    c : float
        ``exp_correction``.
    n_updates : int
        Number of link updates (may exceed m: the sweep wraps around).
    start : int
        Position in ``order`` to start at.

    Returns
    -------
    int
        Position in ``order`` after the last update (the next start).
    """
    n = order.shape[0]
    two_pi = 2.0 * math.pi
    pos = start
    for _ in range(n_updates):
        k = order[pos]
        f = ends[k, 0]
        t = ends[k, 1]
        lx = pose[f, 0] + ldata[k, 0] * math.cos(pose[f, 2] + ldata[k, 1])
        ly = pose[f, 1] + ldata[k, 0] * math.sin(pose[f, 2] + ldata[k, 1])
        pose[f, 0] += (pose[t, 0] - lx) * c
        pose[f, 1] += (pose[t, 1] - ly) * c
        pose[t, 0] -= (pose[t, 0] - lx) * c
        pose[t, 1] -= (pose[t, 1] - ly) * c
        a1 = pose[f, 2] + ldata[k, 2]
        a2 = pose[t, 2]
        direction = _clip180(a2 - a1)
        delta = abs(_clip360(a1) - _clip360(a2))
        if delta < two_pi - delta:
            df = delta if direction > 0 else -delta
        else:
            df = two_pi - delta if direction > 0 else -(two_pi - delta)
        pose[f, 2] = _clip180(pose[f, 2] + df * c)
        pose[t, 2] = _clip180(pose[t, 2] - df * c)
        pos += 1
        if pos == n:
            pos = 0
    return pos


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
