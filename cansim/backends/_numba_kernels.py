"""Compiled kernels of the numba backend (generic N-D, any axis count).

Everything works on *boxes*: a box is, per axis, a circular arc ``start, start + 1,
..., start + m - 1 (mod n)`` of the periodic grid, and a box buffer is a flat float64
array holding the box's cells in C order. A box covering a whole axis has ``m == n``
and ``start == 0``. After global inhibition (Alg 5) the activity is non-zero only in a
small packet, so the step runs on the smallest box that holds the non-zero cells
(the complement of the largest empty circular gap per axis), grown pass by pass by
the kernel half-widths and shift extents. When the packet spreads over an axis the
box covers that axis and the same code is the dense path.

Every operation is a *line pass* along one axis: each output cell of a line is a
weighted sum of input cells of the same line, ``dst[p] = sum_j w_j src[tab[p, j]]``
with ``tab[p, j] = -1`` for a source outside the input box (zero activity there).
Excitation/inhibition (Alg 3/4) are passes with the Gaussian taps; a fractional
shift (Fig 5.11) is a pass with taps ``(1 - f, f)`` at offsets ``floor(s)`` and
``floor(s) + 1``; a heading-conditional shift uses one tap table per condition.
Sums run in float64 in the numpy reference's order (tap after tap), and values are
rounded to the storage dtype wherever the reference stores them, so decisions at the
global-inhibition threshold match it.

Every function is compiled lazily on first call (``cache=True`` keeps the machine code
between runs). ``*_par`` variants spread a pass over threads; the caller uses them
only when the pass is big enough to repay the thread launch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

_OPTS = dict(cache=True, fastmath=False, nogil=True)

STATUS_OK = 0
STATUS_COLLAPSE = 1

_TWO_PI = 2.0 * np.pi


# --------------------------------------------------------------------------- boxes
@njit(**_OPTS)
def box_size(m):
    """Number of cells of a box with extents ``m``."""
    s = 1
    for k in range(m.shape[0]):
        s *= m[k]
    return s


@njit(**_OPTS)
def arc_from_occupancy(occ, n):
    """Smallest circular arc ``(start, length)`` covering the marked cells of ``occ[:n]``.

    It is the complement of the largest run of unmarked cells (circularly).
    Returns ``(0, 0)`` when nothing is marked and ``(0, n)`` when everything is.
    """
    cnt = 0
    for i in range(n):
        if occ[i] != 0:
            cnt += 1
    if cnt == 0:
        return 0, 0
    if cnt == n:
        return 0, n
    best_len = 0
    best_end = 0
    run = 0
    for t in range(2 * n):
        i = t - n if t >= n else t
        if occ[i] == 0:
            run += 1
            if run > best_len:
                best_len = run
                best_end = i + 1 if i + 1 < n else 0
        else:
            run = 0
    return best_end, n - best_len


@njit(**_OPTS)
def grow_arc(start, m, left, right, n):
    """Arc ``(start, m)`` extended by ``left`` cells below and ``right`` above (whole axis if it fills it)."""
    if m >= n or m + left + right >= n:
        return 0, n
    return (start - left) % n, m + left + right


# ----------------------------------------------------------------------- occupancy
@njit(**_OPTS)
def mark_occupancy(bits, m, occ):
    """Mark in ``occ[k, i]`` every local index ``i`` of axis ``k`` holding a non-zero cell.

    ``bits`` is the box buffer viewed as unsigned integers (any non-zero bit pattern,
    -0.0 included, counts as occupied; that only widens the box). Returns whether any
    cell is occupied.
    """
    d = m.shape[0]
    last = d - 1
    ml = m[last]
    nrows = box_size(m) // ml
    idx = np.zeros(d, np.int64)
    anyset = False
    for r in range(nrows):
        base = r * ml
        acc = bits[base] & 0
        for i in range(ml):
            acc |= bits[base + i]
        if acc != 0:
            anyset = True
            for i in range(ml):
                if bits[base + i] != 0:
                    occ[last, i] = 1
            for k in range(last):
                occ[k, idx[k]] = 1
        k = last - 1
        while k >= 0:
            idx[k] += 1
            if idx[k] < m[k]:
                break
            idx[k] = 0
            k -= 1
    return anyset


@njit(**_OPTS)
def tight_box(occ_local, s, m, n, ts, tm):
    """Global arcs ``(ts, tm)`` covering the occupied local indices of a box ``(s, m)``."""
    d = n.shape[0]
    nmax = 0
    for k in range(d):
        nmax = max(nmax, n[k])
    occ = np.zeros(nmax, np.uint8)
    for k in range(d):
        for i in range(n[k]):
            occ[i] = 0
        for p in range(m[k]):
            if occ_local[k, p] != 0:
                occ[(s[k] + p) % n[k]] = 1
        a0, l0 = arc_from_occupancy(occ, n[k])
        ts[k] = a0
        tm[k] = l0


# ------------------------------------------------------------------- gather/scatter
@njit(**_OPTS)
def _offset_tables(s_from, m_from, s_to, m_to, n):
    """``off[k, p]``: flat offset contribution in the 'from' box of local index p of the 'to' box, -1 outside."""
    d = n.shape[0]
    mmax = 1
    for k in range(d):
        mmax = max(mmax, m_to[k])
    off = np.full((d, mmax), -1, np.int64)
    stride = 1
    for k in range(d - 1, -1, -1):
        for p in range(m_to[k]):
            q = (s_to[k] + p - s_from[k]) % n[k]
            if q < m_from[k]:
                off[k, p] = q * stride
        stride *= m_from[k]
    return off


@njit(**_OPTS)
def crop(src, s_src, m_src, dst, s_dst, m_dst, n):
    """Fill box buffer ``dst`` (box ``s_dst, m_dst``) from ``src`` (box ``s_src, m_src``); zero outside src."""
    d = n.shape[0]
    off = _offset_tables(s_src, m_src, s_dst, m_dst, n)
    last = d - 1
    ml = m_dst[last]
    nrows = box_size(m_dst) // ml
    idx = np.zeros(d, np.int64)
    for r in range(nrows):
        b = 0
        ok = True
        for k in range(last):
            v = off[k, idx[k]]
            if v < 0:
                ok = False
                break
            b += v
        base = r * ml
        if ok:
            for p in range(ml):
                v = off[last, p]
                dst[base + p] = src[b + v] if v >= 0 else 0.0
        else:
            for p in range(ml):
                dst[base + p] = 0.0
        k = last - 1
        while k >= 0:
            idx[k] += 1
            if idx[k] < m_dst[k]:
                break
            idx[k] = 0
            k -= 1


@njit(**_OPTS)
def scatter(src, s, m, out, n):
    """Write box buffer ``src`` (box ``s, m``) into the full grid ``out`` (flat); zero elsewhere."""
    d = n.shape[0]
    full = True
    for k in range(d):
        if m[k] != n[k]:
            full = False
    if full:
        for i in range(out.shape[0]):
            out[i] = src[i]
        return
    out[:] = 0
    zero = np.zeros(d, np.int64)
    off = _offset_tables(zero, n, s, m, n)  # box index -> grid offset
    last = d - 1
    ml = m[last]
    nrows = box_size(m) // ml
    idx = np.zeros(d, np.int64)
    for r in range(nrows):
        b = 0
        for k in range(last):
            b += off[k, idx[k]]
        base = r * ml
        for p in range(ml):
            out[b + off[last, p]] = src[base + p]
        k = last - 1
        while k >= 0:
            idx[k] += 1
            if idx[k] < m[k]:
                break
            idx[k] = 0
            k -= 1


@njit(**_OPTS)
def round_to(buf, size, proto):
    """Round ``buf[:size]`` (float64) to the dtype of the 1-element array ``proto`` and back."""
    for i in range(size):
        proto[0] = buf[i]
        buf[i] = proto[0]


# ---------------------------------------------------------------------- line passes
@njit(**_OPTS)
def _outer_inner(m, k):
    o = 1
    for j in range(k):
        o *= m[j]
    i = 1
    for j in range(k + 1, m.shape[0]):
        i *= m[j]
    return o, i


@njit(**_OPTS)
def conv_lines(src, dst, mi, mo, inner, tab, w, t_lo, t_hi):
    """One tap table for all lines: ``dst[o, p, :] = sum_j w[j] src[o, tab[p, j], :]`` for t = o*mo + p in [t_lo, t_hi)."""
    nw = w.shape[0]
    if inner == 1:
        for t in range(t_lo, t_hi):
            o = t // mo
            p = t - o * mo
            acc = 0.0
            sb = o * mi
            for j in range(nw):
                q = tab[p, j]
                if q >= 0:
                    acc += w[j] * src[sb + q]
            dst[t] = acc
        return
    for t in range(t_lo, t_hi):
        o = t // mo
        p = t - o * mo
        d0 = t * inner
        for i in range(inner):
            dst[d0 + i] = 0.0
        for j in range(nw):
            q = tab[p, j]
            if q >= 0:
                wj = w[j]
                s0 = (o * mi + q) * inner
                for i in range(inner):
                    dst[d0 + i] += wj * src[s0 + i]


@njit(parallel=True, **_OPTS)
def conv_lines_par(src, dst, mi, mo, inner, tab, w, nlines, nchunks):
    """:func:`conv_lines` over ``nlines`` lines split into ``nchunks`` threads' chunks."""
    for c in prange(nchunks):
        lo = nlines * c // nchunks
        hi = nlines * (c + 1) // nchunks
        conv_lines(src, dst, mi, mo, inner, tab, w, lo, hi)


