"""Numba kernels of :class:`cansim.models.posecell_network.PosecellNetwork` (imported on first use).

Every loop runs in OpenRatSLAM's order and every expression keeps its C++
association, so the floating-point results are those of the C++ core bit for
bit (numba emits plain IEEE multiplies and adds: no fused multiply-add without
``fastmath``). Arrays are in the C++ layout ``[th, y, x]``. Transcendental
functions are evaluated by the caller with Python's :mod:`math` (the C
library), never here.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache


@njit(cache=True)
def _spread_dim(
    p: np.ndarray, w: np.ndarray, width: tuple, wrap_xy: np.ndarray, wrap_th: np.ndarray, out: np.ndarray, layers: np.ndarray
) -> bool:
    """``out`` = every non-zero cell's energy spread by the ``dim``^3 weights ``w``, ``dim = len(width)``.

    Returns whether any cell of ``p`` is negative (found by the same scan). ``layers[k]``
    False promises that theta layer ``k`` of ``p`` holds only zeros (it is not scanned).

    ``width`` is a tuple of ``dim`` zeros: its length is a compile-time constant, so each
    kernel row (``dim`` contiguous targets) compiles to unrolled, vectorised code.
    Sources are visited x outermost, theta innermost and each source's targets in
    (theta, y, x) kernel order, so every target accumulates in the C++ order; the
    (y, x) columns without a non-zero cell are found first in memory order and skipped.
    """
    dim = len(width)
    nth, nxy = p.shape[0], p.shape[1]
    o = out.reshape(-1)
    o[:] = 0.0
    plane = nxy * nxy
    fp = p.reshape(-1)
    live = np.zeros(plane, dtype=np.bool_)  # [y, x] column holds a non-zero cell
    negative = False
    for k in range(nth):
        if not layers[k]:
            continue
        base = k * plane
        for q in range(plane):
            v = fp[base + q]
            if v != 0.0:
                live[q] = True
                if v < 0.0:
                    negative = True
    for i in range(nxy):
        x0 = wrap_xy[i]  # first target column; the row is contiguous unless it wraps
        straight = x0 + dim <= nxy
        for j in range(nxy):
            if not live[j * nxy + i]:
                continue
            for k in range(nth):
                v = p[k, j, i]
                if v != 0.0:
                    n = 0
                    for zl in range(k, k + dim):
                        zo = wrap_th[zl] * plane
                        for yl in range(j, j + dim):
                            base = zo + wrap_xy[yl] * nxy
                            if straight:  # unsigned indices: no negative-index wrap code in the row
                                row = np.uint64(base + x0)
                                nn = np.uint64(n)
                                for d in range(dim):
                                    du = np.uint64(d)
                                    o[row + du] += v * w[nn + du]
                            else:
                                for d in range(dim):
                                    o[base + wrap_xy[i + d]] += v * w[n + d]
                            n += dim
    return negative


@njit(cache=True)
def _spread(
    p: np.ndarray, w: np.ndarray, dim: int, wrap_xy: np.ndarray, wrap_th: np.ndarray, out: np.ndarray, layers: np.ndarray
) -> bool:
    """``excite``/``inhibit`` helper: :func:`_spread_dim` with the kernel width ``dim`` (odd, 1..9) as a constant.

    Returns whether any cell of ``p`` is negative; ``layers`` as in :func:`_spread_dim`."""
    if dim == 7:
        return _spread_dim(p, w, (0, 0, 0, 0, 0, 0, 0), wrap_xy, wrap_th, out, layers)
    elif dim == 5:
        return _spread_dim(p, w, (0, 0, 0, 0, 0), wrap_xy, wrap_th, out, layers)
    elif dim == 3:
        return _spread_dim(p, w, (0, 0, 0), wrap_xy, wrap_th, out, layers)
    elif dim == 9:
        return _spread_dim(p, w, (0, 0, 0, 0, 0, 0, 0, 0, 0), wrap_xy, wrap_th, out, layers)
    elif dim == 1:
        return _spread_dim(p, w, (0,), wrap_xy, wrap_th, out, layers)
    return _spread_any(p, w, dim, wrap_xy, wrap_th, out)


@njit(cache=True)
def _spread_any(p: np.ndarray, w: np.ndarray, dim: int, wrap_xy: np.ndarray, wrap_th: np.ndarray, out: np.ndarray) -> bool:
    """:func:`_spread_dim` for any kernel width (a run-time ``dim``; the same order, slower rows)."""
    nth, nxy = p.shape[0], p.shape[1]
    o = out.reshape(-1)
    o[:] = 0.0
    plane = nxy * nxy
    negative = False
    for i in range(nxy):
        for j in range(nxy):
            for k in range(nth):
                v = p[k, j, i]
                if v != 0.0:
                    if v < 0.0:
                        negative = True
                    n = 0
                    for zl in range(k, k + dim):
                        zo = wrap_th[zl] * plane
                        for yl in range(j, j + dim):
                            base = zo + wrap_xy[yl] * nxy
                            for xl in range(i, i + dim):
                                o[base + wrap_xy[xl]] += v * w[n + xl - i]
                            n += dim
    return negative


@njit(cache=True)
def dynamics(
    p: np.ndarray,
    tmp: np.ndarray,
    w_exc: np.ndarray,
    e_dim: int,
    e_wrap_xy: np.ndarray,
    e_wrap_th: np.ndarray,
    w_inh: np.ndarray,
    i_dim: int,
    i_wrap_xy: np.ndarray,
    i_wrap_th: np.ndarray,
    global_inhib: float,
) -> float:
    """Excite, inhibit, global inhibition and normalisation of ``p`` in place; returns the pre-normalisation total.

    ``tmp`` holds the excited activity, ``p`` receives its inhibition, then each cell
    becomes excited - inhibition - global inhibition (clipped at 0) and the total is
    summed in cell order - the C++ arithmetic, one pass. When the total is not positive
    ``p`` is left un-normalised (the caller keeps its own copy).
    """
    every = np.ones(p.shape[0], dtype=np.bool_)
    _spread(p, w_exc, e_dim, e_wrap_xy, e_wrap_th, tmp, every)
    _spread(tmp, w_inh, i_dim, i_wrap_xy, i_wrap_th, p, every)
    total = _combine(p, tmp, global_inhib)
    if total > 0.0:
        flat = p.reshape(-1)
        for q in range(flat.size):
            flat[q] /= total
    return total


@njit(cache=True)
def _combine(p: np.ndarray, tmp: np.ndarray, global_inhib: float) -> float:
    """``p`` = ``tmp`` - ``p`` - global inhibition, clipped at 0, per cell; returns the total (cell order)."""
    flat, ftmp = p.reshape(-1), tmp.reshape(-1)
    total = 0.0
    for q in range(flat.size):
        a = ftmp[q] - flat[q]
        if a >= global_inhib:
            a = a - global_inhib
        else:
            a = 0.0
        flat[q] = a
        total += a
    return total


@njit(cache=True)
def _inhibit_clip_dim(
    tmp: np.ndarray,
    p: np.ndarray,
    w: np.ndarray,
    width: tuple,
    gx_src: np.ndarray,
    gx_w: np.ndarray,
    gy_src: np.ndarray,
    gy_w: np.ndarray,
    gt_src: np.ndarray,
    gt_w: np.ndarray,
    global_inhib: float,
    layers: np.ndarray,
    excited: np.ndarray,
) -> float:
    """``p`` = excited ``tmp`` - its inhibition - global inhibition, clipped at 0; returns the total.

    ``layers[k]`` is set to whether theta layer ``k`` of the result holds a non-zero cell
    (every other cell is ``+0.0``). ``excited[k]`` False promises that layer ``k`` of
    ``tmp`` holds only ``+0.0``: with ``global_inhib > 0`` none of its cells is gathered,
    so it is not scanned.

    The inhibition is gathered, and only for the cells it can matter to: a cell excited
    below ``global_inhib`` ends at 0 whatever its inhibition (``tmp`` and the weights are
    >= 0, so the inhibition is >= 0 and ``tmp - inh <= tmp`` under round-to-nearest). Each
    gathered cell adds its sources' terms in the order the C++ scatter adds them: sources
    by x, then y, then theta index ascending (the ``g*_src`` tables, one row per target
    coordinate, sorted so; ``g*_w`` the matching kernel offsets), every source's term
    ``source * weight`` as in ``inhibit``. A source holding 0 adds ``+0.0``, which leaves
    a sum of non-negative terms unchanged, so the sum equals the scatter's, which skips it.
    The weights must be >= 0 too: then every partial sum is <= the whole (adding a term
    >= 0 never lowers a rounded sum), so once ``tmp - partial < global_inhib`` for the four
    cells summed together, each ends at 0 and the sums stop there (the partial sum is kept:
    the clip then gives the same 0).
    The four cells summed together are the next four gathered cells of a theta layer.
    ``dim = len(width)`` (a compile-time constant); the tables need every axis >= ``dim``
    (each source reaches a target once). The total is summed in cell order, as the C++ does.
    """
    dim = len(width)
    nth, n = tmp.shape[0], tmp.shape[1]
    ft, fp = tmp.reshape(-1), p.reshape(-1)
    plane = n * n
    pick = np.empty(plane + 3, dtype=np.int64)  # the layer's gathered cells (y n + x), padded to a multiple of 4
    inh = np.empty(plane)
    total = 0.0
    skip = global_inhib > 0.0
    for k in range(nth):
        lay = k * plane
        m = 0
        if excited[k] or not skip:
            for q in range(plane):
                if ft[lay + q] >= global_inhib:
                    pick[m] = q
                    m += 1
        if m == 0:
            for q in range(plane):
                fp[lay + q] = 0.0
            layers[k] = False
            continue
        last = pick[m - 1]
        for r in range(m, m + 3):
            pick[r] = last  # padding: computed, not used
        for g in range(0, m, 4):  # four cells of the layer at a time: four independent sums
            q0, q1, q2, q3 = pick[g], pick[g + 1], pick[g + 2], pick[g + 3]
            j0, j1, j2, j3 = q0 // n, q1 // n, q2 // n, q3 // n
            i0, i1, i2, i3 = q0 - j0 * n, q1 - j1 * n, q2 - j2 * n, q3 - j3 * n
            e0, e1, e2, e3 = ft[lay + q0], ft[lay + q1], ft[lay + q2], ft[lay + q3]
            s0 = s1 = s2 = s3 = 0.0
            dead = False
            for xa in range(dim):
                x0, x1, x2, x3 = gx_src[i0, xa], gx_src[i1, xa], gx_src[i2, xa], gx_src[i3, xa]
                w0, w1, w2, w3 = gx_w[i0, xa], gx_w[i1, xa], gx_w[i2, xa], gx_w[i3, xa]
                for ya in range(dim):
                    b0, b1, b2, b3 = gy_src[j0, ya] + x0, gy_src[j1, ya] + x1, gy_src[j2, ya] + x2, gy_src[j3, ya] + x3
                    c0, c1, c2, c3 = gy_w[j0, ya] + w0, gy_w[j1, ya] + w1, gy_w[j2, ya] + w2, gy_w[j3, ya] + w3
                    for ta in range(dim):
                        tb = gt_src[k, ta]
                        tw = gt_w[k, ta]
                        s0 += ft[tb + b0] * w[tw + c0]
                        s1 += ft[tb + b1] * w[tw + c1]
                        s2 += ft[tb + b2] * w[tw + c2]
                        s3 += ft[tb + b3] * w[tw + c3]
                    # a partial sum of terms >= 0 is <= the whole sum (rounding is monotone),
                    # so a cell already below global inhibition ends at 0: stop when all four are
                    if (e0 - s0 < global_inhib and e1 - s1 < global_inhib and e2 - s2 < global_inhib
                            and e3 - s3 < global_inhib):
                        dead = True
                        break
                if dead:
                    break
            inh[q0] = s0
            inh[q1] = s1
            inh[q2] = s2
            inh[q3] = s3
        # every cell not gathered, or clipped, is +0.0, which adds nothing to the total (a sum
        # of terms >= +0.0 starting at +0.0): the layer is zeroed, then the kept cells are
        # written and summed in cell order (pick is ascending)
        for q in range(plane):
            fp[lay + q] = 0.0
        live = False
        for r in range(m):
            q = pick[r]
            a = ft[lay + q] - inh[q]
            if a >= global_inhib:
                a = a - global_inhib
                if a != 0.0:
                    live = True
                    fp[lay + q] = a
                    total += a
        layers[k] = live
    return total


@njit(cache=True)
def _inhibit_clip(
    tmp: np.ndarray,
    p: np.ndarray,
    w: np.ndarray,
    dim: int,
    gx_src: np.ndarray,
    gx_w: np.ndarray,
    gy_src: np.ndarray,
    gy_w: np.ndarray,
    gt_src: np.ndarray,
    gt_w: np.ndarray,
    global_inhib: float,
    layers: np.ndarray,
    excited: np.ndarray,
) -> float:
    """:func:`_inhibit_clip_dim` with the kernel width ``dim`` (odd, 1..9) as a constant."""
    if dim == 5:
        return _inhibit_clip_dim(tmp, p, w, (0, 0, 0, 0, 0), gx_src, gx_w, gy_src, gy_w, gt_src, gt_w, global_inhib,
                                 layers, excited)
    elif dim == 7:
        return _inhibit_clip_dim(tmp, p, w, (0, 0, 0, 0, 0, 0, 0), gx_src, gx_w, gy_src, gy_w, gt_src, gt_w, global_inhib,
                                 layers, excited)
    elif dim == 3:
        return _inhibit_clip_dim(tmp, p, w, (0, 0, 0), gx_src, gx_w, gy_src, gy_w, gt_src, gt_w, global_inhib, layers, excited)
    elif dim == 9:
        return _inhibit_clip_dim(tmp, p, w, (0, 0, 0, 0, 0, 0, 0, 0, 0), gx_src, gx_w, gy_src, gy_w, gt_src, gt_w,
                                 global_inhib, layers, excited)
    return _inhibit_clip_dim(tmp, p, w, (0,), gx_src, gx_w, gy_src, gy_w, gt_src, gt_w, global_inhib, layers, excited)


@njit(cache=True)
def dynamics_gather(
    src: np.ndarray,
    p: np.ndarray,
    tmp: np.ndarray,
    w_exc: np.ndarray,
    e_dim: int,
    e_wrap_xy: np.ndarray,
    e_wrap_th: np.ndarray,
    w_inh: np.ndarray,
    i_dim: int,
    i_wrap_xy: np.ndarray,
    i_wrap_th: np.ndarray,
    gx_src: np.ndarray,
    gx_w: np.ndarray,
    gy_src: np.ndarray,
    gy_w: np.ndarray,
    gt_src: np.ndarray,
    gt_w: np.ndarray,
    global_inhib: float,
    layers: np.ndarray,
) -> float:
    """:func:`dynamics` of ``src`` into ``p`` (every cell written; ``src`` is not changed), with the
    inhibition gathered for the cells excited to ``global_inhib`` or more.

    ``layers`` (bool, one per theta layer), in: False promises the layer of ``src`` holds only
    ``+0.0``; out: whether the layer of the result holds a non-zero cell (the others hold
    ``+0.0``: a clipped cell is written ``0.0``, a kept one ``a - global_inhib >= +0.0``).

    The same result bit for bit (see :func:`_inhibit_clip_dim`); a field with a negative
    cell (not produced by the model, whose cells stay >= 0) takes :func:`dynamics`'s
    scatter path, where a cell's inhibition may be negative. ``i_dim`` odd, 1..9, ``w_inh >= 0``, and
    every axis >= ``i_dim`` (the caller checks; the gather tables come from
    ``posecell_network._gather_table``).
    """
    nth, plane = p.shape[0], p.shape[1] * p.shape[2]
    excited = np.zeros(nth, dtype=np.bool_)  # layers of the excited field the live layers reach
    for k in range(nth):
        if layers[k]:
            for zl in range(k, k + e_dim):
                excited[e_wrap_th[zl]] = True
    negative = _spread(src, w_exc, e_dim, e_wrap_xy, e_wrap_th, tmp, layers)
    flat = p.reshape(-1)
    if negative:
        _spread(tmp, w_inh, i_dim, i_wrap_xy, i_wrap_th, p, np.ones(nth, dtype=np.bool_))
        total = _combine(p, tmp, global_inhib)
        for k in range(nth):
            live = False
            for q in range(k * plane, (k + 1) * plane):
                if flat[q] != 0.0:
                    live = True
                    break
            layers[k] = live
    else:
        total = _inhibit_clip(tmp, p, w_inh, i_dim, gx_src, gx_w, gy_src, gy_w, gt_src, gt_w, global_inhib, layers, excited)
    if total > 0.0:
        for k in range(nth):
            if layers[k]:  # the other layers hold +0.0, and +0.0 / total is +0.0
                for q in range(k * plane, (k + 1) * plane):
                    flat[q] /= total
    return total


@njit(cache=True)
def _rotate(src: np.ndarray, rot: int, dst: np.ndarray) -> None:
    """``dst`` = ``src`` turned by ``rot`` quarter turns as C++ ``rot90_square`` (``rot`` in 0..3)."""
    n = src.shape[0]
    if rot == 0:
        dst[:, :] = src
    elif rot == 1:
        for r in range(n):
            for c in range(n):
                dst[r, c] = src[n - 1 - c, r]
    elif rot == 2:
        for r in range(n):
            for c in range(n):
                dst[r, c] = src[n - 1 - r, n - 1 - c]
    else:
        for r in range(n):
            for c in range(n):
                dst[r, c] = src[c, n - 1 - r]


@njit(cache=True)
def translate(p: np.ndarray, rot: np.ndarray, cos90: np.ndarray, sin90: np.ndarray, vtrans: float, layers: np.ndarray) -> None:
    """Translational path integration of every theta layer by ``vtrans`` cells (<= 1) along its direction.

    Each layer is turned by ``rot[k]`` quarter turns, shifted towards +x/+y by the
    four bilinear weights of the residual angle (``cos90``/``sin90`` of it), the
    overflow row/column wrapped to the opposite edge, and turned back. A layer with
    ``layers[k]`` False (only ``+0.0``) is left as it is: each of its cells would be
    ``+0.0 * w`` summed over four weights of which one at least is positive (they sum to
    1), which is ``+0.0``.
    """
    nth, n = p.shape[0], p.shape[1]
    d = n + 2
    a = np.zeros((d, d))
    b = np.empty((d, d))
    lay = np.empty((n, n))
    for k in range(nth):
        if not layers[k]:
            continue
        c, s = cos90[k], sin90[k]
        w_sw = vtrans * vtrans * c * s
        w_se = vtrans * s * (1.0 - vtrans * c)
        w_nw = vtrans * c * (1.0 - vtrans * s)
        w_ne = 1.0 - w_sw - w_se - w_nw
        _rotate(p[k], rot[k], lay)
        a[:] = 0.0
        for j in range(n):
            for i in range(n):
                a[j + 1, i + 1] = lay[j, i]
        for j in range(d):
            jm = j - 1 if j > 0 else d - 1
            for i in range(d):
                im = i - 1 if i > 0 else d - 1
                b[j, i] = a[j, i] * w_ne + a[j, im] * w_se + a[jm, i] * w_nw
        for j in range(d):
            jm = j - 1 if j > 0 else d - 1
            for i in range(d):
                im = i - 1 if i > 0 else d - 1
                b[j, i] += a[jm, im] * w_sw
        for j in range(n):
            for i in range(n):
                lay[j, i] = b[j + 1, i + 1]
        for i in range(1, n):
            lay[0, i] += b[n + 1, i + 1]
        for j in range(1, n):
            lay[j, 0] += b[j + 1, n + 1]
        lay[0, 0] += b[n + 1, n + 1]
        _rotate(lay, (4 - rot[k]) % 4, p[k])


@njit(cache=True)
def rotate_theta(p: np.ndarray, tmp: np.ndarray, shift1: int, shift2: int, weight: float, layers: np.ndarray) -> None:
    """Rotational path integration: ``p[k] = p[k - shift1] (1 - weight) + p[k - shift2] weight`` (shifts <= 0).

    ``layers`` (in: False promises a layer of only ``+0.0``) is updated to the result's. A
    layer whose two sources hold only ``+0.0`` is ``+0.0`` (``weight`` in (0, 1], so both
    factors are >= 0): it is written as zeros, or left when it is zeros already.
    """
    nth = p.shape[0]
    before = layers.copy()
    for k in range(nth):
        if before[k]:
            tmp[k] = p[k]
        else:
            tmp[k] = 0.0
    keep = 1.0 - weight
    for k in range(nth):
        ka, kb = (k - shift1) % nth, (k - shift2) % nth
        out = p[k]
        if not (before[ka] or before[kb]):
            if before[k]:
                out[:, :] = 0.0
            layers[k] = False
            continue
        layers[k] = True
        a = tmp[ka]
        b = tmp[kb]
        for j in range(p.shape[1]):
            for i in range(p.shape[2]):
                out[j, i] = a[j, i] * keep + b[j, i] * weight


@njit(cache=True)
def best_sums(
    p: np.ndarray,
    half: int,
    wrap_xy: np.ndarray,
    wrap_th: np.ndarray,
    sin_xy: np.ndarray,
    cos_xy: np.ndarray,
    sin_th: np.ndarray,
    cos_th: np.ndarray,
    layers: np.ndarray,
) -> tuple[float, float, float, float, float, float]:
    """``find_best`` up to the ``atan2``: the six sine/cosine sums of the +-``half`` box around the maximum.

    The maximum is searched in the layers with ``layers[k]`` True (the others hold ``+0.0``,
    which never beats the search's start, 0)."""
    nth, n = p.shape[0], p.shape[1]
    mx = 0.0
    x = y = th = 0
    for k in range(nth):
        if not layers[k]:
            continue
        for j in range(n):
            for i in range(n):
                if p[k, j, i] > mx:
                    mx = p[k, j, i]
                    x, y, th = i, j, k
    xs = np.zeros(n)
    ys = np.zeros(n)
    zs = np.zeros(nth)
    width = 2 * half + 1
    for k in range(th, th + width):
        kw = wrap_th[k]
        for j in range(y, y + width):
            jw = wrap_xy[j]
            for i in range(x, x + width):
                iw = wrap_xy[i]
                v = p[kw, jw, iw]
                zs[kw] += v
                ys[jw] += v
                xs[iw] += v
    sx1 = sx2 = sy1 = sy2 = 0.0
    for i in range(n):
        sx1 += sin_xy[i] * xs[i]
        sx2 += cos_xy[i] * xs[i]
        sy1 += sin_xy[i] * ys[i]
        sy2 += cos_xy[i] * ys[i]
    st1 = st2 = 0.0
    for i in range(nth):
        st1 += sin_th[i] * zs[i]
        st2 += cos_th[i] * zs[i]
    return sx1, sx2, sy1, sy2, st1, st2


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
