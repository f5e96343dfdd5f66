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

__all__ = ["ring_step"]


@njit(cache=True, fastmath=False)
def _conv(src, taps, dst):
    """dst[i + j - c] += src[i] * taps[j] with wrap (scatter form of Alg 3)."""
    n = src.shape[0]
    c = taps.shape[0] // 2
    for k in range(n):
        dst[k] = 0.0
    for j in range(taps.shape[0]):
        w = taps[j]
        off = (j - c) % n
        for i in range(n - off):  # split at the wrap point: two branch-free (vectorisable) runs
            dst[i + off] += w * src[i]
        for i in range(n - off, n):
            dst[i + off - n] += w * src[i]


@njit(cache=True, fastmath=False)
def ring_step(a, out, fi, vals, exc, inh, phi, shift, window, decoded, work):
    """One ring iteration: inject, dynamics, shift by ``shift`` cells, decode.

    ``out`` has ``a``'s dtype; ``work`` is float64 scratch of length >= 3n. Returns
    False, with ``out`` untouched, when the activity collapses.
    """
    n = a.shape[0]
    x = work[:n]
    e = work[n:2 * n]
    t = work[2 * n:3 * n]
    for i in range(n):
        x[i] = a[i]
    if fi.shape[0] > 0:
        for k in range(fi.shape[0]):
            x[fi[k]] += vals[k]
        rb = np.empty_like(a[:1])  # the reference stores the injected grid: round to a's dtype
        for i in range(n):
            rb[0] = x[i]
            x[i] = rb[0]
    _conv(x, exc, e)
    _conv(e, inh, t)
    total = global_inhibit(e, t, x, n, phi)
    if not (total > 0.0 and total < np.inf):
        return False
    for i in range(n):  # normalise and round to the storage dtype as the reference stores
        out[i] = x[i] / total
        x[i] = out[i]
    if shift != 0.0:
        lo = math.floor(shift)
        f = shift - lo
        lo_m = lo % n
        # t[i] = (1 - f) x[i - lo] + f x[i - lo - 1] (indices mod n), as the reference's two rolls
        for i in range(n):
            t[i] = x[(i - lo_m) % n]
        if f != 0.0:
            g = 1.0 - f
            last = t[n - 1]
            for i in range(n - 1, 0, -1):
                t[i] = g * t[i] + f * t[i - 1]
            t[0] = g * t[0] + f * last
        for i in range(n):
            x[i] = t[i]
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
