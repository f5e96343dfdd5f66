"""Numba kernels of the 6-DoF object map (relaxation, Alg 6 accumulation, pose composition,
pose distances); imported lazily by :mod:`maps.se3` and :mod:`maps.object_map`.

Quaternions are scalar-last ``[x, y, z, w]`` as scipy's ``Rotation``. The kernels
need the few quaternion operations below in compiled code, where scipy cannot be
called (and where one scipy call costs more than a whole kernel call);
``tests/test_map_se3.py`` checks each kernel against the same operation written with
``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["relax_links_se3", "accumulate_se3", "compose_se3", "pose_distances_se3", "gate_views_se3"]


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


@njit(cache=True, inline="always")
def _slerp_step(fx, fy, fz, fw, tx, ty, tz, tw, dx, dy, dz, dw, c):  # pragma: no cover - compiled
    """New ``(q_f, q_t)`` of one link, any rate ``c``, before normalisation: ``q_f dq exp(c r) dq^-1``
    and ``q_t exp(-c r)``."""
    px, py, pz, pw = _mul(fx, fy, fz, fw, dx, dy, dz, dw)
    ex, ey, ez, ew = _mul(-px, -py, -pz, pw, tx, ty, tz, tw)
    rx, ry, rz = _log(ex, ey, ez, ew)
    mx, my, mz, mw = _exp(-c * rx, -c * ry, -c * rz)
    ax, ay, az, aw = _mul(px, py, pz, pw, -mx, -my, -mz, mw)  # q_f dq exp(c r)
    gx, gy, gz, gw = _mul(ax, ay, az, aw, -dx, -dy, -dz, dw)
    hx, hy, hz, hw = _mul(tx, ty, tz, tw, mx, my, mz, mw)
    return gx, gy, gz, gw, hx, hy, hz, hw


@njit(cache=True, inline="always")
def _midpoint_step(fx, fy, fz, fw, tx, ty, tz, tw, dx, dy, dz, dw):  # pragma: no cover - compiled
    """:func:`_slerp_step` at ``c = 0.5`` without transcendentals.

    With ``p = q_f dq`` and ``e = p^-1 q_t`` (sign chosen so that ``w >= 0``, as the
    logarithm does), ``q_t exp(-r / 2) = p e^(1/2)`` is the midpoint of the arc from
    ``q_t`` to ``sigma p`` (``sigma`` the sign of ``<p, q_t>``):
    ``(q_t + sigma p) / |q_t + sigma p|`` for unit ``p`` and ``q_t``, and
    ``q_f dq exp(r / 2) dq^-1 = sigma q_t' dq^-1``. The same numbers up to rounding
    (``tests/test_map_se3.py`` checks both forms against scipy to 1e-12).
    """
    px, py, pz, pw = _mul(fx, fy, fz, fw, dx, dy, dz, dw)
    dot = px * tx + py * ty + pz * tz + pw * tw
    # |q_t +- p|^2 from the dot product at hand: the sums and the norm are computed side by side
    # (the chain of one link to the next is what bounds the relaxation's speed)
    n2 = (tx * tx + ty * ty + tz * tz + tw * tw) + (px * px + py * py + pz * pz + pw * pw) + 2.0 * abs(dot)
    if dot >= 0.0:
        sg = 1.0
        hx, hy, hz, hw = tx + px, ty + py, tz + pz, tw + pw
    else:
        sg = -1.0
        hx, hy, hz, hw = tx - px, ty - py, tz - pz, tw - pw
    k = 1.0 / math.sqrt(n2)
    hx, hy, hz, hw = hx * k, hy * k, hz * k, hw * k
    gx, gy, gz, gw = _mul(hx, hy, hz, hw, -dx, -dy, -dz, dw)
    k = sg / math.sqrt(gx * gx + gy * gy + gz * gz + gw * gw)
    return gx * k, gy * k, gz * k, gw * k, hx, hy, hz, hw


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
    residual of one link exactly). At ``c = 0.5`` (the thesis' rate) the slerp is the
    normalised sum of two quaternions (:func:`_midpoint_step`): one square root per end
    instead of ``atan2``, ``sin`` and ``cos``.

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
    half = c == 0.5
    for _ in range(n_updates):
        k = order[pos]
        f = ends[k, 0]
        t = ends[k, 1]
        fx, fy, fz, fw = pose[f, 3], pose[f, 4], pose[f, 5], pose[f, 6]
        tx, ty, tz, tw = pose[t, 3], pose[t, 4], pose[t, 5], pose[t, 6]
        dx, dy, dz, dw = ldata[k, 3], ldata[k, 4], ldata[k, 5], ldata[k, 6]
        ox, oy, oz = _rotate(fx, fy, fz, fw, ldata[k, 0], ldata[k, 1], ldata[k, 2])
        rx = pose[t, 0] - (pose[f, 0] + ox)
        ry = pose[t, 1] - (pose[f, 1] + oy)
        rz = pose[t, 2] - (pose[f, 2] + oz)
        pose[f, 0] += rx * c
        pose[f, 1] += ry * c
        pose[f, 2] += rz * c
        pose[t, 0] -= rx * c
        pose[t, 1] -= ry * c
        pose[t, 2] -= rz * c
        if half:
            q = _midpoint_step(fx, fy, fz, fw, tx, ty, tz, tw, dx, dy, dz, dw)
            pose[f, 3], pose[f, 4], pose[f, 5], pose[f, 6] = q[0], q[1], q[2], q[3]
            pose[t, 3], pose[t, 4], pose[t, 5], pose[t, 6] = q[4], q[5], q[6], q[7]
        else:
            q = _slerp_step(fx, fy, fz, fw, tx, ty, tz, tw, dx, dy, dz, dw, c)
            pose[t, 3], pose[t, 4], pose[t, 5], pose[t, 6] = q[4], q[5], q[6], q[7]
            pose[f, 3], pose[f, 4], pose[f, 5], pose[f, 6] = q[0], q[1], q[2], q[3]
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


@njit(cache=True)
def compose_se3(base: np.ndarray, acc: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out = (p_e + R(q_e) d, q_e * q)`` for a pose ``base = (p_e, q_e)`` and ``acc = (d, q)``, (7,) each.

    Both quaternions are normalised first and the product after, as scipy's ``Rotation``
    does (``tests/test_map_se3.py`` checks this against it)."""
    n = math.sqrt(base[3] * base[3] + base[4] * base[4] + base[5] * base[5] + base[6] * base[6])
    bx, by, bz, bw = base[3] / n, base[4] / n, base[5] / n, base[6] / n
    n = math.sqrt(acc[3] * acc[3] + acc[4] * acc[4] + acc[5] * acc[5] + acc[6] * acc[6])
    ax, ay, az, aw = acc[3] / n, acc[4] / n, acc[5] / n, acc[6] / n
    ox, oy, oz = _rotate(bx, by, bz, bw, acc[0], acc[1], acc[2])
    out[0] = base[0] + ox
    out[1] = base[1] + oy
    out[2] = base[2] + oz
    qx, qy, qz, qw = _mul(bx, by, bz, bw, ax, ay, az, aw)
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    out[3], out[4], out[5], out[6] = qx / n, qy / n, qz / n, qw / n


