"""Numba kernels of the surface matcher's particle filters; imported by ``maps.surface_match``.

Each kernel does for every hypothesis what :class:`maps.surface_match.SurfaceMatcher`
describes, in one pass without temporaries: :func:`likelihoods` places a whisk's contacts
by every hypothesis of every object in question, reads its distance to the object's stored surface
from the object's signed-distance grid (:mod:`maps.surface_field`) and returns the log
likelihood and the residuals; :func:`field_distance` is that read for given points; :func:`move`
applies one odometry step with the noise undone; :func:`resample_in_place` is systematic resampling.
``tests/test_surface_match.py`` holds them to the numpy expressions they replace.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["field_distance", "likelihoods", "move", "resample_in_place"]


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


@njit(cache=True, inline="always")
def _likelihoods_row(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray,
                      start: np.ndarray, values: np.ndarray, cell: float, sigma: float, outlier: float, cap: float,
                      rows: np.ndarray, ll: np.ndarray, res: np.ndarray, i: int) -> None:  # pragma: no cover - compiled
    """Fill ``ll[i]`` (N,) and ``res[i]`` (N, m) for the object ``rows[i]`` (:func:`likelihoods`)."""
    k = rows[i]
    N, m = R.shape[1], pts.shape[0]
    inv2s2 = 0.5 / (sigma * sigma)
    at_cap = math.log(outlier + math.exp(-cap * cap * inv2s2))  # the same expression for r == cap, evaluated once
    for n in range(N):
        acc = 0.0
        for j in range(m):
            px, py, pz = pts[j, 0], pts[j, 1], pts[j, 2]
            x = R[k, n, 0, 0] * px + R[k, n, 0, 1] * py + R[k, n, 0, 2] * pz + t[k, n, 0]
            y = R[k, n, 1, 0] * px + R[k, n, 1, 1] * py + R[k, n, 1, 2] * pz + t[k, n, 1]
            z = R[k, n, 2, 0] * px + R[k, n, 2, 1] * py + R[k, n, 2, 2] * pz + t[k, n, 2]
            r = _field_at(x, y, z, k, lo, shape, start, values, cell, cap)
            if r == cap:  # off the grid or capped: the common case on the wrong objects
                acc += at_cap
            else:
                acc += math.log(outlier + math.exp(-r * r * inv2s2))
            res[i, n, j] = r
        ll[i, n] = acc


@njit(cache=True)
def likelihoods(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                values: np.ndarray, cell: float, sigma: float, outlier: float, cap: float,
                rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Log likelihood (len(rows), N) of the contacts ``pts`` (m, 3) under the hypotheses ``R`` (K, N, 3, 3),
    ``t`` (K, N, 3) of the objects ``rows``, and each contact's residual (len(rows), N, m).

    A contact's residual ``r`` is its distance to the object's stored surface (the grid's
    ``|f|``, at most ``cap``); its likelihood is ``outlier + exp(-r^2 / (2 sigma^2))``; a
    hypothesis' log likelihood is the sum of its contacts' logarithms in contact order.
    """
    ll = np.empty((rows.shape[0], R.shape[1]))
    res = np.empty((rows.shape[0], R.shape[1], pts.shape[0]))
    for i in range(rows.shape[0]):
        _likelihoods_row(R, t, pts, lo, shape, start, values, cell, sigma, outlier, cap, rows, ll, res, i)
    return ll, res


@njit(cache=True)
def move(R: np.ndarray, t: np.ndarray, step: np.ndarray, delta: np.ndarray, cos: np.ndarray, sin: np.ndarray,
         scale: np.ndarray, rows: np.ndarray) -> None:  # pragma: no cover - compiled
    """In place: ``t += R @ (delta * scale)``, then ``R = R @ step @ E.T`` for every hypothesis of the objects ``rows``.

    ``R`` (K, N, 3, 3), ``t`` (K, N, 3), ``step`` (3, 3), ``delta`` (3,); per object in
    ``rows``: ``scale`` (len(rows), N) and the cosines and sines ``cos``, ``sin``
    (len(rows), N, 3) of the extrinsic x-y-z Euler angles of ``E``
    (``maps.surface_match._euler_xyz``, the same products in the same order); ``E.T`` undoes it.
    """
    N = R.shape[1]
    tmp = np.empty((3, 3))
    e = np.empty((3, 3))
    for i in range(rows.shape[0]):
        k = rows[i]
        for n in range(N):
            cx, cy, cz = cos[i, n, 0], cos[i, n, 1], cos[i, n, 2]
            sx, sy, sz = sin[i, n, 0], sin[i, n, 1], sin[i, n, 2]
            e[0, 0] = cy * cz
            e[0, 1] = sx * sy * cz - cx * sz
            e[0, 2] = cx * sy * cz + sx * sz
            e[1, 0] = cy * sz
            e[1, 1] = sx * sy * sz + cx * cz
            e[1, 2] = cx * sy * sz - sx * cz
            e[2, 0] = -sy
            e[2, 1] = sx * cy
            e[2, 2] = cx * cy
            s = scale[i, n]
            for a in range(3):
                t[k, n, a] += (R[k, n, a, 0] * delta[0] + R[k, n, a, 1] * delta[1] + R[k, n, a, 2] * delta[2]) * s
            for a in range(3):
                for b in range(3):
                    tmp[a, b] = R[k, n, a, 0] * step[0, b] + R[k, n, a, 1] * step[1, b] + R[k, n, a, 2] * step[2, b]
            for a in range(3):
                for b in range(3):
                    R[k, n, a, b] = tmp[a, 0] * e[b, 0] + tmp[a, 1] * e[b, 1] + tmp[a, 2] * e[b, 2]


@njit(cache=True)
def resample_in_place(R: np.ndarray, t: np.ndarray, w: np.ndarray, low: np.ndarray, rows: np.ndarray,
                      offsets: np.ndarray) -> None:  # pragma: no cover - compiled
    """Systematic resampling, in place, of the hypotheses ``R`` (K, N, 3, 3), ``t`` (K, N, 3) of the objects
    ``rows[low]`` by their weights ``w[low]`` (``w`` (len(rows), N)), the comb of object ``k`` offset by
    ``offsets[k]`` in [0, 1): hypothesis ``n`` becomes the first ``i`` whose cumulative weight reaches
    ``(offsets[k] + n) / N``."""
    N = R.shape[1]
    R_old = np.empty((N, 3, 3))
    t_old = np.empty((N, 3))
    for q in range(low.shape[0]):
        i_ = low[q]
        k = rows[i_]
        R_old[:] = R[k]
        t_old[:] = t[k]
        c = w[i_, 0]
        i = 0
        for n in range(N):
            u = (offsets[k] + n) / N
            while c < u and i < N - 1:
                i += 1
                c += w[i_, i]
            R[k, n] = R_old[i]
            t[k, n] = t_old[i]


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
