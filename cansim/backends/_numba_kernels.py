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
``floor(s) + 1``; a heading-conditional shift gives every line the taps of its condition.
A pass reads its axis as the *leading* axis of the buffer, so each tap is a sum over
long contiguous rows (vectorised for any axis, even a last axis of 5 cells), and
writes that axis as the trailing one: after one pass per axis the buffer is back in
C order ("rotating" passes; axes without work get a copy-only pass).
Sums run in float64 in the numpy reference's order (tap after tap), and values are
rounded to the storage dtype wherever the reference stores them, so decisions at the
global-inhibition threshold match it.

Every function is compiled lazily on first call (``cache=True`` keeps the machine code
between runs). Integer arguments that may be constants are passed as ``np.int64(...)``:
numba would compile a separate variant for every literal value. ``*_par`` variants
spread a pass over threads; the caller uses them only when the pass is big enough to
repay the thread launch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from whisker_io.numba_cache import tolerate_corrupt_cache

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


@njit(inline="always", **_OPTS)
def _advance(idx, ext, top):
    """Odometer step: increment the multi-index ``idx[:top + 1]`` (last fastest) within ``ext``."""
    k = top
    while k >= 0:
        idx[k] += 1
        if idx[k] < ext[k]:
            return
        idx[k] = 0
        k -= 1


@njit(**_OPTS)
def unravel(flat, n):
    """Per-axis index of the flat C-order index ``flat`` in a grid of shape ``n``."""
    d = n.shape[0]
    idx = np.empty(d, np.int64)
    for k in range(d - 1, -1, -1):
        idx[k] = flat % n[k]
        flat //= n[k]
    return idx


@njit(**_OPTS)
def is_full(m, n):
    """Whether a box with extents ``m`` covers the whole grid of shape ``n``."""
    for k in range(n.shape[0]):
        if m[k] != n[k]:
            return False
    return True


@njit(**_OPTS)
def arc_from_occupancy(occ, n):
    """Smallest circular arc ``(start, length)`` covering the marked cells of ``occ[:n]``.

    It is the complement of the largest run of unmarked cells (circularly; among equal
    runs the first one between marked cells, then the one across the wrap). Returns
    ``(0, 0)`` when nothing is marked and ``(0, n)`` when everything is.
    """
    first = -1
    prev = -1
    best_len = 0
    best_end = 0
    for i in range(n):
        if occ[i] != 0:
            if first < 0:
                first = i
            elif i - prev - 1 > best_len:
                best_len = i - prev - 1
                best_end = i
            prev = i
    if first < 0:
        return 0, 0
    wrap = first + (n - 1 - prev)
    if wrap > best_len:
        best_len = wrap
        best_end = first
    if best_len == 0:
        return 0, n
    return best_end, n - best_len


@njit(**_OPTS)
def grow_arc(start, m, left, right, n):
    """Arc ``(start, m)`` extended by ``left`` cells below and ``right`` above (whole axis if it fills it)."""
    if m >= n or m + left + right >= n:
        return 0, n
    return (start - left) % n, m + left + right


# ----------------------------------------------------------------------- occupancy
@njit(inline="always", **_OPTS)
def _mark_row(bits, base, ml, idx, occ):
    """Mark the non-zero cells of the row at ``base`` (outer index ``idx``); returns the new marks."""
    last = occ.shape[0] - 1
    new = 0
    nonzero = False
    for i in range(ml):
        if bits[base + i] != 0:
            nonzero = True
            if occ[last, i] == 0:
                occ[last, i] = 1
                new += 1
    if nonzero:
        for k in range(last):
            if occ[k, idx[k]] == 0:
                occ[k, idx[k]] = 1
                new += 1
    return new


@njit(**_OPTS)
def mark_occupancy(bits, m, occ):
    """Mark in ``occ[k, i]`` (zeroed by the caller) every local index ``i`` of axis ``k`` holding a non-zero cell.

    ``bits`` is the box buffer viewed as unsigned integers (any non-zero bit pattern,
    -0.0 included, counts as occupied; that only widens the box). Rows spread evenly
    over the box are looked at first, then all rows in order; the scan stops as soon as
    every index is marked (spread-out activity). Returns the number of marks (0: nothing
    is occupied). The row test stays in the loops (a called helper, or one loop with a
    branch per row, keeps LLVM from vectorising it: 4-5x slower); the marking of a
    non-empty row is inlined.
    """
    d = m.shape[0]
    last = d - 1
    ml = m[last]
    nrows = box_size(m) // ml
    total = 0
    for k in range(d):
        total += m[k]
    idx = np.zeros(d, np.int64)
    marks = 0
    nsample = min(nrows, total)
    for t in range(nsample):
        r = (t * nrows) // nsample
        rr = r
        for k in range(last - 1, -1, -1):
            idx[k] = rr % m[k]
            rr //= m[k]
        marks += _mark_row(bits, r * ml, ml, idx, occ)
    if marks == total:
        return marks
    idx[:] = 0
    for r in range(nrows):
        base = r * ml
        acc = bits[base] & 0
        for i in range(ml):
            acc |= bits[base + i]
        if acc != 0:
            marks += _mark_row(bits, base, ml, idx, occ)
            if marks == total:
                break
        _advance(idx, m, last - 1)
    return marks


