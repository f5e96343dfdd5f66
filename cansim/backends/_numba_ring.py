"""Fused numba step for 1-D rings (head-direction cells).

A ring step is a few thousand multiply-adds; the generic N-D pipeline's fixed cost
(argument dispatch of ~20 arrays) dominates it, so rings get this small kernel with
the same semantics as the numpy reference (float64 arithmetic, rounding to the
storage dtype where the reference stores: after injection, after the dynamics and
after the shift).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cansim.backends._numba_kernels import global_inhibit
from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["ring_step", "workspace_size"]


def workspace_size(n: int, exc_taps: int, inh_taps: int) -> int:
    """float64 cells of scratch :func:`ring_step` needs for a ring of ``n`` cells."""
    return 4 * n + exc_taps + inh_taps + 2


@njit(cache=True, fastmath=False)
def _pad(src, c, xp):
    """``xp[p] = src[(p - c) mod n]`` for ``p in [0, n + 2c)``: the ring with c cells of wrap on each side."""
    n = src.shape[0]
    mid = xp[c:c + n]
    for i in range(n):
        mid[i] = src[i]
    for p in range(c):  # the pads (they wrap more than once when c > n)
        q = p - c
        while q < 0:
            q += n
        xp[p] = src[q]
        q = p
        while q >= n:
            q -= n
        xp[c + n + p] = src[q]


@njit(cache=True, fastmath=False)
def _conv(src, taps, dst, xp):
    """dst[i + j - c] += src[i] * taps[j] with wrap (scatter form of Alg 3), tap after tap.

    Gathered from the padded ring: ``dst[k] = sum_j taps[j] src[k + c - j]``, summed in tap
    order from 0.0 as the reference's scatter does; every tap is one contiguous,
    vectorised pass (slices, so no negative-index checks).
    """
    n = src.shape[0]
    nt = taps.shape[0]
    c = nt // 2
    _pad(src, c, xp)
    for k in range(n):
        dst[k] = 0.0
    for j in range(nt):
        w = taps[j]
        seg = xp[2 * c - j: 2 * c - j + n]
        for k in range(n):
            dst[k] += w * seg[k]


@njit(cache=True, fastmath=False)
def ring_step(a, out, fi, vals, exc, inh, phi, shift, window, decoded, work):
    """One ring iteration: inject, dynamics, shift by ``shift`` cells, decode.

    ``out`` has ``a``'s dtype; ``work`` is float64 scratch of length >= ``4n + len(exc) +
    len(inh) + 2`` (:func:`workspace_size`). Returns False, with ``out`` untouched, when the
    activity collapses.
    """
    n = a.shape[0]
    x = work[:n]
    e = work[n:2 * n]
    t = work[2 * n:3 * n]
    xp = work[3 * n:]
    for i in range(n):
        x[i] = a[i]
    if fi.shape[0] > 0:
        for k in range(fi.shape[0]):
            x[fi[k]] += vals[k]
        rb = np.empty_like(a[:1])  # the reference stores the injected grid: round to a's dtype
        for i in range(n):
            rb[0] = x[i]
            x[i] = rb[0]
    _conv(x, exc, e, xp)
    _conv(e, inh, t, xp)
    total = global_inhibit(e, t, x, n, phi)
    if not (total > 0.0 and total < np.inf):
        return False
    for i in range(n):  # normalise and round to the storage dtype as the reference stores
        out[i] = x[i] / total
        x[i] = out[i]
    if shift != 0.0:
        lo = math.floor(shift)
        f = shift - lo
        lo_m = np.int64(lo % n)
        # t[i] = (1 - f) x[i - lo] + f x[i - lo - 1] (indices mod n), as the reference's two rolls:
        # with xp[p] = x[(p - lo - 1) mod n], p in [0, n], that is (1 - f) xp[i + 1] + f xp[i]
        head = xp[:lo_m + 1]
        src = x[n - lo_m - 1:]
        for p in range(lo_m + 1):
            head[p] = src[p]
        tail = xp[lo_m + 1:n + 1]
        for p in range(n - lo_m):
            tail[p] = x[p]
        hi = xp[1:n + 1]
        if f != 0.0:
            g = 1.0 - f
            lo_s = xp[:n]
            for i in range(n):
                x[i] = g * hi[i] + f * lo_s[i]
        else:
            for i in range(n):
                x[i] = hi[i]
    best = 0
    for i in range(n):
        out[i] = x[i]
        if out[i] > out[best]:
            best = i
    # population vector over +-window around the first maximum, clipped to the ring
    s = 0.0
    cc = 0.0
    if 2 * window + 1 >= n:
        lo_i, hi_i = 0, n - 1
        base = 0
    else:
        lo_i, hi_i = -window, window
        base = best
    for d in range(lo_i, hi_i + 1):
        i = (base + d) % n
        p = np.float64(out[i])
        ang = 2.0 * math.pi * i / n
        s += p * math.sin(ang)
        cc += p * math.cos(ang)
    m = math.atan2(s, cc) % (2.0 * math.pi)
    idx = m * n / (2.0 * math.pi)
    decoded[0] = idx if idx < n else 0.0
    return True


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
