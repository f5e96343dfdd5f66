"""Numba kernels of the surface matcher's particle filters; imported by ``maps.surface_match``.

Each kernel does for every hypothesis what :class:`maps.surface_match.SurfaceMatcher`
describes, in one pass without temporaries: :func:`likelihoods` places a whisk's contacts
by every hypothesis of every object in question, reads its distance to the object's stored surface
from the object's signed-distance grid (:mod:`maps.surface_field`) and returns the log
likelihood and the residuals; :func:`field_distance` is that read for given points; :func:`move`
applies one odometry step with the noise undone; :func:`resample_in_place` is systematic resampling;
:func:`refine` is the registration-refined proposal (Levenberg-Marquardt steps of every hypothesis on
its contacts' signed distances, read with the grid's trilinear gradient, and Laplace weights).
``tests/test_surface_match.py`` holds them to the numpy expressions they replace
(``tests/test_surface_match_refine.py`` the refinement). A change made for speed must leave every
output bit as it was: ``bench/surface_kernels_equal.py`` replays whisks through the matcher with a
reference copy of this module and with this one and compares every output with ``np.array_equal``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["field_distance", "likelihoods", "move", "refine", "refine_chunks", "resample_in_place"]


@njit(cache=True, inline="always")
def _cell_of(x: float, y: float, z: float, k: int, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
             cell: float) -> tuple[int, float, float, float]:  # pragma: no cover - compiled
    """The flat index of the grid corner below (x, y, z) on object ``k``'s grid and the fractions along each axis;
    index -1 when the point's cell is not inside the grid."""
    u = (x - lo[k, 0]) / cell
    v = (y - lo[k, 1]) / cell
    w = (z - lo[k, 2]) / cell
    i = int(math.floor(u))
    j = int(math.floor(v))
    l_ = int(math.floor(w))
    sx, sy, sz = shape[k, 0], shape[k, 1], shape[k, 2]
    if i < 0 or j < 0 or l_ < 0 or i >= sx - 1 or j >= sy - 1 or l_ >= sz - 1:
        return -1, 0.0, 0.0, 0.0
    return start[k] + (i * sy + j) * sz + l_, u - i, v - j, w - l_


@njit(cache=True, inline="always")
def _field_at(x: float, y: float, z: float, k: int, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
              values: np.ndarray, cell: float, cap: float) -> float:  # pragma: no cover - compiled
    """``|f|`` of object ``k``'s grid at (x, y, z), trilinear; ``cap`` off the grid (never more than ``cap``).

    The value of :func:`_field_grad` (inlined: the gradient it does not use is not computed)."""
    f, ok, _, _, _ = _field_grad(x, y, z, k, lo, shape, start, values, cell)
    return min(abs(f), cap) if ok else cap


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