@njit(**_OPTS)
def group_lines(src, dst, mi, mo, inner, tab, w, grp_o, grp_i, t_lo, t_hi):
    """One tap table per line group: line t = o*inner + i uses table ``grp_o[o] + grp_i[i]``."""
    nw = w.shape[1]
    for t in range(t_lo, t_hi):
        o = t // inner
        i = t - o * inner
        g = grp_o[o] + grp_i[i]
        sb = o * mi
        db = o * mo
        for p in range(mo):
            acc = 0.0
            for j in range(nw):
                q = tab[g, p, j]
                if q >= 0:
                    acc += w[g, j] * src[(sb + q) * inner + i]
            dst[(db + p) * inner + i] = acc


@njit(parallel=True, **_OPTS)
def group_lines_par(src, dst, mi, mo, inner, tab, w, grp_o, grp_i, nlines, nchunks):
    """:func:`group_lines` split into ``nchunks`` threads' chunks."""
    for c in prange(nchunks):
        lo = nlines * c // nchunks
        hi = nlines * (c + 1) // nchunks
        group_lines(src, dst, mi, mo, inner, tab, w, grp_o, grp_i, lo, hi)


@njit(**_OPTS)
def conv_table(taps, nt, s_in, m_in, s_out, m_out, n):
    """Tap table of a periodic scatter convolution (Alg 3): output p reads input ``p - (j - c)``."""
    c = nt // 2
    tab = np.empty((m_out, nt), np.int64)
    for p in range(m_out):
        gp = s_out + p
        for j in range(nt):
            q = (gp - (j - c) - s_in) % n
            tab[p, j] = q if (q < m_in and taps[j] != 0.0) else -1
    return tab