# ------------------------------------------------------------------- gather/scatter
@njit(**_OPTS)
def _offset_tables(s_from, m_from, s_to, m_to, n):
    """``off[k, p]``: flat offset contribution in the 'from' box of local index p of the 'to' box, -1 outside."""
    d = n.shape[0]
    mmax = max(1, m_to.max())
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
def _copy_box(src, s_src, m_src, dst, s_dst, m_dst, n, zero_outside):
    """Copy into box buffer ``dst`` (box ``s_dst, m_dst``) the cells of ``src`` (box ``s_src, m_src``)
    that lie in it; the other cells of ``dst`` become 0 (``zero_outside``) or stay as they are."""
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
                if v >= 0:
                    dst[base + p] = src[b + v]
                elif zero_outside:
                    dst[base + p] = 0.0
        elif zero_outside:
            for p in range(ml):
                dst[base + p] = 0.0
        _advance(idx, m_dst, last - 1)


@njit(**_OPTS)
def crop(src, s_src, m_src, dst, s_dst, m_dst, n):
    """Fill box buffer ``dst`` (box ``s_dst, m_dst``) from ``src`` (box ``s_src, m_src``); zero outside src."""
    d = n.shape[0]
    same = True
    for k in range(d):
        if s_src[k] != s_dst[k] or m_src[k] != m_dst[k]:
            same = False
    if same:
        for i in range(box_size(m_dst)):
            dst[i] = src[i]
        return
    _copy_box(src, s_src, m_src, dst, s_dst, m_dst, n, True)


@njit(**_OPTS)
def paste(src, s_src, m_src, dst, s_dst, m_dst, n):
    """Copy into box buffer ``dst`` (box ``s_dst, m_dst``) the cells of ``src`` (box ``s_src, m_src``)
    that lie in it; other cells of ``dst`` are left as they are."""
    _copy_box(src, s_src, m_src, dst, s_dst, m_dst, n, False)


@njit(**_OPTS)
def scatter(src, s, m, out, n):
    """Write box buffer ``src`` (box ``s, m``) into the full grid ``out`` (flat); zero elsewhere."""
    if is_full(m, n):
        for i in range(out.shape[0]):
            out[i] = src[i]
        return
    out[:] = 0
    place(src, s, m, out, n)


@njit(inline="always", **_OPTS)
def _put_box(src, from_src, s, m, out, n):
    """Write the box ``s, m`` of the flat grid ``out``: box buffer ``src``'s cells when
    ``from_src`` (a constant at each call), else zeros; other cells untouched."""
    d = n.shape[0]
    ml = m[d - 1]
    if ml == 0:
        return
    zero = np.zeros(d, np.int64)
    off = _offset_tables(zero, n, s, m, n)  # box index -> grid offset
    last = d - 1
    nrows = box_size(m) // ml
    idx = np.zeros(d, np.int64)
    for r in range(nrows):
        b = 0
        for k in range(last):
            b += off[k, idx[k]]
        base = r * ml
        if from_src:
            for p in range(ml):
                out[b + off[last, p]] = src[base + p]
        else:
            for p in range(ml):
                out[b + off[last, p]] = 0.0
        _advance(idx, m, last - 1)


@njit(**_OPTS)
def place(src, s, m, out, n):
    """Write box buffer ``src`` (box ``s, m``) into the flat grid ``out`` (other cells untouched)."""
    _put_box(src, True, s, m, out, n)


@njit(**_OPTS)
def clear_box(s, m, out, n):
    """Zero the box ``s, m`` (arc starts; lengths) of the flat grid ``out``; other cells untouched."""
    _put_box(out, False, s, m, out, n)


@njit(**_OPTS)
def round_to(buf, size, proto):
    """Round ``buf[:size]`` (float64) to the dtype of the 1-element array ``proto`` and back."""
    for i in range(size):
        proto[0] = buf[i]
        buf[i] = proto[0]


# ---------------------------------------------------------------------- line passes
_CHUNK = 256  # cells of one accumulation block (stays in L1)


@njit(inline="always", **_OPTS)
def _all_taps(tab, p, nw):
    """Whether every tap of output row ``p`` reads a source row (none outside the box, none zero)."""
    for j in range(nw):
        if tab[p, j] < 0:
            return False
    return True


@njit(inline="always", **_OPTS)
def _tap_row(src, tab, p, j, rest, r0, rc):
    """The ``rc`` cells from ``r0`` of the source row that tap ``j`` of output row ``p`` reads."""
    q = tab[p, j] * rest + r0
    return src[q:q + rc]


@njit(**_OPTS)
def _sum5(tmp, src, tab, w, p, rest, r0, rc):
    """``tmp[:rc]`` = row ``p``'s 5 taps summed in one loop, in tap order from the first product (:func:`rot_lines`)."""
    a0, a1 = _tap_row(src, tab, p, 0, rest, r0, rc), _tap_row(src, tab, p, 1, rest, r0, rc)
    a2, a3 = _tap_row(src, tab, p, 2, rest, r0, rc), _tap_row(src, tab, p, 3, rest, r0, rc)
    a4 = _tap_row(src, tab, p, 4, rest, r0, rc)
    w0, w1, w2, w3, w4 = w[0], w[1], w[2], w[3], w[4]
    for i in range(rc):
        tmp[i] = (((w0 * a0[i] + w1 * a1[i]) + w2 * a2[i]) + w3 * a3[i]) + w4 * a4[i]