@njit(cache=True)
def pose_distances_se3(poses: np.ndarray, n: int, p: np.ndarray, dist: np.ndarray, angle: np.ndarray) -> None:  # pragma: no cover
    """Euclidean distance (m) and rotation angle ``2 acos |<q_i, q>|`` (rad) of the first ``n`` rows of
    ``poses`` (>= n, 7) to the pose ``p`` (7,), into ``dist`` and ``angle`` (n,)."""
    for i in range(n):
        dx = poses[i, 0] - p[0]
        dy = poses[i, 1] - p[1]
        dz = poses[i, 2] - p[2]
        dist[i] = math.sqrt(dx * dx + dy * dy + dz * dz)
        dot = abs(poses[i, 3] * p[3] + poses[i, 4] * p[4] + poses[i, 5] * p[5] + poses[i, 6] * p[6])
        angle[i] = 2.0 * math.acos(min(dot, 1.0))


@njit(cache=True, error_model="numpy")
def gate_views_se3(
    poses: np.ndarray, n: int, p: np.ndarray, gate_m: np.ndarray, gate_rad: np.ndarray, views: np.ndarray,
    consistent: np.ndarray, best: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """For each of the first ``n`` experiences within ``gate_m[i]`` m and ``gate_rad[i]`` rad of ``p``
    (the distances of :func:`pose_distances_se3`): ``consistent[v] = True`` and
    ``best[v] = min(best[v], d / gate_m[i] + angle / gate_rad[i])`` for its view ``v = views[i]``
    (``numpy.minimum``: NaN propagates). The angle is computed only past the position gate.

    Returns 0, or (with the outputs incomplete) 1 for a gate that is negative or NaN and 2 for a
    view beyond ``consistent``."""
    nv = consistent.shape[0]
    for i in range(n):
        if not (gate_m[i] >= 0.0 and gate_rad[i] >= 0.0):
            return 1
        v = views[i]
        if v >= nv:
            return 2
        dx = poses[i, 0] - p[0]
        dy = poses[i, 1] - p[1]
        dz = poses[i, 2] - p[2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not dist <= gate_m[i]:
            continue
        dot = abs(poses[i, 3] * p[3] + poses[i, 4] * p[4] + poses[i, 5] * p[5] + poses[i, 6] * p[6])
        angle = 2.0 * math.acos(min(dot, 1.0))
        if not angle <= gate_rad[i]:
            continue
        c = dist / gate_m[i] + angle / gate_rad[i]
        b = best[v]
        if c < b or c != c:
            best[v] = c
        consistent[v] = True
    return 0


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