@njit(**_OPTS)
def split_shift(s, n):
    """Integer part (centred mod n), and fraction of a shift, as the reference's ``floor``/``s - floor``."""
    lo_f = math.floor(s)
    f = s - lo_f
    r = lo_f - n * math.floor(lo_f / n)
    lo = np.int64(r)
    if lo >= n:
        lo -= n
    if lo > n // 2:
        lo -= n
    return lo, f


@njit(**_OPTS)
def shift_row(s, n, s_in, m_in, s_out, m_out, tab_row, w_row):
    """Taps ``(1 - f, f)`` of a fractional roll by ``s`` (Fig 5.11) for one line table."""
    lo, f = split_shift(s, n)
    w_row[0] = 1.0 - f
    w_row[1] = f
    for p in range(m_out):
        gp = s_out + p
        for j in range(2):
            q = (gp - lo - j - s_in) % n
            tab_row[p, j] = q if (q < m_in and w_row[j] != 0.0) else -1


@njit(**_OPTS)
def run_conv_pass(src, dst, s, m, k, taps, nt, left, right, n, par_work, nthreads):
    """Pass along axis k with one tap table; the box grows by ``left``/``right`` on k (updated in place)."""
    s_in = s[k]
    m_in = m[k]
    s_out, m_out = grow_arc(s_in, m_in, left, right, n[k])
    tab = conv_table(taps, nt, s_in, m_in, s_out, m_out, n[k])
    outer, inner = _outer_inner(m, k)
    nlines = outer * m_out
    if nthreads > 1 and nlines * inner * nt >= par_work and nlines >= nthreads:
        conv_lines_par(src, dst, m_in, m_out, inner, tab, taps[:nt], nlines, nthreads)
    else:
        conv_lines(src, dst, m_in, m_out, inner, tab, taps[:nt], 0, nlines)
    s[k] = s_out
    m[k] = m_out


