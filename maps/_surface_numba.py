"""Numba kernels of the surface matcher's particle filters; imported by ``maps.surface_match``.

Each kernel does for every hypothesis what :class:`maps.surface_match.SurfaceMatcher`
describes, in one pass without temporaries: :func:`likelihoods` places a whisk's contacts
by every hypothesis of every object, reads its distance to the object's stored surface
from the object's signed-distance grid (:mod:`maps.surface_field`) and returns the log
likelihood and the residuals; :func:`field_distance` is that read for given points; :func:`move`
applies one odometry step with the noise undone; :func:`resample` is systematic resampling.
``tests/test_surface_match.py`` holds them to the numpy expressions they replace.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["field_distance", "likelihoods", "move", "resample"]


@njit(cache=True, inline="always")
def _field_at(x: float, y: float, z: float, k: int, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
              values: np.ndarray, cell: float, cap: float) -> float:  # pragma: no cover - compiled
    """``|f|`` of object ``k``'s grid at (x, y, z), trilinear; ``cap`` off the grid (never more than ``cap``)."""
    u = (x - lo[k, 0]) / cell
    v = (y - lo[k, 1]) / cell
    w = (z - lo[k, 2]) / cell
    i = int(math.floor(u))
    j = int(math.floor(v))
    l_ = int(math.floor(w))
    sx, sy, sz = shape[k, 0], shape[k, 1], shape[k, 2]
    if i < 0 or j < 0 or l_ < 0 or i >= sx - 1 or j >= sy - 1 or l_ >= sz - 1:
        return cap
    fu, fv, fw = u - i, v - j, w - l_
    base = start[k] + (i * sy + j) * sz + l_
    c00 = values[base] * (1.0 - fw) + values[base + 1] * fw
    c01 = values[base + sz] * (1.0 - fw) + values[base + sz + 1] * fw
    c10 = values[base + sy * sz] * (1.0 - fw) + values[base + sy * sz + 1] * fw
    c11 = values[base + sy * sz + sz] * (1.0 - fw) + values[base + sy * sz + sz + 1] * fw
    f = (c00 * (1.0 - fv) + c01 * fv) * (1.0 - fu) + (c10 * (1.0 - fv) + c11 * fv) * fu
    return min(abs(f), cap)


@njit(cache=True)
def field_distance(x: np.ndarray, obj: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                   values: np.ndarray, cell: float, cap: float) -> np.ndarray:  # pragma: no cover - compiled
    """``|f|`` (n,) of points ``x`` (n, 3) on the grids of objects ``obj`` (n,) (:mod:`maps.surface_field`)."""
    out = np.empty(x.shape[0])
    for n in range(x.shape[0]):
        out[n] = _field_at(x[n, 0], x[n, 1], x[n, 2], obj[n], lo, shape, start, values, cell, cap)
    return out


@njit(cache=True)
def likelihoods(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                values: np.ndarray, cell: float, sigma: float, outlier: float, cap: float,
                rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Log likelihood (K, N) of the contacts ``pts`` (m, 3) under hypotheses ``R`` (K, N, 3, 3), ``t`` (K, N, 3),
    and each contact's residual (K, N, m), for the objects ``rows`` (the other rows are 0).

    A contact's residual ``r`` is its distance to the object's stored surface (the grid's
    ``|f|``, at most ``cap``); its likelihood is ``outlier + exp(-r^2 / (2 sigma^2))``.
    """
    K, N = R.shape[0], R.shape[1]
    m = pts.shape[0]
    ll = np.zeros((K, N))
    res = np.zeros((K, N, m))
    inv2s2 = 0.5 / (sigma * sigma)
    for r_ in range(rows.shape[0]):
        k = rows[r_]
        for n in range(N):
            acc = 0.0
            for j in range(m):
                px, py, pz = pts[j, 0], pts[j, 1], pts[j, 2]
                x = R[k, n, 0, 0] * px + R[k, n, 0, 1] * py + R[k, n, 0, 2] * pz + t[k, n, 0]
                y = R[k, n, 1, 0] * px + R[k, n, 1, 1] * py + R[k, n, 1, 2] * pz + t[k, n, 1]
                z = R[k, n, 2, 0] * px + R[k, n, 2, 1] * py + R[k, n, 2, 2] * pz + t[k, n, 2]
                r = _field_at(x, y, z, k, lo, shape, start, values, cell, cap)
                acc += math.log(outlier + math.exp(-r * r * inv2s2))
                res[k, n, j] = r
            ll[k, n] = acc
    return ll, res


@njit(cache=True)
def move(R: np.ndarray, t: np.ndarray, step: np.ndarray, delta: np.ndarray, undo: np.ndarray,
         scale: np.ndarray, rows: np.ndarray) -> None:  # pragma: no cover - compiled
    """In place: ``t += R @ (delta * scale)``, then ``R = R @ step @ undo`` for every hypothesis of the objects ``rows``.

    ``R`` (K, N, 3, 3), ``t`` (K, N, 3), ``step`` (3, 3), ``delta`` (3,), ``undo`` (K, N, 3, 3),
    ``scale`` (K, N).
    """
    N = R.shape[1]
    tmp = np.empty((3, 3))
    for r_ in range(rows.shape[0]):
        k = rows[r_]
        for n in range(N):
            s = scale[k, n]
            for a in range(3):
                t[k, n, a] += (R[k, n, a, 0] * delta[0] + R[k, n, a, 1] * delta[1] + R[k, n, a, 2] * delta[2]) * s
            for a in range(3):
                for b in range(3):
                    tmp[a, b] = R[k, n, a, 0] * step[0, b] + R[k, n, a, 1] * step[1, b] + R[k, n, a, 2] * step[2, b]
            for a in range(3):
                for b in range(3):
                    R[k, n, a, b] = tmp[a, 0] * undo[k, n, 0, b] + tmp[a, 1] * undo[k, n, 1, b] + tmp[a, 2] * undo[k, n, 2, b]


@njit(cache=True)
def resample(w: np.ndarray, offsets: np.ndarray, rows: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Systematic resampling indices (len(rows), N) of the rows ``rows`` of the weights ``w`` (K, N),
    each row's comb offset by ``offsets[row]`` in [0, 1)."""
    N = w.shape[1]
    out = np.empty((rows.shape[0], N), dtype=np.int64)
    for r in range(rows.shape[0]):
        k = rows[r]
        c = w[k, 0]
        i = 0
        for n in range(N):
            u = (offsets[k] + n) / N
            while c < u and i < N - 1:
                i += 1
                c += w[k, i]
            out[r, n] = i
    return out


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
