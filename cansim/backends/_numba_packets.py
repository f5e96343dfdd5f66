"""Several packets as fast as one: the generic numba step on one box per packet (issue 26, item 2).

The generic pipeline (:mod:`cansim.backends._numba_kernels`) runs a step on the smallest
box holding every non-zero cell; with two packets far apart that box covers most of the
grid. Here the non-zero cells (and the injected ones) are split into *packets* whose
boxes are far enough apart that no pass of the step can carry activity from one to the
other, and each packet's step runs on its own box. The result is the one-box step's,
bit for bit:

- every output cell of a pass is a sum, tap after tap, of products of input cells; a
  cell of another packet's box would contribute only exact zeros (the activity is
  >= 0), which do not change a sum, so each cell gets the same value;
- the normalisation total (Alg 5) is summed over the non-zero cells in the order the
  one-box step sums them (C order of the box the union's excitation fills), found by
  sorting the cells by their index in that box;
- decoding (Eq 5.11-5.12) takes the first largest cell of the grid and sums the window
  row by row in grid order, reading each cell from whichever box holds it.

Two packets are computed apart when, on some axis, the empty gaps between their
occupied arcs (both ways round) are at least :func:`separations`' margin: twice the
excitation half-width, plus the inhibition half-width, plus how far the step's shifts
can move one packet relative to the other, plus one. Packets closer than that are
merged into one box (their union's box, as before). A single packet runs the one-box
step unchanged. See :func:`plan_packets`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cansim.backends._numba_kernels import (
    STATUS_COLLAPSE, STATUS_OK, _advance, _offset_tables, arc_from_occupancy, box_argmax, box_inject_excite_inhibit,
    box_normalise, box_shift, box_size, box_step, circular_mean_index, circular_mean_index_table, clear_box, crop,
    decode_box, grow_arc, is_full, mark_occupancy, no_trig, paste, place, scatter, split_shift, trig_table, unravel,
)
from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["packets_run", "packets_step", "plan_packets", "separations"]

_OPTS = dict(cache=True, fastmath=False, nogil=True)

#: Most packets (regions of a box, injected cells) one step keeps apart; with more the step
#: runs on one box holding them all (the one-box step).
MAX_ITEMS = 32

#: Boxes a region list of :func:`packets_step` holds (a grid's non-zero cells, one box per
#: packet); more packets are held by one box round them all.
MAX_REGIONS = 8

#: :func:`packets_step`'s status for a region list with a start outside ``[0, n)`` or a
#: length outside ``[0, n]`` on some axis (nothing was read or written).
STATUS_BAD_REGIONS = 7


@njit(**_OPTS)
def _regions_valid(regions, n):
    """Whether every box of ``regions[0]`` and ``regions[1]`` has its starts in ``[0, n)`` and its
    lengths in ``[0, n]``."""
    d = n.shape[0]
    for i in range(2):
        for j in range(regions.shape[1]):
            for k in range(d):
                if not (0 <= regions[i, j, 0, k] < n[k] and 0 <= regions[i, j, 1, k] <= n[k]):
                    return False
    return True


# ------------------------------------------------------------------------ margins
@njit(**_OPTS)
def separations(exc_w, inh_w, n, do_cond, cmask, cond_tab, do_uni, uni, gap, spread):
    """Per axis k, the empty cells ``gap[k]`` two packets' occupied arcs need between them (both ways
    round) to be computed apart, and ``spread[k]``: how many cells a packet's box grows by in the
    step's shifts (the conditional shifts' range of integer parts, plus one for a uniform shift)."""
    d = n.shape[0]
    col = 0
    for k in range(d):
        sp = 0
        if do_cond and cmask[k] != 0:
            lo_min = n[k]
            hi_max = -n[k]
            for g in range(cond_tab.shape[0]):
                lo, f = split_shift(cond_tab[g, col], n[k])
                lo_min = min(lo_min, lo)
                hi_max = max(hi_max, lo + 1 if f != 0.0 else lo)
            if hi_max >= lo_min:
                sp += hi_max - lo_min
            col += 1
        if do_uni and uni[k] != 0.0:
            sp += 1
        spread[k] = sp
        gap[k] = 2 * (exc_w[k] // 2) + inh_w[k] // 2 + sp + 1


@njit(**_OPTS)
def least_gaps(exc_w, inh_w, gap):
    """:func:`separations`' margins without the shifts' part (a lower bound of them): a packet with
    no gap this wide cannot be cut by any step's margin, so the one-packet test needs no shifts."""
    for k in range(exc_w.shape[0]):
        gap[k] = 2 * (exc_w[k] // 2) + inh_w[k] // 2 + 1


@njit(**_OPTS)
def apart(as_, am, bs, bm, n, gap):
    """Whether two boxes' arcs leave at least ``gap[k]`` empty cells both ways round on some axis k."""
    for k in range(n.shape[0]):
        if am[k] >= n[k] or bm[k] >= n[k]:
            continue
        d1 = (bs[k] - as_[k]) % n[k]
        if d1 >= am[k] and d1 + bm[k] <= n[k]:
            if d1 - am[k] >= gap[k] and n[k] - d1 - bm[k] >= gap[k]:
                return True
    return False


# ---------------------------------------------------------------------- occupancy
@njit(**_OPTS)
def region_occupancy(bits, s, m, n, rs, rm, occ):
    """Mark in ``occ[k, g]`` (grid index g of axis k; zeroed by the caller) the non-zero cells of the
    region ``(rs, rm)`` of the box buffer ``bits`` (box ``(s, m)``, viewed as unsigned integers).
    Returns whether any cell is non-zero."""
    d = n.shape[0]
    off = _offset_tables(s, m, rs, rm, n)
    last = d - 1
    ml = rm[last]
    nrows = box_size(rm) // ml
    idx = np.zeros(d, np.int64)
    anyset = False
    for r in range(nrows):
        b = 0
        ok = True
        for k in range(last):
            v = off[k, idx[k]]
            if v < 0:
                ok = False
                break
            b += v
        if ok:
            nz = False
            for p in range(ml):
                v = off[last, p]
                if v >= 0 and bits[b + v] != 0:
                    occ[last, (rs[last] + p) % n[last]] = 1
                    nz = True
            if nz:
                anyset = True
                for k in range(last):
                    occ[k, (rs[k] + idx[k]) % n[k]] = 1
        _advance(idx, rm, last - 1)
    return anyset


@njit(**_OPTS)
def _segments(occ_k, start, length, nk, gap_k, seg_s, seg_m):
    """Split the arc ``(start, length)`` at every run of at least ``gap_k`` unmarked cells of ``occ_k``;
    writes the occupied segments' arcs and returns their number (1: no cut)."""
    nseg = 0
    p = 0
    while p < length:
        while p < length and occ_k[(start + p) % nk] == 0:
            p += 1
        if p >= length:
            break
        a = p
        last_occ = p
        p += 1
        while p < length:
            if occ_k[(start + p) % nk] != 0:
                last_occ = p
                p += 1
            elif p - last_occ >= gap_k:  # a run of gap_k empty cells
                break
            else:
                p += 1
        seg_s[nseg] = (start + a) % nk
        seg_m[nseg] = last_occ - a + 1
        nseg += 1
        p = last_occ + 1
    return nseg


@njit(**_OPTS)
def _one_box_of(n, inj_idx, gap, cl_s, cl_m, union_occ):
    """The rest of :func:`_one_packet` once ``union_occ`` holds the occupied grid indices: their
    arcs leave no gap to cut at and every injected cell lies inside them. Then writes the one
    box (the arcs) and marks the injected cells; returns whether it is one box."""
    d = n.shape[0]
    for k in range(d):
        a0, l0 = arc_from_occupancy(union_occ[k], n[k])
        cl_s[0, k] = a0
        cl_m[0, k] = l0
        if l0 < n[k] and l0 > gap[k] and _has_gap(union_occ[k], a0, l0, n[k], gap[k]):
            return False
    for t in range(inj_idx.shape[0]):
        r = inj_idx[t]
        for k in range(d - 1, -1, -1):
            if (r % n[k] - cl_s[0, k]) % n[k] >= cl_m[0, k]:
                return False
            r //= n[k]
    for t in range(inj_idx.shape[0]):  # inside the arcs: they do not change them
        r = inj_idx[t]
        for k in range(d - 1, -1, -1):
            union_occ[k, r % n[k]] = 1
            r //= n[k]
    return True


@njit(**_OPTS)
def _mark_grid(bits, s, m, n, loc, occ):
    """Mark in ``occ[k, g]`` the grid index g of axis k of every occupied cell of the box buffer
    ``bits`` (box ``s, m``, viewed as unsigned integers; :func:`mark_occupancy`, ``loc`` its
    box-local scratch, zeroed here). Returns whether any cell is occupied."""
    loc[:] = 0
    if mark_occupancy(bits, m, loc) == 0:
        return False
    for k in range(n.shape[0]):
        for p in range(m[k]):
            if loc[k, p] != 0:
                occ[k, (s[k] + p) % n[k]] = 1
    return True


@njit(**_OPTS)
def _one_packet(bits, s, m, n, inj_idx, gap, cl_s, cl_m, union_occ):
    """The common case of :func:`plan_packets`, decided without its tables: one box whose occupied
    cells leave no gap to cut at, and every injected cell inside their arcs. Then writes the
    one box (the union's arcs) and returns True; otherwise False (``union_occ`` is dirty)."""
    loc = np.empty((n.shape[0], n.max()), np.uint8)
    if not _mark_grid(bits, s, m, n, loc, union_occ):
        return False
    return _one_box_of(n, inj_idx, gap, cl_s, cl_m, union_occ)


@njit(**_OPTS)
def _one_packet_sources(bits, src_off, src_s, src_m, nsrc, n, inj_idx, gap, cl_s, cl_m, union_occ):
    """:func:`_one_packet` for the non-zero cells of ``nsrc`` boxes (laid out as in
    :func:`plan_packets`): the same test on the union of their occupied cells."""
    loc = np.empty((n.shape[0], n.max()), np.uint8)
    occupied = False
    for j in range(nsrc):
        if _mark_grid(bits[src_off[j]:src_off[j + 1]], src_s[j], src_m[j], n, loc, union_occ):
            occupied = True
    if not occupied:
        return False
    return _one_box_of(n, inj_idx, gap, cl_s, cl_m, union_occ)


@njit(**_OPTS)
def _has_gap(occ_k, start, length, nk, gap_k):
    """Whether the arc ``(start, length)`` holds a run of at least ``gap_k`` unmarked cells of ``occ_k``."""
    run = 0
    for p in range(length):
        if occ_k[(start + p) % nk] == 0:
            run += 1
            if run >= gap_k:
                return True
        else:
            run = 0
    return False


@njit(**_OPTS)
def plan_packets(bits, src_off, src_s, src_m, nsrc, n, inj_idx, gap, cl_s, cl_m, union_occ):
    """Split the non-zero cells of ``nsrc`` box buffers and the injected cells into packets.

    ``bits`` holds the boxes one after another (box j at ``src_off[j]``, arcs ``src_s[j]``,
    ``src_m[j]``), viewed as unsigned integers. Each box is cut along axes where its
    occupied cells leave a gap of at least ``gap[k]`` empty cells (recursively, on the cut
    regions); the regions and the injected cells are then merged while two of them are not
    :func:`apart`. ``union_occ`` (zeroed by the caller) receives every occupied grid index
    per axis (the one-box step's occupancy). Writes the packets' arcs (from their occupied
    cells) to ``cl_s``, ``cl_m`` (at least :data:`MAX_ITEMS` rows) and returns their number:
    0 when nothing is occupied, 1 when the step runs on one box (``cl_s[0]``, ``cl_m[0]``,
    the union's arcs).
    """
    if nsrc == 1 and _one_packet(bits[src_off[0]:src_off[1]], src_s[0], src_m[0], n, inj_idx, gap, cl_s, cl_m,
                                 union_occ):
        return 1
    union_occ[:] = 0
    d = n.shape[0]
    nmax = n.max()
    it_occ = np.zeros((MAX_ITEMS, d, nmax), np.uint8)
    nit = 0
    overflow = False
    stack_s = np.empty((MAX_ITEMS, d), np.int64)
    stack_m = np.empty((MAX_ITEMS, d), np.int64)
    seg_s = np.empty(nmax, np.int64)
    seg_m = np.empty(nmax, np.int64)
    occ = np.zeros((d, nmax), np.uint8)
    loc = np.empty((d, nmax), np.uint8)
    ts = np.empty(d, np.int64)
    tm = np.empty(d, np.int64)
    for j in range(nsrc):
        sb = bits[src_off[j]:src_off[j + 1]]
        s = src_s[j]
        m = src_m[j]
        # the whole box: mark_occupancy (box-local), mapped to the grid
        occ[:] = 0
        if not _mark_grid(sb, s, m, n, loc, occ):
            continue
        nst = 0
        first = True
        while True:
            if not first:
                if nst == 0:
                    break
                nst -= 1
                occ[:] = 0
                if not region_occupancy(sb, s, m, n, stack_s[nst], stack_m[nst], occ):
                    continue
            first = False
            for k in range(d):
                a0, l0 = arc_from_occupancy(occ[k], n[k])
                ts[k] = a0
                tm[k] = l0
            cut = -1
            nseg = 1
            if not overflow:
                for k in range(d):
                    if tm[k] < n[k] and tm[k] > gap[k]:
                        nseg = _segments(occ[k], ts[k], tm[k], n[k], gap[k], seg_s, seg_m)
                        if nseg > 1:
                            cut = k
                            break
            if cut >= 0 and nst + nseg <= MAX_ITEMS and nit + nst + nseg <= MAX_ITEMS:
                for q in range(nseg):
                    stack_s[nst] = ts
                    stack_m[nst] = tm
                    stack_s[nst, cut] = seg_s[q]
                    stack_m[nst, cut] = seg_m[q]
                    nst += 1
                continue
            if nit >= MAX_ITEMS:
                overflow = True
            else:
                it_occ[nit] = occ
                nit += 1
            for k in range(d):
                for g in range(n[k]):
                    if occ[k, g] != 0:
                        union_occ[k, g] = 1
    # the injected cells: one packet each (merged below with what they touch)
    for t in range(inj_idx.shape[0]):
        r = inj_idx[t]
        if nit >= MAX_ITEMS:
            overflow = True
        else:
            it_occ[nit] = 0
        for k in range(d - 1, -1, -1):
            g = r % n[k]
            union_occ[k, g] = 1
            if nit < MAX_ITEMS:
                it_occ[nit, k, g] = 1
            r //= n[k]
        if nit < MAX_ITEMS:
            nit += 1
    if nit == 0:
        return 0
    if overflow or nit == 1:
        for k in range(d):
            a0, l0 = arc_from_occupancy(union_occ[k], n[k])
            cl_s[0, k] = a0
            cl_m[0, k] = l0
        return 1
    # merge packets that are not apart, with their merged arcs, until all are
    k_cl = nit
    cocc = it_occ[:nit].copy()
    for i in range(nit):
        for k in range(d):
            a0, l0 = arc_from_occupancy(cocc[i, k], n[k])
            cl_s[i, k] = a0
            cl_m[i, k] = l0
    merged = True
    while merged and k_cl > 1:
        merged = False
        for i in range(k_cl):
            for j in range(i + 1, k_cl):
                if not apart(cl_s[i], cl_m[i], cl_s[j], cl_m[j], n, gap):
                    for k in range(d):
                        for g in range(n[k]):
                            if cocc[j, k, g] != 0:
                                cocc[i, k, g] = 1
                        a0, l0 = arc_from_occupancy(cocc[i, k], n[k])
                        cl_s[i, k] = a0
                        cl_m[i, k] = l0
                    last = k_cl - 1
                    if j != last:
                        cocc[j] = cocc[last]
                        cl_s[j] = cl_s[last]
                        cl_m[j] = cl_m[last]
                    k_cl -= 1
                    merged = True
                    break
            if merged:
                break
    if k_cl == 1:
        for k in range(d):
            a0, l0 = arc_from_occupancy(union_occ[k], n[k])
            cl_s[0, k] = a0
            cl_m[0, k] = l0
    return k_cl


# ------------------------------------------------------------------------ decoding
@njit(**_OPTS)
def decode_boxes(data, offs, bs, bm, nb, n, centre, window, res, trig):
    """:func:`cansim.backends._numba_kernels.decode_box` over ``nb`` disjoint boxes of one grid
    (box i at ``data[offs[i]:]``, arcs ``bs[i]``, ``bm[i]``; zero elsewhere): the window is
    summed in the same order, each cell read from the box holding it, so the bits equal
    decoding any one box holding every non-zero cell."""
    d = n.shape[0]
    nmax = n.max()
    wmax = min(nmax, 2 * window + 1)
    wlen = np.empty(d, np.int64)
    widx = np.empty((d, wmax), np.int64)
    loc = np.empty((nb, d, wmax), np.int64)
    for k in range(d):
        if 2 * window + 1 >= n[k]:
            wlen[k] = n[k]
            for t in range(n[k]):
                widx[k, t] = t
        else:
            wlen[k] = 2 * window + 1
            for t in range(2 * window + 1):
                widx[k, t] = (centre[k] - window + t) % n[k]
    for i in range(nb):
        stride = 1
        for k in range(d - 1, -1, -1):
            for t in range(wlen[k]):
                q = (widx[k, t] - bs[i, k]) % n[k]
                loc[i, k, t] = q * stride if q < bm[i, k] else -1
            stride *= bm[i, k]
    prof = np.zeros((d, nmax), np.float64)
    last = d - 1
    nrows = 1
    for k in range(last):
        nrows *= wlen[k]
    idx = np.zeros(d, np.int64)
    base = np.empty(nb, np.int64)
    for r in range(nrows):
        inrow = False
        for i in range(nb):
            b = 0
            for k in range(last):
                v = loc[i, k, idx[k]]
                if v < 0:
                    b = -1
                    break
                b += v
            base[i] = b
            if b >= 0:
                inrow = True
        if inrow:
            rowsum = 0.0
            for t in range(wlen[last]):
                for i in range(nb):
                    o = loc[i, last, t]
                    if base[i] >= 0 and o >= 0:
                        v = np.float64(data[offs[i] + base[i] + o])
                        prof[last, widx[last, t]] += v
                        rowsum += v
                        break
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
def argmax_boxes(data, offs, bs, bm, nb, n):
    """Flat grid index of the largest cell over ``nb`` disjoint boxes; ties go to the first in grid C order."""
    best = -1.0
    flat = -1
    for i in range(nb):
        buf = data[offs[i]:offs[i] + box_size(bm[i])]
        v = buf[0]
        for t in range(buf.shape[0]):
            if buf[t] > v:
                v = buf[t]
        f = box_argmax(buf, bs[i], bm[i], n)
        if flat < 0 or v > best or (v == best and f < flat):
            best = v
            flat = f
    return flat


# ------------------------------------------------------------------- the step
@njit(**_OPTS)
def multi_step(data, src_off, src_s, src_m, nsrc, n, k_cl, cl_s, cl_m, union_occ, spread,
               inj_idx, inj_val, exc, exc_w, inh, inh_w, phi,
               do_cond, cmask, cond_tab, do_uni, uni, proto, ws, par_work, nthreads,
               res_off, res_s, res_m):
    """One step on ``k_cl >= 2`` packets (:func:`plan_packets`): each packet's box is filled from the
    source boxes, stepped with the phases of :func:`cansim.backends._numba_kernels.box_step`,
    normalised by the one-box step's total. The results are left in ``ws`` as boxes
    ``ws[res_off[i]:]``, arcs ``res_s[i]``, ``res_m[i]``. Returns ``(status, number of boxes)``
    (a packet whose cells all fell below the global inhibition is dropped), or ``(-1, 0)``
    when the packets' boxes would not fit in ``ws`` (the caller runs the one-box step).
    """
    d = n.shape[0]
    size = 1
    for k in range(d):
        size *= n[k]
    # workspace: three buffers per packet, as large as its box gets during the step
    bound = np.empty(k_cl, np.int64)
    slot = np.empty(k_cl + 1, np.int64)
    slot[0] = 0
    for i in range(k_cl):
        b = 1
        for k in range(d):
            b *= min(n[k], cl_m[i, k] + 2 * (exc_w[k] // 2) + spread[k])
        bound[i] = b
        slot[i + 1] = slot[i] + 3 * b
    if slot[k_cl] > ws.shape[0]:
        return -1, 0
    s = cl_s[:k_cl].copy()
    m = cl_m[:k_cl].copy()
    cur = np.zeros(k_cl, np.int64)
    # which packet each injected cell belongs to (every one is in exactly one box)
    inj_cl = np.full(inj_idx.shape[0], -1, np.int64)
    cell = np.empty(d, np.int64)
    for t in range(inj_idx.shape[0]):
        r = inj_idx[t]
        for k in range(d - 1, -1, -1):
            cell[k] = r % n[k]
            r //= n[k]
        for i in range(k_cl):
            inside = True
            for k in range(d):
                if (cell[k] - s[i, k]) % n[k] >= m[i, k]:
                    inside = False
                    break
            if inside:
                inj_cl[t] = i
                break
    # 1. fill each packet's box, inject, excite, inhibit
    for i in range(k_cl):
        base = slot[i]
        bb = bound[i]
        bufs = (ws[base:base + bb], ws[base + bb:base + 2 * bb], ws[base + 2 * bb:base + 3 * bb])
        b0 = bufs[0][:box_size(m[i])]
        b0[:] = 0.0
        for j in range(nsrc):
            paste(data[src_off[j]:src_off[j + 1]], src_s[j], src_m[j], b0, s[i], m[i], n)
        cnt = 0
        for t in range(inj_idx.shape[0]):
            if inj_cl[t] == i:
                cnt += 1
        ii = np.empty(cnt, np.int64)
        iv = np.empty(cnt, np.float64)
        cnt = 0
        for t in range(inj_idx.shape[0]):
            if inj_cl[t] == i:
                ii[cnt] = inj_idx[t]
                iv[cnt] = inj_val[t]
                cnt += 1
        ci, _ = box_inject_excite_inhibit(bufs, np.int64(0), s[i], m[i], n, ii, iv, exc, exc_w, inh, inh_w, phi, proto,
                                          par_work, nthreads)
        cur[i] = ci
    # 2. the total in the one-box step's order: C order of the union's excitation box
    us = np.empty(d, np.int64)
    um = np.empty(d, np.int64)
    for k in range(d):
        a0, l0 = arc_from_occupancy(union_occ[k], n[k])
        h = exc_w[k] // 2
        us[k], um[k] = grow_arc(a0, l0, h, h, n[k])
    ustride = np.empty(d, np.int64)
    acc = 1
    for k in range(d - 1, -1, -1):
        ustride[k] = acc
        acc *= um[k]
    ncells = 0
    for i in range(k_cl):
        ncells += box_size(m[i])
    keys = np.empty(ncells, np.int64)
    vals = np.empty(ncells, np.float64)
    nz = 0
    idx = np.zeros(d, np.int64)
    for i in range(k_cl):
        base = slot[i]
        bb = bound[i]
        e = ws[base + cur[i] * bb:base + cur[i] * bb + box_size(m[i])]
        loc = np.empty((d, n.max()), np.int64)
        for k in range(d):
            for p in range(m[i, k]):
                loc[k, p] = ((s[i, k] + p - us[k]) % n[k]) * ustride[k]
        idx[:] = 0
        last = d - 1
        ml = m[i, last]
        for r in range(e.shape[0] // ml):
            kb = 0
            for k in range(last):
                kb += loc[k, idx[k]]
            for p in range(ml):
                v = e[r * ml + p]
                if v != 0.0:
                    keys[nz] = kb + loc[last, p]
                    vals[nz] = v
                    nz += 1
            _advance(idx, m[i], last - 1)
    order = np.argsort(keys[:nz])
    total = 0.0
    for q in range(nz):
        total += vals[order[q]]
    if not (np.isfinite(total) and total > 0.0):
        return STATUS_COLLAPSE, 0
    # 3. normalise, shrink and shift each packet
    nres = 0
    for i in range(k_cl):
        base = slot[i]
        bb = bound[i]
        bufs = (ws[base:base + bb], ws[base + bb:base + 2 * bb], ws[base + 2 * bb:base + 3 * bb])
        occupied, c = box_normalise(bufs, cur[i], s[i], m[i], n, total, proto, np.bool_(False))
        if not occupied:
            continue
        c = box_shift(bufs, c, s[i], m[i], n, do_cond, cmask, cond_tab, do_uni, uni, proto, par_work, nthreads)
        res_off[nres] = base + c * bb
        res_s[nres] = s[i]
        res_m[nres] = m[i]
        nres += 1
    return STATUS_OK, nres


@njit(**_OPTS)
def _clear_regions(out, reg, n):
    """Zero the boxes of the region list ``reg`` (shape (R, 2, d), see :func:`packets_step`) in
    the flat grid ``out`` (all of it when they cover more than a quarter of it: one contiguous
    pass is faster than their rows)."""
    total = 0
    for j in range(reg.shape[0]):
        total += box_size(reg[j, 1])
    if 4 * total > out.shape[0]:
        out[:] = 0
        return
    for j in range(reg.shape[0]):
        clear_box(reg[j, 0], reg[j, 1], out, n)


@njit(**_OPTS)
def _set_regions(reg, bs, bm, nb, n):
    """Write the ``nb`` boxes ``(bs[i], bm[i])`` as the region list ``reg`` (shape (R, 2, d)); more
    than R boxes become one: per axis the smallest arc holding them all."""
    d = n.shape[0]
    nr = reg.shape[0]
    reg[:, 1, :] = 0
    if nb <= nr:
        for i in range(nb):
            reg[i, 0] = bs[i]
            reg[i, 1] = bm[i]
        return
    occ = np.zeros(n.max(), np.uint8)
    for k in range(d):
        occ[:] = 0
        for i in range(nb):
            for p in range(bm[i, k]):
                occ[(bs[i, k] + p) % n[k]] = 1
        a0, l0 = arc_from_occupancy(occ, n[k])
        reg[0, 0, k] = a0
        reg[0, 1, k] = l0


@njit(**_OPTS)
def packets_step(
    a, a_bits, out, ws, n,
    inj_idx, inj_val,
    exc, exc_w, inh, inh_w, phi,
    do_cond, cmask, cond_tab,
    do_uni, uni,
    window, decoded,
    par_work, nthreads,
    regions, st, st_bits,
):
    """The fused step of :func:`cansim.backends._numba_kernels.pipeline` (dynamics and decoding on)
    with one box per packet; the same arguments and the same bits. One packet (or packets too
    close to keep apart) runs the one-box step itself.

    ``regions`` (int64, shape (3, R, 2, d)) lets a caller that knows where its grids can be
    non-zero skip the passes over the whole grid. ``regions[i]`` is a list of up to R boxes
    (box j: arc starts ``regions[i, j, 0]``, lengths ``regions[i, j, 1]``; a box of no cells
    is an unused entry): ``regions[0]`` holds every non-zero cell of ``a``, ``regions[1]``
    every non-zero cell of ``out``'s current content (a box of the whole grid: not known).
    On success ``regions[2]`` is written: boxes holding every non-zero cell of the result
    (one per packet; more packets than R: one box round them all). ``st`` (``a``'s dtype, at
    least ``a.size`` cells; ``st_bits`` the same memory viewed as ``a_bits``) holds the
    boxes of ``a`` while the step reads them (boxes of more than a quarter of the grid in all
    are read in ``a`` itself). The cells read and the sums are the same either way: the same
    bits as with the whole grid, as long as the regions given are true. A start or a length
    out of range returns :data:`STATUS_BAD_REGIONS` before anything is read.
    """
    if not _regions_valid(regions, n):
        return STATUS_BAD_REGIONS
    d = n.shape[0]
    size = a.shape[0]
    gap = np.empty(d, np.int64)
    spread = np.empty(d, np.int64)
    zero = np.zeros(d, np.int64)
    nr = regions.shape[1]
    # the input: a's boxes copied one after another into st, or a itself (one box, the grid)
    src_off = np.zeros(nr + 1, np.int64)
    src_s = np.zeros((nr, d), np.int64)
    src_m = np.zeros((nr, d), np.int64)
    nsrc = 0
    for j in range(nr):
        bs = box_size(regions[0, j, 1])
        if bs > 0:
            src_s[nsrc] = regions[0, j, 0]
            src_m[nsrc] = regions[0, j, 1]
            src_off[nsrc + 1] = src_off[nsrc] + bs
            nsrc += 1
    if nsrc == 0 or 4 * src_off[nsrc] > size:  # a large part of the grid: read a itself, not a copy
        nsrc = 1
        src_s[0] = zero
        src_m[0] = n
        src_off[1] = size
        data = a
        bits = a_bits
    else:
        for j in range(nsrc):
            crop(a, zero, n, st[src_off[j]:src_off[j + 1]], src_s[j], src_m[j], n)
        data = st
        bits = st_bits
    cl_s = np.empty((MAX_ITEMS, d), np.int64)
    cl_m = np.empty((MAX_ITEMS, d), np.int64)
    union_occ = np.zeros((d, n.max()), np.uint8)
    least_gaps(exc_w, inh_w, gap)
    if _one_packet_sources(bits, src_off, src_s, src_m, nsrc, n, inj_idx, gap, cl_s, cl_m, union_occ):
        k_cl = 1
    else:
        separations(exc_w, inh_w, n, do_cond, cmask, cond_tab, do_uni, uni, gap, spread)
        union_occ[:] = 0
        k_cl = plan_packets(bits, src_off, src_s, src_m, np.int64(nsrc), n, inj_idx, gap, cl_s, cl_m, union_occ)
    if k_cl == 0:
        return STATUS_COLLAPSE
    proto = out[:1].copy()
    if k_cl >= 2:
        res_off = np.empty(k_cl, np.int64)
        res_s = np.empty((k_cl, d), np.int64)
        res_m = np.empty((k_cl, d), np.int64)
        status, nres = multi_step(data, src_off, src_s, src_m, np.int64(nsrc), n, k_cl, cl_s, cl_m, union_occ,
                                  spread, inj_idx, inj_val, exc, exc_w, inh, inh_w, phi,
                                  do_cond, cmask, cond_tab, do_uni, uni, proto, ws, par_work, nthreads,
                                  res_off, res_s, res_m)
        if status >= 0:
            if status != STATUS_OK:
                return status
            _clear_regions(out, regions[1], n)
            for i in range(nres):
                place(ws[res_off[i]:], res_s[i], res_m[i], out, n)
            _set_regions(regions[2], res_s, res_m, nres, n)
            centre = unravel(argmax_boxes(ws, res_off, res_s, res_m, nres, n), n)
            decode_boxes(ws, res_off, res_s, res_m, nres, n, centre, window, decoded, no_trig())
            return STATUS_OK
        for k in range(d):  # the packets do not fit: one box
            a0, l0 = arc_from_occupancy(union_occ[k], n[k])
            cl_s[0, k] = a0
            cl_m[0, k] = l0
    # one box: the step of pipeline()
    bufs = (ws[:size], ws[size:2 * size], ws[2 * size:3 * size])
    s = cl_s[0].copy()
    m = cl_m[0].copy()
    if nsrc == 1:
        crop(data, src_s[0], src_m[0], bufs[0], s, m, n)
    else:
        b0 = bufs[0][:box_size(m)]
        b0[:] = 0.0
        for j in range(nsrc):
            paste(data[src_off[j]:src_off[j + 1]], src_s[j], src_m[j], b0, s, m, n)
    status, cur = box_step(bufs, np.int64(0), s, m, n, inj_idx, inj_val, np.bool_(True), exc, exc_w, inh, inh_w, phi,
                           do_cond, cmask, cond_tab, do_uni, uni, proto, np.bool_(False), par_work, nthreads)
    if status != STATUS_OK:
        return status
    if is_full(m, n):
        scatter(bufs[cur], s, m, out, n)
    else:
        _clear_regions(out, regions[1], n)
        place(bufs[cur], s, m, out, n)
    _set_regions(regions[2], s.reshape(1, d), m.reshape(1, d), 1, n)
    decode_box(bufs[cur], s, m, n, unravel(box_argmax(bufs[cur], s, m, n), n), window, decoded, no_trig())
    return STATUS_OK


@njit(**_OPTS)
def packets_run(a, a_bits, out, hist, record, ws, st, n,
                inj_off, inj_idx, inj_val,
                exc, exc_w, inh, inh_w, phi,
                has_cond, cmask, cond_tabs,
                has_uni, unis,
                window, decoded,
                par_work, nthreads):
    """T iterations of :func:`packets_step` (the arguments of
    :func:`cansim.backends._numba_run.pipeline_run`, plus ``st``: a float64 buffer of at least
    ``a.size`` cells that holds the packets' boxes between steps).

    One packet stays a box buffer of the workspace between steps, as in ``pipeline_run``;
    several are copied to ``st`` after their step and planned again from there
    (:func:`plan_packets`) at the next. Returns -1 after the last step or the index of the
    first step whose dynamics collapsed; the last activity is written to ``out``.
    """
    d = n.shape[0]
    size = a.shape[0]
    proto = out[:1].copy()
    bufs = (ws[:size], ws[size:2 * size], ws[2 * size:3 * size])
    trig = trig_table(n)
    zero = np.zeros(d, np.int64)
    gap = np.empty(d, np.int64)
    gap0 = np.empty(d, np.int64)
    least_gaps(exc_w, inh_w, gap0)
    spread = np.empty(d, np.int64)
    cl_s = np.empty((MAX_ITEMS, d), np.int64)
    cl_m = np.empty((MAX_ITEMS, d), np.int64)
    union_occ = np.zeros((d, n.max()), np.uint8)
    one_off = np.zeros(2, np.int64)
    grid_s = zero.reshape(1, d)
    grid_m = n.copy().reshape(1, d)
    st_off = np.zeros(MAX_ITEMS + 1, np.int64)
    st_s = np.zeros((MAX_ITEMS, d), np.int64)
    st_m = np.zeros((MAX_ITEMS, d), np.int64)
    res_off = np.empty(MAX_ITEMS, np.int64)
    res_s = np.empty((MAX_ITEMS, d), np.int64)
    res_m = np.empty((MAX_ITEMS, d), np.int64)
    st_bits = st.view(np.uint64)
    nst = np.int64(0)
    mode = 0  # 0: the grid a; 1: one box bufs[cur] (s, m); 2: nst boxes in st
    cur = np.int64(0)
    s = np.zeros(d, np.int64)
    m = n.copy()
    for t in range(decoded.shape[0]):
        lo = inj_off[t]
        hi = inj_off[t + 1]
        inj = inj_idx[lo:hi]
        ival = inj_val[lo:hi]
        union_occ[:] = 0
        k_cl = -1
        if mode == 0:
            if _one_packet(a_bits, zero, n, n, inj, gap0, cl_s, cl_m, union_occ):
                k_cl = 1
        elif mode == 1:
            if _one_packet(bufs[cur][:box_size(m)].view(np.uint64), s, m, n, inj, gap0, cl_s, cl_m, union_occ):
                k_cl = 1
        if k_cl < 0:
            separations(exc_w, inh_w, n, has_cond[t], cmask, cond_tabs[t], has_uni[t], unis[t], gap, spread)
            union_occ[:] = 0
            if mode == 0:
                one_off[1] = size
                k_cl = plan_packets(a_bits, one_off, grid_s, grid_m, np.int64(1), n, inj, gap, cl_s, cl_m, union_occ)
            elif mode == 1:
                one_off[1] = box_size(m)
                k_cl = plan_packets(bufs[cur][:box_size(m)].view(np.uint64), one_off, s.reshape(1, d),
                                    m.reshape(1, d), np.int64(1), n, inj, gap, cl_s, cl_m, union_occ)
            else:
                k_cl = plan_packets(st_bits, st_off, st_s, st_m, nst, n, inj, gap, cl_s, cl_m, union_occ)
        if k_cl == 0:
            return t
        if k_cl >= 2:
            if mode == 1:  # the workspace is about to be reused: keep the box in st
                bs = box_size(m)
                st[:bs] = bufs[cur][:bs]
                st_off[0] = 0
                st_off[1] = bs
                st_s[0] = s
                st_m[0] = m
                nst = 1
                mode = 2
            if mode == 0:
                one_off[1] = size
                status, nres = multi_step(a, one_off, grid_s, grid_m, np.int64(1), n, k_cl, cl_s, cl_m, union_occ, spread,
                                          inj, ival, exc, exc_w, inh, inh_w, phi,
                                          has_cond[t], cmask, cond_tabs[t], has_uni[t], unis[t], proto, ws,
                                          par_work, nthreads, res_off, res_s, res_m)
            else:
                status, nres = multi_step(st, st_off, st_s, st_m, nst, n, k_cl, cl_s, cl_m, union_occ, spread,
                                          inj, ival, exc, exc_w, inh, inh_w, phi,
                                          has_cond[t], cmask, cond_tabs[t], has_uni[t], unis[t], proto, ws,
                                          par_work, nthreads, res_off, res_s, res_m)
            if status >= 0:
                if status != STATUS_OK:
                    return t
                pos = 0
                for i in range(nres):
                    bs = box_size(res_m[i])
                    st[pos:pos + bs] = ws[res_off[i]:res_off[i] + bs]
                    st_off[i] = pos
                    st_s[i] = res_s[i]
                    st_m[i] = res_m[i]
                    pos += bs
                    st_off[i + 1] = pos
                nst = nres
                mode = 2
                centre = unravel(argmax_boxes(st, st_off, st_s, st_m, nst, n), n)
                decode_boxes(st, st_off, st_s, st_m, nst, n, centre, window, decoded[t], trig)
                if record:
                    hist[t, :] = 0
                    for i in range(nst):
                        place(st[st_off[i]:], st_s[i], st_m[i], hist[t], n)
                continue
            for k in range(d):  # the packets do not fit: one box
                a0, l0 = arc_from_occupancy(union_occ[k], n[k])
                cl_s[0, k] = a0
                cl_m[0, k] = l0
        ts = cl_s[0]
        tm = cl_m[0]
        if mode == 0:
            crop(a, zero, n, bufs[0], ts, tm, n)
            cur = np.int64(0)
        elif mode == 1:
            same = True
            for k in range(d):
                if ts[k] != s[k] or tm[k] != m[k]:
                    same = False
            if not same:
                crop(bufs[cur], s, m, bufs[1 - cur], ts, tm, n)
                cur = 1 - cur
        else:
            b0 = bufs[0][:box_size(tm)]
            b0[:] = 0.0
            for j in range(nst):
                paste(st[st_off[j]:st_off[j + 1]], st_s[j], st_m[j], b0, ts, tm, n)
            cur = np.int64(0)
        s[:] = ts
        m[:] = tm
        mode = 1
        status, cur = box_step(
            bufs, cur, s, m, n,
            inj, ival,
            np.bool_(True), exc, exc_w, inh, inh_w, phi,
            has_cond[t], cmask, cond_tabs[t],
            has_uni[t], unis[t],
            proto, np.bool_(False), par_work, nthreads,
        )
        if status != STATUS_OK:
            return t
        decode_box(bufs[cur], s, m, n, unravel(box_argmax(bufs[cur], s, m, n), n), window, decoded[t], trig)
        if record:
            scatter(bufs[cur], s, m, hist[t], n)
    if mode == 1:
        scatter(bufs[cur], s, m, out, n)
    else:
        out[:] = 0
        for i in range(nst):
            place(st[st_off[i]:], st_s[i], st_m[i], out, n)
    return -1


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