# -------------------------------------------------------------------------- shifts
@njit(**_OPTS)
def _line_groups(s, m, k, n, cmask, cstride):
    """Condition index contributions of the outer (axes < k) and inner (axes > k) coordinates."""
    d = n.shape[0]
    outer, inner = _outer_inner(m, k)
    grp_o = np.zeros(outer, np.int64)
    grp_i = np.zeros(inner, np.int64)
    idx = np.zeros(d, np.int64)
    for o in range(outer):
        g = 0
        for j in range(k):
            if cmask[j] == 0:
                g += ((s[j] + idx[j]) % n[j]) * cstride[j]
        grp_o[o] = g
        j = k - 1
        while j >= 0:
            idx[j] += 1
            if idx[j] < m[j]:
                break
            idx[j] = 0
            j -= 1
    idx[:] = 0
    for i in range(inner):
        g = 0
        for j in range(k + 1, d):
            if cmask[j] == 0:
                g += ((s[j] + idx[j]) % n[j]) * cstride[j]
        grp_i[i] = g
        j = d - 1
        while j > k:
            idx[j] += 1
            if idx[j] < m[j]:
                break
            idx[j] = 0
            j -= 1
    return grp_o, grp_i


@njit(**_OPTS)
def run_cond_shift(bufs, cur, s, m, n, cmask, cond_tab, par_work, nthreads):
    """Heading-conditional shift (SPEC §1.4): every condition slice rolls along the shift axes
    by its own row of ``cond_tab`` (G, n_shift_axes), axis after axis. Returns the buffer index."""
    d = n.shape[0]
    ng = cond_tab.shape[0]
    # strides of the condition index over the non-shift axes, C order
    cstride = np.zeros(d, np.int64)
    acc = 1
    for j in range(d - 1, -1, -1):
        if cmask[j] == 0:
            cstride[j] = acc
            acc *= n[j]
    kk = 0
    for k in range(d):
        if cmask[k] == 0:
            continue
        col = kk
        kk += 1
        lo_min = n[k]
        hi_max = -n[k]
        moving = False
        for g in range(ng):
            lo, f = split_shift(cond_tab[g, col], n[k])
            hi = lo + 1 if f != 0.0 else lo
            lo_min = min(lo_min, lo)
            hi_max = max(hi_max, hi)
            if lo != 0 or f != 0.0:
                moving = True
        if not moving:
            continue
        s_in = s[k]
        m_in = m[k]
        s_out, m_out = grow_arc(s_in, m_in, -lo_min, hi_max, n[k])
        if m_in >= n[k]:
            s_out, m_out = 0, n[k]
        tab = np.empty((ng, m_out, 2), np.int64)
        w = np.empty((ng, 2), np.float64)
        for g in range(ng):
            shift_row(cond_tab[g, col], n[k], s_in, m_in, s_out, m_out, tab[g], w[g])
        grp_o, grp_i = _line_groups(s, m, k, n, cmask, cstride)
        outer, inner = _outer_inner(m, k)
        src = bufs[cur]
        dst = bufs[1 - cur]
        nlines = outer * inner
        if nthreads > 1 and nlines * m_out * 2 >= par_work and nlines >= nthreads:
            group_lines_par(src, dst, m_in, m_out, inner, tab, w, grp_o, grp_i, nlines, nthreads)
        else:
            group_lines(src, dst, m_in, m_out, inner, tab, w, grp_o, grp_i, 0, nlines)
        s[k] = s_out
        m[k] = m_out
        cur = 1 - cur
    return cur


