"""Population-vector decoding (Eq 5.11-5.12, thesis Eq 5.11-5.12, Fig 5.12)."""

from __future__ import annotations

import numpy as np

__all__ = ["circular_mean_index", "window_indices", "population_vector_window"]


def circular_mean_index(profile: np.ndarray) -> float:
    """Activity-weighted circular mean of an axis profile, as a fractional index.

    Index ``i`` of an axis of ``n`` cells maps to the angle ``2*pi*i/n``; the mean
    angle is ``atan2(sum p_i sin, sum p_i cos)``, wrapped to ``[0, 2*pi)`` and mapped
    back to an index in ``[0, n)``.

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Non-negative activity per cell along the axis.

    Returns
    -------
    float
        Fractional index in ``[0, n)``.

    Examples
    --------
    Fig 5.12 of the thesis: five head-direction cells at 72..360 deg, activities 1 at
    360 (index 0), 3.1 at 288 (index 4) and 0.8 at 216 (index 3):

    >>> i = circular_mean_index(np.array([1.0, 0, 0, 0.8, 3.1]))
    >>> round(i * 72.0, 3)
    290.978
    """
    n = profile.shape[0]
    ang = 2.0 * np.pi * np.arange(n) / n
    p = profile.astype(np.float64)
    mean = np.arctan2(np.dot(p, np.sin(ang)), np.dot(p, np.cos(ang)))
    idx = (mean % (2.0 * np.pi)) * n / (2.0 * np.pi)
    return float(idx) if idx < n else 0.0


def window_indices(centre: int, window: int, n: int) -> np.ndarray:
    """Indices ``centre - window .. centre + window`` wrapped into ``[0, n)``.

    Clipped to the whole axis when ``2 * window + 1 >= n`` so no cell appears twice. On an
    odd axis that is the cap ``window <= (n - 1) // 2``; on an even axis of ``n <= 2 * window``
    cells (4 or 6 with the default 3) the window is all ``n`` cells, the cell opposite the
    peak included, where that cap would leave it out (decision: every cell counted once
    either way; the thesis' axes, 5, 21, 30 and 36 cells, never meet the case). Every
    backend's decoding follows this rule.
    """
    if 2 * window + 1 >= n:
        return np.arange(n)
    return np.arange(centre - window, centre + window + 1) % n


def population_vector_window(a: np.ndarray, window: int) -> np.ndarray:
    """Decode an N-D activity grid: argmax, +-window box with wrap, per-axis circular mean.

    Parameters
    ----------
    a : ndarray, shape (n_0, ..., n_{d-1})
    window : int
        Half-width of the box in cells (OpenRatSLAM ``pc_cells_to_avg``, default 3).

    Returns
    -------
    ndarray, shape (d,), float64
        Fractional index per axis, each in ``[0, n_k)``.
    """
    best = np.unravel_index(int(np.argmax(a)), a.shape)
    idx = [window_indices(int(b), window, n) for b, n in zip(best, a.shape)]
    box = a[np.ix_(*idx)].astype(np.float64)
    out = np.empty(a.ndim, dtype=np.float64)
    for ax, n in enumerate(a.shape):
        other = tuple(o for o in range(a.ndim) if o != ax)
        prof_win = box.sum(axis=other) if other else box
        profile = np.zeros(n, dtype=np.float64)
        profile[idx[ax]] = prof_win
        out[ax] = circular_mean_index(profile)
    return out
