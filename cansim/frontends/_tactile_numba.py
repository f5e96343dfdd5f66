"""Compiled Eq 3.1 scan: the best match of one tactile image among stored templates."""

from __future__ import annotations

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

#: sqrt(k) for every possible |a - b| of two 8-bit pixels
SQRT_LEVELS = np.sqrt(np.arange(256, dtype=np.float64))


@njit(cache=True, fastmath=False, nogil=True)
def best_tactile_match(data, n, image, table):
    """Smallest ``S = sum sqrt(|t - image|)`` over the first ``n`` rows of ``data``.

    Parameters
    ----------
    data : float64 (capacity, k)
        Stored templates, flattened to k pixels (integer values 0-255).
    image : float64 (k,)
    table : float64 (256,)
        :data:`SQRT_LEVELS`.

    Returns
    -------
    (best, err) : (int, float)
        First template with the smallest S (ties -> lowest id) and its S.
    """
    best = 0
    err = np.inf
    k = image.shape[0]
    for r in range(n):
        s = 0.0
        for j in range(k):
            d = data[r, j] - image[j]
            s += table[int(d if d >= 0.0 else -d)]
        if s < err:
            err = s
            best = r
    return best, err


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