@njit(cache=True, parallel=True)
def likelihoods(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                values: np.ndarray, cell: float, sigma: float, outlier: float, cap: float,
                rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Log likelihood (len(rows), N) of the contacts ``pts`` (m, 3) under the hypotheses ``R`` (K, N, 3, 3),
    ``t`` (K, N, 3) of the objects ``rows``, and each contact's residual (len(rows), N, m).

    A contact's residual ``r`` is its distance to the object's stored surface (the grid's
    ``|f|``, at most ``cap``); its likelihood is ``outlier + exp(-r^2 / (2 sigma^2))``; a
    hypothesis' log likelihood is the sum of its contacts' logarithms in contact order.
    The objects are shared among numba's threads (each is computed alone: the same bits on
    any number of threads).
    """
    ll = np.empty((rows.shape[0], R.shape[1]))
    res = np.empty((rows.shape[0], R.shape[1], pts.shape[0]))
    for i in prange(rows.shape[0]):
        _likelihoods_row(R, t, pts, lo, shape, start, values, cell, sigma, outlier, cap, rows, ll, res, i)
    return ll, res


@njit(cache=True, inline="always")
def _field_grad(x: float, y: float, z: float, k: int, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                values: np.ndarray, cell: float) -> tuple[float, bool, float, float, float]:  # pragma: no cover - compiled
    """Signed ``f`` of object ``k``'s grid at (x, y, z) and its gradient (gx, gy, gz), trilinear: (f, True, gx, gy, gz);
    (0, False, 0, 0, 0) off the grid."""
    base, fu, fv, fw = _cell_of(x, y, z, k, lo, shape, start, cell)
    if base < 0:
        return 0.0, False, 0.0, 0.0, 0.0
    sy, sz = shape[k, 1], shape[k, 2]
    a0, a1 = values[base], values[base + 1]
    b0, b1 = values[base + sz], values[base + sz + 1]
    c0, c1 = values[base + sy * sz], values[base + sy * sz + 1]
    d0, d1 = values[base + sy * sz + sz], values[base + sy * sz + sz + 1]
    c00 = a0 * (1.0 - fw) + a1 * fw
    c01 = b0 * (1.0 - fw) + b1 * fw
    c10 = c0 * (1.0 - fw) + c1 * fw
    c11 = d0 * (1.0 - fw) + d1 * fw
    lo_u = c00 * (1.0 - fv) + c01 * fv
    hi_u = c10 * (1.0 - fv) + c11 * fv
    gx = (hi_u - lo_u) / cell
    gy = ((c01 - c00) * (1.0 - fu) + (c11 - c10) * fu) / cell
    gz = (((a1 - a0) * (1.0 - fv) + (b1 - b0) * fv) * (1.0 - fu) + ((c1 - c0) * (1.0 - fv) + (d1 - d0) * fv) * fu) / cell
    return lo_u * (1.0 - fu) + hi_u * fu, True, gx, gy, gz


@njit(cache=True, inline="always")
def _fit_pass(R: np.ndarray, t: np.ndarray, pts: np.ndarray, k: int, lo: np.ndarray, shape: np.ndarray,
              start: np.ndarray, values: np.ndarray, cell: float, inv2s2: float, outlier: float, cap: float,
              at_cap: float, sd: np.ndarray, H: np.ndarray, gv: np.ndarray,
              res_out: np.ndarray) -> tuple[float, int]:  # pragma: no cover - compiled
    """Log likelihood of the contacts at the pose ``R`` (3, 3), ``t`` (3,) and how many of them are on the grid
    and under the cap (the others add nothing to the system); fills the whitened Gauss-Newton system ``H`` (6, 6)
    (without the prior's identity) and gradient ``gv`` (6,) of the robust cost, and the contacts' residuals
    ``res_out`` (m,). The sums run in local scalars, contact by contact."""
    used = 0
    g0 = g1 = g2 = g3 = g4 = g5 = 0.0
    h00 = h10 = h11 = h20 = h21 = h22 = h30 = h31 = h32 = h33 = 0.0
    h40 = h41 = h42 = h43 = h44 = h50 = h51 = h52 = h53 = h54 = h55 = 0.0
    s0, s1, s2, s3, s4, s5 = sd[0], sd[1], sd[2], sd[3], sd[4], sd[5]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1], R[2, 2]
    t0, t1, t2 = t[0], t[1], t[2]
    acc = 0.0
    for j in range(pts.shape[0]):
        px, py, pz = pts[j, 0], pts[j, 1], pts[j, 2]
        x = r00 * px + r01 * py + r02 * pz + t0
        y = r10 * px + r11 * py + r12 * pz + t1
        z = r20 * px + r21 * py + r22 * pz + t2
        f, ok, gx, gy, gz = _field_grad(x, y, z, k, lo, shape, start, values, cell)
        r = abs(f)
        if not ok or r >= cap:
            acc += at_cap
            res_out[j] = cap
            continue
        res_out[j] = r
        used += 1
        e = math.exp(-r * r * inv2s2)
        acc += math.log(outlier + e)
        wgt = 2.0 * inv2s2 * e / (outlier + e)  # d(-log(outlier + e)) / d(f) = wgt * f: the robust (IRLS) weight
        # the gradient in the body frame, and the Jacobian of f over (u, omega): [gb, p x gb], whitened by sd
        gbx = r00 * gx + r10 * gy + r20 * gz
        gby = r01 * gx + r11 * gy + r21 * gz
        gbz = r02 * gx + r12 * gy + r22 * gz
        j0 = gbx * s0
        j1 = gby * s1
        j2 = gbz * s2
        j3 = (py * gbz - pz * gby) * s3
        j4 = (pz * gbx - px * gbz) * s4
        j5 = (px * gby - py * gbx) * s5
        # the array version's products in its order: gv[a] += (wgt * f) * J[a], H[a, b] += (wgt * J[a]) * J[b]
        wf = wgt * f
        g0 += wf * j0
        w0 = wgt * j0
        h00 += w0 * j0
        g1 += wf * j1
        w1 = wgt * j1
        h10 += w1 * j0
        h11 += w1 * j1
        g2 += wf * j2
        w2 = wgt * j2
        h20 += w2 * j0
        h21 += w2 * j1
        h22 += w2 * j2
        g3 += wf * j3
        w3 = wgt * j3
        h30 += w3 * j0
        h31 += w3 * j1
        h32 += w3 * j2
        h33 += w3 * j3
        g4 += wf * j4
        w4 = wgt * j4
        h40 += w4 * j0
        h41 += w4 * j1
        h42 += w4 * j2
        h43 += w4 * j3
        h44 += w4 * j4
        g5 += wf * j5
        w5 = wgt * j5
        h50 += w5 * j0
        h51 += w5 * j1
        h52 += w5 * j2
        h53 += w5 * j3
        h54 += w5 * j4
        h55 += w5 * j5
    gv[0] = g0
    gv[1] = g1
    gv[2] = g2
    gv[3] = g3
    gv[4] = g4
    gv[5] = g5
    H[0, 0] = h00
    H[1, 0] = h10
    H[0, 1] = h10
    H[1, 1] = h11
    H[2, 0] = h20
    H[0, 2] = h20
    H[2, 1] = h21
    H[1, 2] = h21
    H[2, 2] = h22
    H[3, 0] = h30
    H[0, 3] = h30
    H[3, 1] = h31
    H[1, 3] = h31
    H[3, 2] = h32
    H[2, 3] = h32
    H[3, 3] = h33
    H[4, 0] = h40
    H[0, 4] = h40
    H[4, 1] = h41
    H[1, 4] = h41
    H[4, 2] = h42
    H[2, 4] = h42
    H[4, 3] = h43
    H[3, 4] = h43
    H[4, 4] = h44
    H[5, 0] = h50
    H[0, 5] = h50
    H[5, 1] = h51
    H[1, 5] = h51
    H[5, 2] = h52
    H[2, 5] = h52
    H[5, 3] = h53
    H[3, 5] = h53
    H[5, 4] = h54
    H[4, 5] = h54
    H[5, 5] = h55
    return acc, used


@njit(cache=True, inline="always")
def _cholesky_solve(A: np.ndarray, b: np.ndarray, L: np.ndarray, x: np.ndarray) -> float:  # pragma: no cover - compiled
    """Solve the symmetric positive-definite ``A`` (6, 6) x = ``b`` in place of ``x``; returns log det A."""
    logdet = 0.0
    for i in range(6):
        for j in range(i + 1):
            s = A[i, j]
            for q in range(j):
                s -= L[i, q] * L[j, q]
            if i == j:
                s = max(s, 1e-300)
                L[i, i] = math.sqrt(s)
                logdet += math.log(s)
            else:
                L[i, j] = s / L[j, j]
    for i in range(6):
        s = b[i]
        for q in range(i):
            s -= L[i, q] * x[q]
        x[i] = s / L[i, i]
    for i in range(5, -1, -1):
        s = x[i]
        for q in range(i + 1, 6):
            s -= L[q, i] * x[q]
        x[i] = s / L[i, i]
    return logdet


@njit(cache=True, inline="always")
def _compose(R: np.ndarray, t: np.ndarray, step: np.ndarray, Rout: np.ndarray, tout: np.ndarray,
             tmp: np.ndarray) -> None:  # pragma: no cover - compiled
    """``tout = t + R u``, ``Rout = R Exp(omega)`` for the body-frame step (u, omega) ``step`` (6,)."""
    for a in range(3):
        tout[a] = t[a] + R[a, 0] * step[0] + R[a, 1] * step[1] + R[a, 2] * step[2]
    wx, wy, wz = step[3], step[4], step[5]
    th = math.sqrt(wx * wx + wy * wy + wz * wz)
    if th < 1e-12:
        s_, c_ = 1.0, 0.5
    else:
        s_, c_ = math.sin(th) / th, (1.0 - math.cos(th)) / (th * th)
    # Rodrigues: E = I + s K + c K^2, K = [omega]x
    tmp[0, 0] = 1.0 - c_ * (wy * wy + wz * wz)
    tmp[0, 1] = -s_ * wz + c_ * wx * wy
    tmp[0, 2] = s_ * wy + c_ * wx * wz
    tmp[1, 0] = s_ * wz + c_ * wx * wy
    tmp[1, 1] = 1.0 - c_ * (wx * wx + wz * wz)
    tmp[1, 2] = -s_ * wx + c_ * wy * wz
    tmp[2, 0] = -s_ * wy + c_ * wx * wz
    tmp[2, 1] = s_ * wx + c_ * wy * wz
    tmp[2, 2] = 1.0 - c_ * (wx * wx + wy * wy)
    for a in range(3):
        for b in range(3):
            Rout[a, b] = R[a, 0] * tmp[0, b] + R[a, 1] * tmp[1, b] + R[a, 2] * tmp[2, b]


@intrinsic
def _prefetch(typingctx, arr, idx):  # type: ignore[no-untyped-def]  # pragma: no cover - compiled
    """``llvm.prefetch`` (read, high locality) of ``arr[idx]`` of a 1-d array: a hint that changes no value and
    never faults (an address outside the array is not read)."""
    sig = types.void(arr, idx)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]], wraparound=False)
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
                                            "llvm.prefetch.p0")
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return sig, codegen


@njit(cache=True, inline="always")
def _prefetch_cells(R: np.ndarray, t: np.ndarray, pts: np.ndarray, k: int, n: int, lo: np.ndarray, shape: np.ndarray,
                    start: np.ndarray, values: np.ndarray, cell: float) -> None:  # pragma: no cover - compiled
    """Prefetch the grid cells that the contacts ``pts`` placed by hypothesis ``R[k, n]``, ``t[k, n]`` read on
    object ``k``'s grid (the four z-pairs of each cell's corners), so that they arrive while another
    hypothesis is refined. Changes nothing."""
    sy, sz = shape[k, 1], shape[k, 2]
    for j in range(pts.shape[0]):
        px, py, pz = pts[j, 0], pts[j, 1], pts[j, 2]
        x = R[k, n, 0, 0] * px + R[k, n, 0, 1] * py + R[k, n, 0, 2] * pz + t[k, n, 0]
        y = R[k, n, 1, 0] * px + R[k, n, 1, 1] * py + R[k, n, 1, 2] * pz + t[k, n, 1]
        z = R[k, n, 2, 0] * px + R[k, n, 2, 1] * py + R[k, n, 2, 2] * pz + t[k, n, 2]
        base, _, _, _ = _cell_of(x, y, z, k, lo, shape, start, cell)
        if base >= 0:
            _prefetch(values, base)
            _prefetch(values, base + sz)
            _prefetch(values, base + sy * sz)
            _prefetch(values, base + sy * sz + sz)


def refine_chunks(pairs: int) -> int:
    """How many runs :func:`refine` splits ``pairs`` (object, hypothesis) pairs into: one per numba thread
    (``numba.get_num_threads()``), at most one per pair, at least one."""
    return max(1, min(int(pairs), numba.get_num_threads()))


@njit(cache=True)
def _refine_range(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
                  values: np.ndarray, cell: float, sigma: float, outlier: float, cap: float, rows: np.ndarray,
                  sd: np.ndarray, iterations: int, q0: int, q1: int, ll: np.ndarray,
                  res: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`refine` of the (object, hypothesis) pairs ``q0 <= q < q1`` (pair ``q``: ``rows[q // N]``,
    hypothesis ``q % N``), into ``ll`` and ``res``; its own scratch. A function of its own, called
    from :func:`refine`'s parallel loop, not inlined into it: inlined, numba's parallel lowering
    of this body took 14 s more to compile (24 s against 10 s for the first whisks, empty cache)."""
    N, m = R.shape[1], pts.shape[0]
    inv2s2 = 0.5 / (sigma * sigma)
    at_cap = math.log(outlier + math.exp(-cap * cap * inv2s2))
    # scratch allocated once per run; the current and the trial state swap buffers instead of copying
    H = np.empty((6, 6))
    gv = np.empty(6)
    H2 = np.empty((6, 6))
    gv2 = np.empty(6)
    A = np.empty((6, 6))
    L = np.empty((6, 6))
    rhs = np.empty(6)
    d_eta = np.empty(6)
    eta = np.empty(6)
    eta2 = np.empty(6)
    step = np.empty(6)
    Rc = np.empty((3, 3))
    tc = np.empty(3)
    Rt = np.empty((3, 3))
    tt = np.empty(3)
    tmp = np.empty((3, 3))
    r_cur = np.empty(m)
    r_try = np.empty(m)
    for q in range(q0, q1):
        i, n = q // N, q % N
        k = rows[i]
        if q + 1 < q1:  # the next hypothesis' grid cells, read while this one is refined
            _prefetch_cells(R, t, pts, rows[(q + 1) // N], (q + 1) % N, lo, shape, start, values, cell)
        for a in range(3):
            for b in range(3):
                Rc[a, b] = R[k, n, a, b]
            tc[a] = t[k, n, a]
        for a in range(6):
            eta[a] = 0.0
        lik, used = _fit_pass(Rc, tc, pts, k, lo, shape, start, values, cell, inv2s2, outlier, cap, at_cap, sd,
                              H, gv, r_cur)
        if used == 0:
            # no contact on the grid under the cap: H = 0 and the gradient is 0, so every step is exactly zero, the
            # trial pose is this pose (R Exp(0) = R bit for bit) and is refused; E = -lik and log det(I) = 0
            ll[i, n] = lik
            for j in range(m):
                res[i, n, j] = r_cur[j]
            continue
        cost = -lik
        lam = 1e-3
        moved = False
        for _ in range(iterations):
            for a in range(6):
                for b in range(6):
                    A[a, b] = H[a, b]
                A[a, a] += 1.0 + lam * (H[a, a] + 1.0)
                rhs[a] = -(gv[a] + eta[a])
            _cholesky_solve(A, rhs, L, d_eta)
            for a in range(6):
                eta2[a] = eta[a] + d_eta[a]
                step[a] = sd[a] * d_eta[a]
            _compose(Rc, tc, step, Rt, tt, tmp)
            lik2, _ = _fit_pass(Rt, tt, pts, k, lo, shape, start, values, cell, inv2s2, outlier, cap, at_cap, sd,
                             H2, gv2, r_try)
            prior2 = 0.0
            prior1 = 0.0
            for a in range(6):
                prior2 += 0.5 * eta2[a] * eta2[a]
                prior1 += 0.5 * eta[a] * eta[a]
            if -lik2 + prior2 < cost + prior1:  # accepted: the trial state becomes the current one
                Rc, Rt = Rt, Rc
                tc, tt = tt, tc
                eta, eta2 = eta2, eta
                H, H2 = H2, H
                gv, gv2 = gv2, gv
                r_cur, r_try = r_try, r_cur
                cost = -lik2
                lam *= 0.1
                moved = True
            else:
                lam *= 10.0
        prior = 0.0
        for a in range(6):
            prior += 0.5 * eta[a] * eta[a]
            for b in range(6):
                A[a, b] = H[a, b]
            A[a, a] += 1.0
            rhs[a] = 0.0
        logdet = _cholesky_solve(A, rhs, L, d_eta)
        ll[i, n] = -cost - prior - 0.5 * logdet
        for j in range(m):
            res[i, n, j] = r_cur[j]
        if moved:
            for a in range(3):
                for b in range(3):
                    R[k, n, a, b] = Rc[a, b]
                t[k, n, a] = tc[a]



@njit(cache=True, parallel=True)
def refine(R: np.ndarray, t: np.ndarray, pts: np.ndarray, lo: np.ndarray, shape: np.ndarray, start: np.ndarray,
           values: np.ndarray, cell: float, sigma: float, outlier: float, cap: float, rows: np.ndarray,
           sd: np.ndarray, iterations: int, nchunks: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Registration-refined hypotheses, in place, and their Laplace log marginal likelihoods.

    Every hypothesis ``R[k, n]``, ``t[k, n]`` of the objects ``rows`` is corrected by a body-frame
    step ``delta = sd * eta`` (``sd`` (6,): the prior's standard deviations of the displacement, m,
    and of the rotation vector, rad) that lowers ``E(eta) = -sum_j log(outlier + exp(-r_j^2 / 2 sigma^2))
    + |eta|^2 / 2``: ``iterations`` Levenberg-Marquardt steps on the Gauss-Newton system of the
    contacts' signed distances (an uphill step is refused and the damping raised). Returns the log
    marginal likelihood ``-E(eta*) - log det(H) / 2`` (``H`` the whitened Gauss-Newton Hessian at the
    refined pose, identity included: the Laplace approximation of the likelihood integrated over
    the prior of the correction), (len(rows), N), and each contact's residual at the refined pose,
    (len(rows), N, m), as :func:`likelihoods`.

    A hypothesis none of whose contacts is on the grid under the cap keeps its pose (its system is
    zero, so is every step) and gets its log likelihood; while one hypothesis is refined the grid
    cells of the next are prefetched. The hypotheses are split into ``nchunks`` runs of consecutive
    (object, hypothesis) pairs refined in parallel: each is refined alone, so the results do not
    depend on ``nchunks``.
    """
    N, m = R.shape[1], pts.shape[0]
    ll = np.empty((rows.shape[0], N))
    res = np.empty((rows.shape[0], N, m))
    total = rows.shape[0] * N
    for c in prange(nchunks):
        _refine_range(R, t, pts, lo, shape, start, values, cell, sigma, outlier, cap, rows, sd, iterations,
                      total * c // nchunks, total * (c + 1) // nchunks, ll, res)
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
