"""Numba kernel of the experience map's match search (Eq 2.22); imported lazily by ``maps.experience_map``."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["nearest_of_view"]


@njit(cache=True)
def _distance(pc: np.ndarray, i: int, corr: np.ndarray, shape: np.ndarray) -> float:  # pragma: no cover - compiled
    total = 0.0  # 0.0 + the first square: exact (the square is >= +0)
    for ax in range(corr.shape[0]):
        e = abs(corr[ax] - pc[i, ax])
        w = shape[ax] - e
        if w < e:  # min(e, n - e): the first of equal values (equal values have equal bits here)
            e = w
        total += e * e
    return math.sqrt(total)


@njit(cache=True)
def nearest_of_view(
    pc: np.ndarray, next_same: np.ndarray, head: int, current: int, corr: np.ndarray, shape: np.ndarray
) -> tuple[float, int, float]:  # pragma: no cover - compiled
    """The packet's distance to the current experience and to the nearest other one of a view.

    Parameters
    ----------
    pc : float64 (>= n, ndim)
        Pose-cell coordinates of the experiences (cells).
    next_same : int64 (>= n,)
        Per experience, the next experience of the same view by id (-1: none).
    head : int
        The view's first experience (-1: the view has none).
    current : int
        The current experience (excluded from the search), >= 0.
    corr : float64 (ndim,)
        The (offset-corrected) packet (cells).
    shape : float64 (ndim,)
        Pose-cell grid shape, to wrap the distances.

    Returns
    -------
    (float, int, float)
        Wrapped distance (cells) to ``current``; the view's experience other than ``current``
        with the smallest distance (the lowest id on ties; -1 when there is none) and that
        distance (``inf`` when none). Each distance is ``sqrt(sum over axes, in axis order,
        of min(|c - v|, n - |c - v|)^2)``.
    """
    d_current = _distance(pc, current, corr, shape)
    best_id = -1
    best = math.inf
    i = head
    while i >= 0:
        if i != current:
            d = _distance(pc, i, corr, shape)
            if best_id < 0 or d < best:  # strict: the first minimum, as numpy's argmin
                best_id = i
                best = d
        i = next_same[i]
    return d_current, best_id, best


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