@njit(**_OPTS)
def run_uniform_shift(bufs, cur, s, m, n, shifts, par_work, nthreads):
    """Shift of the whole box by ``shifts`` cells per axis (product of 1-D splits). Returns the buffer index."""
    d = n.shape[0]
    w = np.empty(2, np.float64)
    for k in range(d):
        if shifts[k] == 0.0:
            continue
        lo, f = split_shift(shifts[k], n[k])
        hi = lo + 1 if f != 0.0 else lo
        if m[k] >= n[k]:
            s_out, m_out = 0, n[k]
        else:
            s_out, m_out = grow_arc(s[k], m[k], -lo, hi, n[k])
        tab = np.empty((m_out, 2), np.int64)
        shift_row(shifts[k], n[k], s[k], m[k], s_out, m_out, tab, w)
        outer, inner = _outer_inner(m, k)
        nlines = outer * m_out
        src = bufs[cur]
        dst = bufs[1 - cur]
        if nthreads > 1 and nlines * inner * 2 >= par_work and nlines >= nthreads:
            conv_lines_par(src, dst, m[k], m_out, inner, tab, w, nlines, nthreads)
        else:
            conv_lines(src, dst, m[k], m_out, inner, tab, w, 0, nlines)
        s[k] = s_out
        m[k] = m_out
        cur = 1 - cur
    return cur


# ------------------------------------------------------------------------ decoding
@njit(**_OPTS)
def circular_mean_index(profile, nk):
    """Activity-weighted circular mean index of ``profile[:nk]`` (Eq 5.11-5.12)."""
    ssum = 0.0
    csum = 0.0
    for i in range(nk):
        ang = _TWO_PI * i / nk
        ssum += profile[i] * math.sin(ang)
        csum += profile[i] * math.cos(ang)
    mean = math.atan2(ssum, csum)
    idx = (mean % _TWO_PI) * nk / _TWO_PI
    return idx if idx < nk else 0.0


@njit(**_OPTS)
def decode_window(grid, n, centre, window, res):
    """Population vector (SPEC §1.6) of the flat grid around the cell ``centre`` into ``res``."""
    d = n.shape[0]
    nmax = 0
    for k in range(d):
        nmax = max(nmax, n[k])
    wlen = np.empty(d, np.int64)
    widx = np.empty((d, min(nmax, 2 * window + 1)), np.int64)
    for k in range(d):
        if 2 * window + 1 >= n[k]:
            wlen[k] = n[k]
            for t in range(n[k]):
                widx[k, t] = t
        else:
            wlen[k] = 2 * window + 1
            for t in range(2 * window + 1):
                widx[k, t] = (centre[k] - window + t) % n[k]
    stride = np.empty(d, np.int64)
    acc = 1
    for k in range(d - 1, -1, -1):
        stride[k] = acc
        acc *= n[k]
    prof = np.zeros((d, nmax), np.float64)
    last = d - 1
    nrows = 1
    for k in range(last):
        nrows *= wlen[k]
    idx = np.zeros(d, np.int64)
    for r in range(nrows):
        b = 0
        for k in range(last):
            b += widx[k, idx[k]] * stride[k]
        for t in range(wlen[last]):
            c = widx[last, t]
            v = np.float64(grid[b + c])
            if v != 0.0:
                prof[last, c] += v
                for k in range(last):
                    prof[k, widx[k, idx[k]]] += v
        k = last - 1
        while k >= 0:
            idx[k] += 1
            if idx[k] < wlen[k]:
                break
            idx[k] = 0
            k -= 1
    for k in range(d):
        res[k] = circular_mean_index(prof[k], n[k])