@njit(**_OPTS)
def _sum7(tmp, src, tab, w, p, rest, r0, rc):
    """``tmp[:rc]`` = row ``p``'s 7 taps summed in one loop, in tap order from the first product (:func:`rot_lines`)."""
    a0, a1 = _tap_row(src, tab, p, 0, rest, r0, rc), _tap_row(src, tab, p, 1, rest, r0, rc)
    a2, a3 = _tap_row(src, tab, p, 2, rest, r0, rc), _tap_row(src, tab, p, 3, rest, r0, rc)
    a4, a5 = _tap_row(src, tab, p, 4, rest, r0, rc), _tap_row(src, tab, p, 5, rest, r0, rc)
    a6 = _tap_row(src, tab, p, 6, rest, r0, rc)
    w0, w1, w2, w3, w4, w5, w6 = w[0], w[1], w[2], w[3], w[4], w[5], w[6]
    for i in range(rc):
        tmp[i] = (((((w0 * a0[i] + w1 * a1[i]) + w2 * a2[i]) + w3 * a3[i]) + w4 * a4[i]) + w5 * a5[i]) + w6 * a6[i]


@njit(**_OPTS)
def rot_lines(src, dst, mo, rest, tab, w, r_lo, r_hi):
    """A pass along the leading axis that rotates the layout: ``src`` is (m_in, rest), ``dst`` is (rest, mo).

    ``dst[r, p] = sum_j w[j] src[tab[p, j], r]`` for r in [r_lo, r_hi): the sums run over
    contiguous rows (vectorised), and after one pass per axis the layout is back in C order.
    A block of up to :data:`_CHUNK` cells of every output row is summed first, then written
    out cell by cell (``dst`` is contiguous over a block's cells: the transposed store
    walks the block, not ``dst`` at a stride of ``mo``). A row whose 5 (or 7) taps all
    read the box is summed in one loop, the partial sum in a register (:func:`_sum5`,
    :func:`_sum7`); others tap by tap through the block. Both evaluate ``((w0 x0 + w1 x1) + w2 x2) + ...`` from the first
    product in tap order (``fastmath`` off: no contraction), so every cell has the same
    bits as summing tap after tap. (Slices instead of offset indexing let numba drop
    its negative-index checks.)
    """
    nw = w.shape[0]
    blk = np.empty((mo, _CHUNK), np.float64)
    for r0 in range(r_lo, r_hi, _CHUNK):
        rc = min(_CHUNK, r_hi - r0)
        for p in range(mo):
            tmp = blk[p]
            if nw == 5 and _all_taps(tab, p, nw):
                _sum5(tmp, src, tab, w, p, rest, r0, rc)
                continue
            if nw == 7 and _all_taps(tab, p, nw):
                _sum7(tmp, src, tab, w, p, rest, r0, rc)
                continue
            first = True  # the first tap assigns (0 + x == x): one pass less over tmp
            for j in range(nw):
                q = tab[p, j]
                if q >= 0:
                    wj = w[j]
                    row = src[q * rest + r0: q * rest + r0 + rc]
                    if first:
                        for i in range(rc):
                            tmp[i] = wj * row[i]
                        first = False
                    else:
                        for i in range(rc):
                            tmp[i] += wj * row[i]
            if first:
                for i in range(rc):
                    tmp[i] = 0.0
        out = dst[r0 * mo:(r0 + rc) * mo]
        for i in range(rc):
            for p in range(mo):
                out[i * mo + p] = blk[p, i]


_BLOCK = 2048  # cells of one block of short lines (16 kB of float64: stays in L1)
_SHORT = 64  # lines shorter take rot_short_lines (measured: ~2.5x faster at 12 cells, even at ~80, slower from ~100)


