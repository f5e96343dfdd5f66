"""Numba kernel of OpenRatSLAM's template comparison (``LocalViewMatch::compare``); imported lazily."""

from __future__ import annotations

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["sad_compare"]


@njit(cache=True)
def sad_compare(
    view: np.ndarray, templates: np.ndarray, means: np.ndarray, view_mean: float, mean_tol: float, shift: int, step: int, panoramic: bool
) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """Smallest sum of absolute differences over templates and column offsets.

    Loops, summation order and tie-breaking follow the C++ exactly: templates
    in id order, offsets ascending, rows then columns, strict ``<``.

    Parameters
    ----------
    view : float64 (Y, X)
        Current view template.
    templates : float64 (T, Y, X)
        Stored templates.
    means : float64 (T,)
        Their means.
    view_mean : float
        Mean of ``view``.
    mean_tol : float
        Templates whose mean differs by more than this are skipped (threshold + 0.005).
    shift, step : int
        ``shift_match_blocks`` and ``step_match_blocks`` of the config.
    panoramic : bool
        Circular shifts over all columns instead of +-shift on the central columns.

    Returns
    -------
    (min_sad, template_index, offset)
        ``min_sad`` is ``inf`` when no template passed the mean filter.
    """
    n_t = templates.shape[0]
    n_y = view.shape[0]
    n_x = view.shape[1]
    mindiff = np.inf
    min_t = 0
    min_off = 0
    for t in range(n_t):
        if abs(view_mean - means[t]) > mean_tol:
            continue
        if panoramic:
            for off in range(0, n_x, step):
                cdiff = 0.0
                for r in range(n_y):
                    for c in range(n_x - off):
                        cdiff += abs(view[r, c] - templates[t, r, c + off])
                    if cdiff > mindiff:
                        break
                for r in range(n_y):
                    for c in range(off):
                        cdiff += abs(view[r, n_x - off + c] - templates[t, r, c])
                    if cdiff > mindiff:
                        break
                if cdiff < mindiff:
                    mindiff = cdiff
                    min_t = t
                    min_off = off
        else:
            width = n_x - 2 * shift
            for off in range(0, 2 * shift + 1, step):
                cdiff = 0.0
                for r in range(n_y):
                    for c in range(width):
                        cdiff += abs(view[r, shift + c] - templates[t, r, off + c])
                    if cdiff > mindiff:
                        break
                if cdiff < mindiff:
                    mindiff = cdiff
                    min_t = t
                    min_off = 0
    return mindiff, min_t, min_off


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