@njit(**_OPTS)
def decode_grid(grid, n, window, res):
    """Decode a whole flat grid: first argmax in C order, then :func:`decode_window`."""
    best = np.argmax(grid)
    d = n.shape[0]
    centre = np.empty(d, np.int64)
    for k in range(d - 1, -1, -1):
        centre[k] = best % n[k]
        best //= n[k]
    decode_window(grid, n, centre, window, res)


@njit(**_OPTS)
def box_argmax(buf, s, m, n):
    """Global index (per axis) of the largest cell of a box; ties go to the first in C order of the grid."""
    d = n.shape[0]
    zero = np.zeros(d, np.int64)
    off = _offset_tables(zero, n, s, m, n)
    size = box_size(m)
    best = -np.inf
    best_flat = -1
    idx = np.zeros(d, np.int64)
    for t in range(size):
        v = buf[t]
        if v >= best:
            flat = 0
            for k in range(d):
                flat += off[k, idx[k]]
            if v > best or flat < best_flat:
                best = v
                best_flat = flat
        k = d - 1
        while k >= 0:
            idx[k] += 1
            if idx[k] < m[k]:
                break
            idx[k] = 0
            k -= 1
    centre = np.empty(d, np.int64)
    for k in range(d - 1, -1, -1):
        centre[k] = best_flat % n[k]
        best_flat //= n[k]
    return centre