@njit(**_OPTS)
def rot_short_lines(src, dst, mo, rest, tab, w):
    """:func:`rot_lines` over all lines when the lines are short (``rest < _SHORT``).

    A pass over a small box has short rows (a 12 x 12 box: 12 cells), too short for the
    per-row loops of :func:`rot_lines` to vectorise. Here the output rows are taken in
    blocks of about :data:`_BLOCK` cells and summed tap after tap: for one tap, output
    rows ``p, p + 1, ...`` whose source rows ``tab[p, j], tab[p, j] + 1, ...`` are
    consecutive are one contiguous run of cells in ``src`` and in the block, so each tap
    is a few long vectorised loops. Every cell sums the same products in the same tap
    order from 0.0 as :func:`rot_lines` (which assigns the first product: the same value
    for the non-negative activity), so the two give the same bits.
    """
    nw = w.shape[0]
    pb = max(1, _BLOCK // max(rest, 1))
    tmp = np.empty(min(pb, mo) * rest, np.float64)
    for p0 in range(0, mo, pb):
        p1 = min(mo, p0 + pb)
        blk = tmp[:(p1 - p0) * rest]
        for i in range(blk.shape[0]):
            blk[i] = 0.0
        for j in range(nw):
            wj = w[j]
            p = p0
            while p < p1:
                q = tab[p, j]
                if q < 0:
                    p += 1
                    continue
                e = p + 1
                while e < p1 and tab[e, j] == q + (e - p):
                    e += 1
                acc = blk[(p - p0) * rest:(e - p0) * rest]
                row = src[q * rest:(q + e - p) * rest]
                for i in range(acc.shape[0]):
                    acc[i] += wj * row[i]
                p = e
        for r in range(rest):
            out = dst[r * mo + p0:r * mo + p1]
            for pp in range(p1 - p0):
                out[pp] = blk[pp * rest + r]


@njit(parallel=True, **_OPTS)
def rot_lines_par(src, dst, mo, rest, tab, w, nchunks):
    """:func:`rot_lines` split over ``nchunks`` threads."""
    for c in prange(nchunks):
        lo = rest * c // nchunks
        hi = rest * (c + 1) // nchunks
        rot_lines(src, dst, mo, rest, tab, w, lo, hi)


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
    """Rotating pass along axis k (the leading axis of ``src``'s layout) with one tap table.

    The box grows by ``left``/``right`` cells on axis k (``s``, ``m`` updated in place).
    """
    s_in = s[k]
    m_in = m[k]
    s_out, m_out = grow_arc(s_in, m_in, left, right, n[k])
    tab = conv_table(taps, nt, s_in, m_in, s_out, m_out, n[k])
    rest = box_size(m) // m_in
    if nthreads > 1 and rest * m_out * nt >= par_work and rest >= nthreads * _CHUNK:
        rot_lines_par(src, dst, m_out, rest, tab, taps[:nt], nthreads)
    elif rest < _SHORT:
        rot_short_lines(src, dst, m_out, rest, tab, taps[:nt])
    else:
        rot_lines(src, dst, m_out, rest, tab, taps[:nt], np.int64(0), rest)
    s[k] = s_out
    m[k] = m_out


# -------------------------------------------------------------------------- shifts
@njit(**_OPTS)
def rot_class_lines(src, dst, mo, rest, qtab, gw, gcls, gtab, inner, r_lo, r_hi):
    """Rotating pass where each line r has its own 2-tap shift (condition ``g(r)``).

    The conditions are grouped into classes of equal integer shift ``lo``; ``qtab[c, p, j]``
    is the source row of output row p for class c, tap j (-1 outside the box), and
    ``gw[g]`` the taps ``(1 - f, f)`` of condition g, of class ``gcls[g]``. Every row is
    summed over every class with zero weights for the other classes, which keeps the
    loops vectorised and adds only exact zeros. The condition of line r is
    ``gtab[(r // inner) % len(gtab)]`` (the condition axes are one run of the layout).
    """
    ncls = qtab.shape[0]
    glen = gtab.shape[0]
    tmp = np.empty(_CHUNK, np.float64)
    wch = np.empty((ncls, 2, _CHUNK), np.float64)
    wflat = wch.reshape(-1)
    for r0 in range(r_lo, r_hi, _CHUNK):
        rc = min(_CHUNK, r_hi - r0)
        wflat[:] = 0.0
        li = (r0 // inner) % glen
        rem = r0 % inner
        for i in range(rc):
            g = gtab[li]
            c = gcls[g]
            wch[c, 0, i] = gw[g, 0]
            wch[c, 1, i] = gw[g, 1]
            rem += 1
            if rem == inner:
                rem = 0
                li += 1
                if li == glen:
                    li = 0
        for p in range(mo):
            for i in range(rc):
                tmp[i] = 0.0
            for c in range(ncls):
                for j in range(2):
                    q = qtab[c, p, j]
                    if q >= 0:
                        row = src[q * rest + r0: q * rest + r0 + rc]
                        wv = wch[c, j]
                        for i in range(rc):
                            tmp[i] += wv[i] * row[i]
            col = dst[r0 * mo + p:]
            for i in range(rc):
                col[i * mo] = tmp[i]


@njit(parallel=True, **_OPTS)
def rot_class_lines_par(src, dst, mo, rest, qtab, gw, gcls, gtab, inner, nchunks):
    """:func:`rot_class_lines` split over ``nchunks`` threads."""
    for c in prange(nchunks):
        lo = rest * c // nchunks
        hi = rest * (c + 1) // nchunks
        rot_class_lines(src, dst, mo, rest, qtab, gw, gcls, gtab, inner, lo, hi)


@njit(**_OPTS)
def _rot_tables(tab, w, src, dst, mo, rest, par_work, nthreads):
    if nthreads > 1 and rest * mo * w.shape[0] >= par_work and rest >= nthreads * _CHUNK:
        rot_lines_par(src, dst, mo, rest, tab, w, nthreads)
    elif rest < _SHORT:
        rot_short_lines(src, dst, mo, rest, tab, w)
    else:
        rot_lines(src, dst, mo, rest, tab, w, np.int64(0), rest)


@njit(**_OPTS)
def _cond_pass(src, dst, s, m, k, n, col, cmask, cond_tab, par_work, nthreads):
    """Rotating conditional-shift pass along axis k with column ``col`` of ``cond_tab``."""
    d = n.shape[0]
    ng = cond_tab.shape[0]
    los = np.empty(ng, np.int64)
    gw = np.empty((ng, 2), np.float64)
    lo_min = n[k]
    hi_max = -n[k]
    for g in range(ng):
        lo, f = split_shift(cond_tab[g, col], n[k])
        los[g] = lo
        gw[g, 0] = 1.0 - f
        gw[g, 1] = f
        lo_min = min(lo_min, lo)
        hi_max = max(hi_max, lo + 1 if f != 0.0 else lo)
    # classes of equal integer shift
    ncls_max = hi_max - lo_min + 1
    cls_of = np.full(ncls_max, -1, np.int64)
    ncls = 0
    for g in range(ng):
        if cls_of[los[g] - lo_min] < 0:
            cls_of[los[g] - lo_min] = ncls
            ncls += 1
    gcls = np.empty(ng, np.int64)
    clo = np.empty(ncls, np.int64)
    for g in range(ng):
        c = cls_of[los[g] - lo_min]
        gcls[g] = c
        clo[c] = los[g]
    s_in = s[k]
    m_in = m[k]
    s_out, m_out = grow_arc(s_in, m_in, -lo_min, hi_max, n[k])
    qtab = np.empty((ncls, m_out, 2), np.int64)
    for c in range(ncls):
        for p in range(m_out):
            for j in range(2):
                q = (s_out + p - clo[c] - j - s_in) % n[k]
                qtab[c, p, j] = q if q < m_in else -1
    # condition index of the lines: the rotated layout of the other axes is
    # (k+1, ..., d-1, 0, ..., k-1); the run of it from the first to the last condition
    # axis gets a table of condition indices, the axes after the run repeat each entry
    cstride = np.zeros(d, np.int64)
    acc = 1
    for j in range(d - 1, -1, -1):
        if cmask[j] == 0:
            cstride[j] = acc
            acc *= n[j]
    t0 = d
    t1 = -1
    for t in range(d - 1):
        if cmask[(k + 1 + t) % d] == 0:
            t0 = min(t0, t)
            t1 = max(t1, t)
    inner = 1
    for t in range(t1 + 1, d - 1):
        inner *= m[(k + 1 + t) % d]
    glen = 1
    for t in range(t0, t1 + 1):
        glen *= m[(k + 1 + t) % d]
    gtab = np.zeros(glen, np.int64)
    if t1 >= t0:
        nrun = t1 - t0 + 1
        idx = np.zeros(nrun, np.int64)
        run_ext = np.empty(nrun, np.int64)
        for u in range(nrun):
            run_ext[u] = m[(k + 1 + t0 + u) % d]
        for li in range(glen):
            g = 0
            for u in range(nrun):
                ax = (k + 1 + t0 + u) % d
                if cmask[ax] == 0:
                    g += ((s[ax] + idx[u]) % n[ax]) * cstride[ax]
            gtab[li] = g
            _advance(idx, run_ext, nrun - 1)
    rest = box_size(m) // m_in
    if nthreads > 1 and rest * m_out * 2 * ncls >= par_work and rest >= nthreads * _CHUNK:
        rot_class_lines_par(src, dst, m_out, rest, qtab, gw, gcls, gtab, np.int64(inner), nthreads)
    else:
        rot_class_lines(src, dst, m_out, rest, qtab, gw, gcls, gtab, np.int64(inner), np.int64(0), rest)
    s[k] = s_out
    m[k] = m_out


@njit(**_OPTS)
def run_shift_cycle(bufs, cur, s, m, n, kinds, cmask, cond_tab, uni, round_after, proto, par_work, nthreads):
    """One rotating pass per axis: ``kinds[k]`` 0 = none (layout only), 1 = uniform shift by
    ``uni[k]``, 2 = conditional shift (Fig 5.7-5.11). Rounds to the storage dtype after axis
    ``round_after`` (``>= d``: only at the end) and at the end. Returns the buffer index of the result."""
    d = n.shape[0]
    col = 0
    w1 = np.ones(1, np.float64)
    w2 = np.empty(2, np.float64)
    for k in range(d):
        src = bufs[cur]
        dst = bufs[1 - cur]
        if kinds[k] == 2:
            _cond_pass(src, dst, s, m, k, n, np.int64(col), cmask, cond_tab, par_work, nthreads)
        else:
            m_in = m[k]
            rest = box_size(m) // m_in
            if kinds[k] == 1:
                lo, f = split_shift(uni[k], n[k])
                s_out, m_out = grow_arc(s[k], m_in, -lo, lo + 1 if f != 0.0 else lo, n[k])
                tab = np.empty((m_out, 2), np.int64)
                shift_row(uni[k], n[k], s[k], m_in, s_out, m_out, tab, w2)
                _rot_tables(tab, w2, src, dst, m_out, rest, par_work, nthreads)
                s[k] = s_out
                m[k] = m_out
            else:
                tab = np.empty((m_in, 1), np.int64)
                for p in range(m_in):
                    tab[p, 0] = p
                _rot_tables(tab, w1, src, dst, m_in, rest, par_work, nthreads)
        if cmask[k] != 0:
            col += 1
        cur = 1 - cur
        if k == round_after:
            round_to(bufs[cur], box_size(m), proto)
    round_to(bufs[cur], box_size(m), proto)
    return cur


# ------------------------------------------------------------------------ decoding
@njit(inline="always", **_OPTS)
def _mean_index(ssum, csum, nk):
    mean = math.atan2(ssum, csum)
    idx = (mean % _TWO_PI) * nk / _TWO_PI
    return idx if idx < nk else 0.0


@njit(**_OPTS)
def circular_mean_index(profile, nk):
    """Activity-weighted circular mean index of ``profile[:nk]`` (Eq 5.11-5.12)."""
    ssum = 0.0
    csum = 0.0
    for i in range(nk):
        if profile[i] != 0.0:  # empty cells add exact zeros; skip their sin/cos
            ang = _TWO_PI * i / nk
            ssum += profile[i] * math.sin(ang)
            csum += profile[i] * math.cos(ang)
    return _mean_index(ssum, csum, nk)


@njit(**_OPTS)
def trig_table(n):
    """``tab[k, 0, i]``, ``tab[k, 1, i]``: the sine and cosine :func:`circular_mean_index` takes for cell i of axis k."""
    d = n.shape[0]
    tab = np.zeros((d, 2, n.max()), np.float64)
    for k in range(d):
        nk = n[k]
        for i in range(nk):
            ang = _TWO_PI * i / nk
            tab[k, 0, i] = math.sin(ang)
            tab[k, 1, i] = math.cos(ang)
    return tab


@njit(**_OPTS)
def circular_mean_index_table(profile, nk, trig):
    """:func:`circular_mean_index` with the sines ``trig[0]`` and cosines ``trig[1]`` of :func:`trig_table` (same bits)."""
    ssum = 0.0
    csum = 0.0
    for i in range(nk):
        if profile[i] != 0.0:
            ssum += profile[i] * trig[0, i]
            csum += profile[i] * trig[1, i]
    return _mean_index(ssum, csum, nk)


@njit(**_OPTS)
def decode_box(buf, s, m, n, centre, window, res, trig):
    """Population vector (Eq 5.11-5.12) around the cell ``centre`` of the grid a box buffer stands for.

    ``buf`` holds the box ``(s, m)`` of a grid of shape ``n`` that is zero outside it (a
    whole grid is the box ``s = 0, m = n``). Sums the window's cells in the grid's order;
    cells outside the box would add exact zeros and are skipped, so every box of the same
    grid gives the same bits. ``trig`` is :func:`trig_table` of ``n``, or an empty array
    to compute the sines and cosines here.
    """
    d = n.shape[0]
    nmax = n.max()
    wmax = min(nmax, 2 * window + 1)
    wlen = np.empty(d, np.int64)
    widx = np.empty((d, wmax), np.int64)
    loc = np.empty((d, wmax), np.int64)  # offset in the box of window index t of axis k, -1 outside
    stride = 1
    for k in range(d - 1, -1, -1):
        if 2 * window + 1 >= n[k]:
            wlen[k] = n[k]
            for t in range(n[k]):
                widx[k, t] = t
        else:
            wlen[k] = 2 * window + 1
            for t in range(2 * window + 1):
                widx[k, t] = (centre[k] - window + t) % n[k]
        for t in range(wlen[k]):
            q = (widx[k, t] - s[k]) % n[k]
            loc[k, t] = q * stride if q < m[k] else -1
        stride *= m[k]
    prof = np.zeros((d, nmax), np.float64)
    last = d - 1
    nrows = 1
    for k in range(last):
        nrows *= wlen[k]
    idx = np.zeros(d, np.int64)
    for r in range(nrows):
        b = 0
        for k in range(last):
            v = loc[k, idx[k]]
            if v < 0:
                b = -1
                break
            b += v
        if b >= 0:
            rowsum = 0.0
            for t in range(wlen[last]):
                o = loc[last, t]
                if o >= 0:
                    v = np.float64(buf[b + o])
                    prof[last, widx[last, t]] += v
                    rowsum += v
            if rowsum != 0.0:
                for k in range(last):
                    prof[k, widx[k, idx[k]]] += rowsum
        _advance(idx, wlen, last - 1)
    for k in range(d):
        if trig.shape[0] > 0:
            res[k] = circular_mean_index_table(prof[k], n[k], trig[k])
        else:
            res[k] = circular_mean_index(prof[k], n[k])


@njit(**_OPTS)
def no_trig():
    """The empty sine/cosine table: :func:`decode_box` without :func:`trig_table` (computes the sines itself).

    A fresh (writable) array, not a module constant: numba types a global array as
    read-only, which would compile every function taking it a second time for the
    writable tables of :func:`trig_table`.
    """
    return np.empty((0, 2, 1), np.float64)


@njit(**_OPTS)
def decode_window(grid, n, centre, window, res):
    """Population vector (Eq 5.11-5.12) of the flat grid around the cell ``centre`` into ``res``."""
    decode_box(grid, np.zeros(n.shape[0], np.int64), n, n, centre, window, res, no_trig())


@njit(**_OPTS)
def decode_grid(grid, n, window, res):
    """Decode a whole flat grid: first argmax in C order, then :func:`decode_window`."""
    best = np.int64(0)
    for i in range(grid.shape[0]):
        if grid[i] > grid[best]:
            best = i
    decode_window(grid, n, unravel(best, n), window, res)


@njit(**_OPTS)
def box_argmax(buf, s, m, n):
    """Flat grid index of the largest cell of a box; ties go to the first in C order of the grid."""
    d = n.shape[0]
    size = box_size(m)
    best = buf[0]
    first = 0
    for t in range(size):
        if buf[t] > best:
            best = buf[t]
            first = t
    if is_full(m, n):  # box index == grid index: the first maximum is the answer
        return first
    zero = np.zeros(d, np.int64)
    off = _offset_tables(zero, n, s, m, n)
    last = d - 1
    ml = m[last]
    best_flat = -1
    idx = np.zeros(d, np.int64)
    for r in range(size // ml):
        base = r * ml
        for p in range(ml):
            if buf[base + p] == best:
                flat = off[last, p]
                for k in range(last):
                    flat += off[k, idx[k]]
                if best_flat < 0 or flat < best_flat:
                    best_flat = flat
        _advance(idx, m, last - 1)
    return best_flat


# ------------------------------------------------------------------------ pipeline
@njit(**_OPTS)
def global_inhibit(e, inhibition, out, n, phi):
    """Alg 4's subtraction and Alg 5 over the first ``n`` cells; returns the total.

    ``out[t] = max(e[t] - inhibition[t] - phi, 0)`` with cells below phi set to 0
    (``out`` may be ``e``).
    """
    total = 0.0
    for t in range(n):
        b = e[t] - inhibition[t]
        c = b - phi if b >= phi else 0.0
        out[t] = c
        total += c
    return total


@njit(**_OPTS)
def occupied_box(bits, s, m, n, inj_idx, ts, tm):
    """The tight box ``(ts, tm)`` of the non-zero cells of a box buffer and of the injected cells.

    ``bits`` is the buffer of box ``(s, m)`` (a whole grid: ``s = 0``, ``m = n``) viewed as
    unsigned integers; ``inj_idx`` are flat grid indices. The arcs are found in grid
    coordinates, so every box holding the same non-zero cells gives the same box.
    Returns False when nothing is occupied (``ts``, ``tm`` untouched).
    """
    d = n.shape[0]
    nmax = n.max()
    occ = np.zeros((d, nmax), np.uint8)
    anyset = mark_occupancy(bits, m, occ) > 0
    grid = np.zeros((d, nmax), np.uint8)
    for k in range(d):
        for p in range(m[k]):
            if occ[k, p] != 0:
                grid[k, (s[k] + p) % n[k]] = 1
    for t in range(inj_idx.shape[0]):
        r = inj_idx[t]
        for k in range(d - 1, -1, -1):
            grid[k, r % n[k]] = 1
            r //= n[k]
        anyset = True
    if anyset:
        for k in range(d):
            a0, l0 = arc_from_occupancy(grid[k], n[k])
            ts[k] = a0
            tm[k] = l0
    return anyset


@njit(**_OPTS)
def start_box(a, a_bits, out, ws, n, inj_idx, dense):
    """Step 1 of :func:`pipeline`: the box of a flat grid's non-zero cells and injections, cropped.

    Returns ``(occupied, proto, bufs, s, m)``: ``bufs`` are three float64 box buffers of
    ``ws`` (at least ``3 * a.size`` cells), ``bufs[0]`` holding the box ``(s, m)`` (the
    whole grid when ``dense``) unless nothing is occupied; ``proto`` is a 1-element
    array of the storage dtype (``out``'s).
    """
    d = n.shape[0]
    size = a.shape[0]
    proto = out[:1].copy()
    bufs = (ws[:size], ws[size:2 * size], ws[2 * size:3 * size])
    s = np.zeros(d, np.int64)
    m = n.copy()
    zero = np.zeros(d, np.int64)
    if not dense and not occupied_box(a_bits, zero, n, n, inj_idx, s, m):
        return False, proto, bufs, s, m
    crop(a, zero, n, bufs[0], s, m, n)
    return True, proto, bufs, s, m


@njit(**_OPTS)
def box_inject(box, s, m, n, inj_idx, inj_val, proto):
    """Add the injections ``inj_val`` at flat grid indices ``inj_idx`` (inside the box ``s, m`` by
    construction) to the box buffer ``box``, then round the box to the working dtype (``proto``)."""
    d = n.shape[0]
    for t in range(inj_idx.shape[0]):
        r = inj_idx[t]
        b = 0
        stride = 1
        for k in range(d - 1, -1, -1):
            b += ((r % n[k] - s[k]) % n[k]) * stride
            stride *= m[k]
            r //= n[k]
        box[b] += inj_val[t]
    round_to(box, box_size(m), proto)


@njit(**_OPTS)
def box_inject_excite_inhibit(bufs, cur, s, m, n, inj_idx, inj_val, exc, exc_w, inh, inh_w, phi, proto,
                              par_work, nthreads):
    """First half of :func:`box_step`: injection, excitation (Alg 3), inhibition (Alg 4) and the
    subtraction of global inhibition (Alg 5), written into the excitation's box buffer.

    Returns ``(index of the buffer holding c = max(e - e (*) I - phi, 0), sum of c in box order)``;
    ``s``, ``m`` become the excitation's box. Nothing is normalised yet.
    """
    d = n.shape[0]
    if inj_idx.shape[0] > 0:
        box_inject(bufs[cur], s, m, n, inj_idx, inj_val, proto)
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
    no_growth = np.int64(0)
    src = bufs[ecur]
    for k in range(d):
        dst = bufs[i0]
        run_conv_pass(src, dst, s, m, k, inh[k], inh_w[k], no_growth, no_growth, n, par_work, nthreads)
        src = dst
        i0, i1 = i1, i0
    e = bufs[ecur]
    # 4. global inhibition (Alg 5)
    total = global_inhibit(e, src, e, size_e, phi)
    return ecur, total


@njit(**_OPTS)
def box_normalise(bufs, cur, s, m, n, total, proto, dense):
    """5. normalisation of :func:`box_step`: ``c / total`` rounded to the storage dtype, and the box
    shrunk to its non-zero cells (unless ``dense``). Returns ``(occupied, buffer index)``;
    not occupied (every cell 0) leaves ``s``, ``m`` as they were."""
    d = n.shape[0]
    size_e = box_size(m)
    e = bufs[cur]
    for t in range(size_e):
        e[t] = e[t] / total
    round_to(e, size_e, proto)
    # the packet is narrower than e's box: shrink to its non-zero cells
    if not dense:
        ts = np.empty(d, np.int64)
        tm = np.empty(d, np.int64)
        if not occupied_box(e[:size_e].view(np.uint64), s, m, n, np.empty(0, np.int64), ts, tm):
            return False, cur
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
    return True, cur


@njit(**_OPTS)
def box_shift(bufs, cur, s, m, n, do_cond, cmask, cond_tab, do_uni, uni, proto, par_work, nthreads):
    """6. path integration of :func:`box_step`: heading-conditional translation, then the uniform
    shift (Fig 5.7-5.11). The box buffer is ``bufs[cur]`` (0 or 1); returns the result's index."""
    d = n.shape[0]
    sb = (bufs[0], bufs[1])  # the result is in bufs[0] or bufs[1] here
    kinds = np.zeros(d, np.int64)
    col = 0
    last_cond = -1
    for k in range(d):
        if do_cond and cmask[k] != 0:
            for g in range(cond_tab.shape[0]):
                if cond_tab[g, col] != 0.0:
                    kinds[k] = 2
                    last_cond = k
                    break
            col += 1
    first_uni = d
    for k in range(d - 1, -1, -1):
        if do_uni and uni[k] != 0.0:
            first_uni = k
    if first_uni < d and (last_cond > first_uni or (last_cond >= 0 and kinds[first_uni] != 0)):
        # the uniform shift touches an earlier or a shifted axis: one cycle each, as the reference
        cur = run_shift_cycle(sb, cur, s, m, n, kinds, cmask, cond_tab, uni, np.int64(d), proto, par_work, nthreads)
        last_cond = -1
        kinds[:] = 0
    for k in range(d):
        if do_uni and uni[k] != 0.0 and kinds[k] == 0:
            kinds[k] = 1
    moving = False
    for k in range(d):
        if kinds[k] != 0:
            moving = True
    if moving:
        cur = run_shift_cycle(sb, cur, s, m, n, kinds, cmask, cond_tab, uni, np.int64(last_cond), proto, par_work, nthreads)
    return cur


@njit(**_OPTS)
def box_step(
    bufs, cur, s, m, n,
    inj_idx, inj_val,
    do_dyn, exc, exc_w, inh, inh_w, phi,
    do_cond, cmask, cond_tab,
    do_uni, uni,
    proto, dense, par_work, nthreads,
):
    """One step on a box: inject, dynamics (Alg 3-5 and normalisation), conditional and uniform shift.

    The activity is ``bufs[cur]``, a box buffer of box ``(s, m)`` holding every non-zero
    cell and every injected cell (float64 values of the storage dtype, whose 1-element
    array is ``proto``). ``s``, ``m`` are updated in place to the result's box. Returns
    ``(status, index of the buffer holding the result)``; the result is in ``bufs[0]``
    or ``bufs[1]``, ``bufs[2]`` is scratch. The three phases are
    :func:`box_inject_excite_inhibit`, :func:`box_normalise` and :func:`box_shift`
    (the multi-packet step, :mod:`cansim.backends._numba_packets`, runs them per packet).
    """
    if do_dyn:
        cur, total = box_inject_excite_inhibit(bufs, cur, s, m, n, inj_idx, inj_val, exc, exc_w, inh, inh_w, phi,
                                               proto, par_work, nthreads)
        if not (np.isfinite(total) and total > 0.0):
            return STATUS_COLLAPSE, cur
        occupied, cur = box_normalise(bufs, cur, s, m, n, total, proto, dense)
    elif inj_idx.shape[0] > 0:
        box_inject(bufs[cur], s, m, n, inj_idx, inj_val, proto)
    return STATUS_OK, box_shift(bufs, cur, s, m, n, do_cond, cmask, cond_tab, do_uni, uni, proto, par_work, nthreads)


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
    # 1. the box holding every non-zero input cell and every injection
    occupied, proto, bufs, s, m = start_box(a, a_bits, out, ws, n, inj_idx, dense)
    if not occupied:
        if do_dyn:
            return STATUS_COLLAPSE
        out[:] = 0
        if do_decode:
            decode_grid(out, n, window, decoded)
        return STATUS_OK
    status, cur = box_step(bufs, np.int64(0), s, m, n, inj_idx, inj_val, do_dyn, exc, exc_w, inh, inh_w, phi,
                           do_cond, cmask, cond_tab, do_uni, uni, proto, dense, par_work, nthreads)
    if status != STATUS_OK:
        return status
    scatter(bufs[cur], s, m, out, n)
    # 7. decoding
    if do_decode:
        decode_box(bufs[cur], s, m, n, unravel(box_argmax(bufs[cur], s, m, n), n), window, decoded, no_trig())
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


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
