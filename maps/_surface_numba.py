"""Numba kernels of the surface matcher's particle filters; imported by ``maps.surface_match``.

Each kernel does for every hypothesis what :class:`maps.surface_match.SurfaceMatcher`
describes, in one pass without temporaries: :func:`likelihoods` places a whisk's contacts
by every hypothesis of every object, looks up the nearest stored point on the object's
grid and returns the log likelihood and the capped squared residuals; :func:`move`
applies one odometry step with the noise undone; :func:`resample` is systematic resampling.
``tests/test_surface_match.py`` holds them to the numpy expressions they replace.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["likelihoods", "move", "resample"]


@njit(cache=True)
def likelihoods(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                table: np.ndarray, cell: float, points: np.ndarray, normals: np.ndarray, gate: float,
                lateral_weight: float, sigma: float, outlier: float, cap: float,
                rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Log likelihood (K, N) of the contacts ``pts`` (m, 3) under hypotheses ``R`` (K, N, 3, 3), ``t`` (K, N, 3),
    and the sum of the contacts' squared residuals capped at ``cap`` (K, N), for the objects ``rows``
    (the other rows are 0).

    A contact's residual is ``hypot(normal, lateral_weight * lateral)`` to its nearest stored point of
    the object (within ``gate``; beyond, the contact is an outlier: likelihood ``outlier``, residual
    ``cap``); its likelihood is ``outlier + exp(-r^2 / (2 sigma^2))``.
    """
    K, N = R.shape[0], R.shape[1]
    m = pts.shape[0]
    ll = np.zeros((K, N))
    sq = np.zeros((K, N))
    inv2s2 = 0.5 / (sigma * sigma)
    log_out = math.log(outlier)
    for r_ in range(rows.shape[0]):
        k = rows[r_]
        sx, sy, sz = shape[k, 0], shape[k, 1], shape[k, 2]
        for n in range(N):
            acc = 0.0
            acc_sq = 0.0
            for j in range(m):
                px, py, pz = pts[j, 0], pts[j, 1], pts[j, 2]
                x = R[k, n, 0, 0] * px + R[k, n, 0, 1] * py + R[k, n, 0, 2] * pz + t[k, n, 0]
                y = R[k, n, 1, 0] * px + R[k, n, 1, 1] * py + R[k, n, 1, 2] * pz + t[k, n, 1]
                z = R[k, n, 2, 0] * px + R[k, n, 2, 1] * py + R[k, n, 2, 2] * pz + t[k, n, 2]
                i = int(math.floor((x - lo[k, 0]) / cell + 0.5))
                jj = int(math.floor((y - lo[k, 1]) / cell + 0.5))
                kk = int(math.floor((z - lo[k, 2]) / cell + 0.5))
                idx = -1
                if 0 <= i < sx and 0 <= jj < sy and 0 <= kk < sz:
                    idx = table[start[k] + (i * sy + jj) * sz + kk]
                r = math.inf
                if idx >= 0:
                    dx, dy, dz = x - points[idx, 0], y - points[idx, 1], z - points[idx, 2]
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 <= gate * gate:
                        nn = abs(dx * normals[idx, 0] + dy * normals[idx, 1] + dz * normals[idx, 2])
                        lat2 = max(d2 - nn * nn, 0.0)
                        r = math.sqrt(nn * nn + lateral_weight * lateral_weight * lat2)
                if r < math.inf:
                    acc += math.log(outlier + math.exp(-r * r * inv2s2))
                    rc = min(r, cap)
                    acc_sq += rc * rc
                else:
                    acc += log_out
                    acc_sq += cap * cap
            ll[k, n] = acc
            sq[k, n] = acc_sq
    return ll, sq


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