# ------------------------------------------------------------------------ pipeline
@njit(**_OPTS)
def pipeline(
    a, a_bits, out, ws, n,
    inj_idx, inj_val,
    do_dyn, exc, exc_w, inh, inh_w, phi,
    do_cond, cmask, cond_tab,
    do_uni, uni,
    do_decode, window, decoded,
    dense, par_work, nthreads,
):
    """Inject, dynamics (Alg 3-5 and normalisation), conditional and uniform shift, decode.

    ``a``/``out`` are flat C-order grids of shape ``n``; ``a_bits`` is ``a`` viewed as
    unsigned integers (for the occupancy scan); ``ws`` is a float64 workspace of at least
    ``3 * a.size`` cells. ``dense`` turns the locality (box) path off. Passes of at least
    ``par_work`` multiply-adds run on ``nthreads`` threads. Returns a status code.
    """
    d = n.shape[0]
    size = a.shape[0]
    proto = out[:1].copy()
    bufs = (ws[:size], ws[size:2 * size], ws[2 * size:3 * size])
    s = np.zeros(d, np.int64)
    m = n.copy()
    nmax = 0
    for k in range(d):
        nmax = max(nmax, n[k])
    # 1. the box holding every non-zero input cell and every injection
    if not dense:
        occ = np.zeros((d, nmax), np.uint8)
        anyset = mark_occupancy(a_bits, n, occ)
        for t in range(inj_idx.shape[0]):
            r = inj_idx[t]
            for k in range(d - 1, -1, -1):
                occ[k, r % n[k]] = 1
                r //= n[k]
            anyset = True
        if not anyset:
            if do_dyn:
                return STATUS_COLLAPSE
            out[:] = 0
            if do_decode:
                decode_grid(out, n, window, decoded)
            return STATUS_OK
        zero = np.zeros(d, np.int64)
        tight_box(occ, zero, n, n, s, m)
    cur = 0
    crop(a, np.zeros(d, np.int64), n, bufs[cur], s, m, n)
    if inj_idx.shape[0] > 0:
        off = _offset_tables(s, m, np.zeros(d, np.int64), n, n)
        src_box = bufs[cur]
        for t in range(inj_idx.shape[0]):
            r = inj_idx[t]
            b = 0
            for k in range(d - 1, -1, -1):
                b += off[k, r % n[k]]
                r //= n[k]
            src_box[b] += inj_val[t]
        round_to(src_box, box_size(m), proto)
    if do_dyn:
        # 2. local excitation (Alg 3): the box grows by the half-widths axis by axis
        for k in range(d):
            nt = exc_w[k]
            run_conv_pass(bufs[cur], bufs[1 - cur], s, m, k, exc[k], nt, nt // 2, nt // 2, n, par_work, nthreads)
            cur = 1 - cur
        ecur = cur
        size_e = box_size(m)
        # 3. local inhibition (Alg 4): e (*) I is only needed inside e's box
        i0 = 2
        i1 = 1 - ecur
        src = bufs[ecur]
        for k in range(d):
            dst = bufs[i0]
            run_conv_pass(src, dst, s, m, k, inh[k], inh_w[k], 0, 0, n, par_work, nthreads)
            src = dst
            i0, i1 = i1, i0
        e = bufs[ecur]
        # 4. global inhibition (Alg 5) and 5. normalisation
        total = 0.0
        for t in range(size_e):
            b = e[t] - src[t]
            c = b - phi if b >= phi else 0.0
            e[t] = c
            total += c
        if not (np.isfinite(total) and total > 0.0):
            return STATUS_COLLAPSE
        for t in range(size_e):
            e[t] = e[t] / total
        round_to(e, size_e, proto)
        cur = ecur
        # the packet is narrower than e's box: shrink to its non-zero cells
        if not dense:
            occ = np.zeros((d, nmax), np.uint8)
            mark_occupancy(e[:size_e].view(np.uint64), m, occ)
            ts = np.empty(d, np.int64)
            tm = np.empty(d, np.int64)
            tight_box(occ, s, m, n, ts, tm)
            shrink = False
            for k in range(d):
                if tm[k] < m[k]:
                    shrink = True
            if shrink:
                other = 1 - cur
                crop(bufs[cur], s, m, bufs[other], ts, tm, n)
                cur = other
                s[:] = ts
                m[:] = tm
    # 6. path integration: heading-conditional translation, then the uniform shift
    sb = (bufs[0], bufs[1])  # the result is in bufs[0] or bufs[1] here
    if do_cond:
        nc = run_cond_shift(sb, cur, s, m, n, cmask, cond_tab, par_work, nthreads)
        if nc != cur:
            round_to(sb[nc], box_size(m), proto)
        cur = nc
    if do_uni:
        nc = run_uniform_shift(sb, cur, s, m, n, uni, par_work, nthreads)
        if nc != cur:
            round_to(sb[nc], box_size(m), proto)
        cur = nc
    scatter(sb[cur], s, m, out, n)
    # 7. decoding
    if do_decode:
        centre = box_argmax(sb[cur], s, m, n)
        decode_window(out, n, centre, window, decoded)
    return STATUS_OK


@njit(**_OPTS)
def inject_grid(a, out, inj_idx, inj_val):
    """``out = a`` plus values scatter-added at flat indices, in float64, rounded once per cell."""
    for i in range(a.shape[0]):
        out[i] = a[i]
    order = np.argsort(inj_idx, kind="mergesort")
    t = 0
    k = inj_idx.shape[0]
    while t < k:
        i = inj_idx[order[t]]
        acc = np.float64(a[i])
        while t < k and inj_idx[order[t]] == i:
            acc += inj_val[order[t]]
            t += 1
        out[i] = acc
