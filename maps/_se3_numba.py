"""Numba kernel of the 6-DoF object-map relaxation; imported lazily by :mod:`maps.se3`.

Quaternions are scalar-last ``[x, y, z, w]`` as scipy's ``Rotation``. The kernel
needs the few quaternion operations below in compiled code, where scipy cannot be
called; ``tests/test_map_se3.py`` checks the kernel against the same update written
with ``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["relax_links_se3"]


@njit(cache=True)
def _mul(ax, ay, az, aw, bx, by, bz, bw):  # pragma: no cover - compiled
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


@njit(cache=True)
def _rotate(qx, qy, qz, qw, vx, vy, vz):  # pragma: no cover - compiled
    # v' = v + 2 w (u x v) + 2 u x (u x v)
    cx = qy * vz - qz * vy
    cy = qz * vx - qx * vz
    cz = qx * vy - qy * vx
    ccx = qy * cz - qz * cy
    ccy = qz * cx - qx * cz
    ccz = qx * cy - qy * cx
    return vx + 2.0 * (qw * cx + ccx), vy + 2.0 * (qw * cy + ccy), vz + 2.0 * (qw * cz + ccz)


@njit(cache=True)
def _log(x, y, z, w):  # pragma: no cover - compiled
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return 2.0 * x, 2.0 * y, 2.0 * z
    angle = 2.0 * math.atan2(s, w)
    k = angle / s
    return k * x, k * y, k * z


@njit(cache=True)
def _exp(rx, ry, rz):  # pragma: no cover - compiled
    a = math.sqrt(rx * rx + ry * ry + rz * rz)
    if a < 1e-12:
        n = math.sqrt(1.0 + 0.25 * a * a)
        return 0.5 * rx / n, 0.5 * ry / n, 0.5 * rz / n, 1.0 / n
    s = math.sin(0.5 * a) / a
    return s * rx, s * ry, s * rz, math.cos(0.5 * a)


@njit(cache=True)
def _normalise(pose, i):  # pragma: no cover - compiled
    n = math.sqrt(pose[i, 3] ** 2 + pose[i, 4] ** 2 + pose[i, 5] ** 2 + pose[i, 6] ** 2)
    for j in range(3, 7):
        pose[i, j] /= n


@njit(cache=True)
def relax_links_se3(
    order: np.ndarray, ends: np.ndarray, ldata: np.ndarray, pose: np.ndarray, c: float, n_updates: int, start: int
) -> int:  # pragma: no cover - compiled
    """Apply ``n_updates`` single-link corrections in place, Gauss-Seidel.

    Position: Eq 2.25 in 3-D with the link translation in the source frame,
    ``l = p_f + R(q_f) d``, ``p_f += c (p_t - l)``, ``p_t -= c (p_t - l)``.
    Orientation: with the residual rotation ``r = log((q_f dq)^-1 q_t)``,
    ``q_t <- q_t exp(-c r)`` and ``q_f <- q_f dq exp(c r) dq^-1`` (both ends move
    toward agreement by ``c``, the slerp of the SE(2) rule; ``c = 0.5`` closes the
    residual of one link exactly).

    Parameters
    ----------
    order : int64 (m,)
    ends : int64 (>= m, 2)
    ldata : float64 (>= m, >= 7)
        ``(dx, dy, dz m, qx, qy, qz, qw)`` per link.
    pose : float64 (>= n, 7)
        ``(x, y, z m, qx, qy, qz, qw)`` per experience, corrected in place.
    c : float
    n_updates, start : int

    Returns
    -------
    int
        Position in ``order`` after the last update.
    """
    n = order.shape[0]
    pos = start
    for _ in range(n_updates):
        k = order[pos]
        f = ends[k, 0]
        t = ends[k, 1]
        fx, fy, fz, fw = pose[f, 3], pose[f, 4], pose[f, 5], pose[f, 6]
        tx, ty, tz, tw = pose[t, 3], pose[t, 4], pose[t, 5], pose[t, 6]
        dx, dy, dz, dw = ldata[k, 3], ldata[k, 4], ldata[k, 5], ldata[k, 6]
        ox, oy, oz = _rotate(fx, fy, fz, fw, ldata[k, 0], ldata[k, 1], ldata[k, 2])
        for j, o in ((0, ox), (1, oy), (2, oz)):
            res = pose[t, j] - (pose[f, j] + o)
            pose[f, j] += res * c
            pose[t, j] -= res * c
        px, py, pz, pw = _mul(fx, fy, fz, fw, dx, dy, dz, dw)
        ex, ey, ez, ew = _mul(-px, -py, -pz, pw, tx, ty, tz, tw)
        rx, ry, rz = _log(ex, ey, ez, ew)
        mx, my, mz, mw = _exp(-c * rx, -c * ry, -c * rz)
        pose[t, 3], pose[t, 4], pose[t, 5], pose[t, 6] = _mul(tx, ty, tz, tw, mx, my, mz, mw)
        ax, ay, az, aw = _mul(px, py, pz, pw, -mx, -my, -mz, mw)  # q_f dq exp(c r)
        pose[f, 3], pose[f, 4], pose[f, 5], pose[f, 6] = _mul(ax, ay, az, aw, -dx, -dy, -dz, dw)
        _normalise(pose, f)
        _normalise(pose, t)
        pos += 1
        if pos == n:
            pos = 0
    return pos


@njit(cache=True)
def accumulate_se3(acc: np.ndarray, v: np.ndarray, w: np.ndarray, dt: float) -> None:  # pragma: no cover - compiled
    """Alg 6 and the frame-correct Eq 5.13 in place on ``acc = (d (3), q (4))``:
    ``d <- d + R(q) v dt``, then ``q <- q * exp(omega dt)`` (rotation vector ``omega dt``)."""
    qx, qy, qz, qw = acc[3], acc[4], acc[5], acc[6]
    ox, oy, oz = _rotate(qx, qy, qz, qw, v[0] * dt, v[1] * dt, v[2] * dt)
    acc[0] += ox
    acc[1] += oy
    acc[2] += oz
    ex, ey, ez, ew = _exp(w[0] * dt, w[1] * dt, w[2] * dt)
    rx, ry, rz, rw = _mul(qx, qy, qz, qw, ex, ey, ez, ew)
    n = math.sqrt(rx * rx + ry * ry + rz * rz + rw * rw)
    acc[3], acc[4], acc[5], acc[6] = rx / n, ry / n, rz / n, rw / n
