"""Compiled kernels of the two region distances (Eq 2.45 chi-squared, Eq 5.3 NMSE).

:func:`whisker_io.features.pfh.chi_squared` and :func:`whisker_io.features.sda.nmse`
validate their input and then call the row kernels; the whisk front end keeps its
stored (already validated) regions column-wise, one row per bin or whisker, and calls
the column kernels directly, so one whisk is compared with 1,000 stored regions in
tens of microseconds.

The column kernels run along the stored regions for one bin at a time: the loops over
regions are contiguous and branch-free, so they vectorise, and every region still sums
its bins in bin order from 0.0, as a loop over the bins of each region does (a
skipped bin adds 0.0, which leaves the non-negative sum unchanged): the row kernels
are the column kernels on the transposed input, and both give the same bits as a
plain per-row loop. The divisions bound the speed (about two cycles per division).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["chi2_rows", "nmse_rows", "chi2_columns", "nmse_columns"]

_OPTS = dict(cache=True, error_model="numpy")  # IEEE division (no zero checks): the loops vectorise


@njit(**_OPTS)
def chi2_columns(q: np.ndarray, vt: np.ndarray, n: int) -> np.ndarray:  # pragma: no cover - compiled
    """``sum_i (q_i - v_ri)^2 / (q_i + v_ri)`` for the first ``n`` columns ``r`` of ``vt`` (B, >= n),
    bins with a zero sum skipped; ``q`` (B,) and ``vt`` non-negative."""
    out = np.zeros(n)
    for i in range(vt.shape[0]):
        qi = q[i]
        col = vt[i, :n]
        for r in range(n):
            s = qi + col[r]
            d = qi - col[r]
            out[r] += d * d / s if s > 0.0 else 0.0
    return out


@njit(**_OPTS)
def nmse_columns(
    x: np.ndarray, yt: np.ndarray, mask_x: np.ndarray, mask_yt: np.ndarray, n: int, masked: bool
) -> np.ndarray:  # pragma: no cover - compiled
    """``MSE(x, y_r) / MSE(x, 0)`` for the first ``n`` columns ``y_r`` of ``yt`` (N, >= n), over
    entries valid in ``mask_x`` (N,) and ``mask_yt`` (N, >= n) (every entry when ``masked`` is
    False), computed on the pair scaled by its largest magnitude (no overflow); inf when no
    entry is valid or ``x`` is all zero there while ``y_r`` is not, 0 when both are."""
    nb = yt.shape[0]
    scale = np.zeros(n)
    count = np.zeros(n, np.int64)
    for i in range(nb):
        if masked and not mask_x[i]:
            continue
        ax = abs(x[i])
        col = yt[i, :n]
        if masked:
            valid = mask_yt[i, :n]
            for r in range(n):
                if valid[r]:
                    count[r] += 1
                    scale[r] = max(scale[r], max(ax, abs(col[r])))
        else:
            for r in range(n):
                count[r] += 1
                scale[r] = max(scale[r], max(ax, abs(col[r])))
    err = np.zeros(n)
    power = np.zeros(n)
    for i in range(nb):
        if masked and not mask_x[i]:
            continue
        xi = x[i]
        col = yt[i, :n]
        if masked:
            valid = mask_yt[i, :n]
            for r in range(n):
                xs = xi / scale[r]
                d = xs - col[r] / scale[r]
                err[r] += d * d if valid[r] else 0.0
                power[r] += xs * xs if valid[r] else 0.0
        else:
            for r in range(n):
                xs = xi / scale[r]
                d = xs - col[r] / scale[r]
                err[r] += d * d
                power[r] += xs * xs
    out = np.empty(n)
    for r in range(n):
        if count[r] == 0:
            out[r] = math.inf
        elif scale[r] == 0.0:
            out[r] = 0.0
        else:
            e = err[r] / count[r]
            p = power[r] / count[r]
            if p > 0.0:
                out[r] = e / p
            else:
                out[r] = 0.0 if e == 0.0 else math.inf
    return out


@njit(**_OPTS)
def chi2_rows(q: np.ndarray, v: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """:func:`chi2_columns` per row ``r`` of ``v`` (m, B)."""
    return chi2_columns(q, np.ascontiguousarray(v.T), v.shape[0])


@njit(**_OPTS)
def nmse_rows(x: np.ndarray, y: np.ndarray, mask_x: np.ndarray, mask_y: np.ndarray) -> np.ndarray:  # pragma: no cover
    """:func:`nmse_columns` per row of ``y`` (m, N) with the masks ``mask_x`` (N,) and ``mask_y`` (m, N)."""
    return nmse_columns(x, np.ascontiguousarray(y.T), mask_x, np.ascontiguousarray(mask_y.T), y.shape[0], np.bool_(True))


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
