"""Compiled multi-step runs of the numba backend: one call for T iterations.

Each loop calls, once per step, the very kernel :meth:`cansim.backends.numba_backend.NumbaBackend.step`
calls for that grid (the ring kernel of :mod:`cansim.backends._numba_ring`, the generic
N-D pipeline of :mod:`cansim.backends._numba_kernels`; the small-grid loop lives with its
generated step in :mod:`cansim.backends._numba_small`) with the arguments the step would
pass, so a run equals T calls of ``step`` bit for bit; only the Python call per step is
gone (and, on the generic pipeline, the whole-grid work between steps: the activity stays
in its box). The input is never written.

Per-step inputs arrive as arrays with a leading step axis: injections in CSR form
(``inj_off[t]:inj_off[t + 1]`` slices ``inj_idx`` / ``inj_val``), shifts as (T, ...)
tables with a per-step flag. Each loop returns -1 after the last step, or the index of
the first step whose dynamics collapsed (the buffers then hold partial results the
caller discards).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cansim.backends._numba_kernels import (
    STATUS_OK, box_argmax, box_size, box_step, crop, decode_box, occupied_box, scatter, start_box, trig_table, unravel,
)
from cansim.backends._numba_ring import ring_step
from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["ring_run", "pipeline_run"]

_OPTS = dict(cache=True, fastmath=False, nogil=True)


@njit(**_OPTS)
def ring_run(a, buf0, buf1, hist, record, inj_off, inj_idx, inj_val, exc, inh, phi, shifts, window,
             decoded, work):
    """T ring iterations (:func:`ring_step`); ``shifts[t]`` is step t's shift in cells (0: none)."""
    src = a
    for t in range(shifts.shape[0]):
        dst = buf0 if t % 2 == 0 else buf1
        lo = inj_off[t]
        hi = inj_off[t + 1]
        if not ring_step(src, dst, inj_idx[lo:hi], inj_val[lo:hi], exc, inh, phi, shifts[t], window,
                         decoded[t], work):
            return t
        if record:
            hist[t, :] = dst
        src = dst
    return -1


@njit(**_OPTS)
def pipeline_run(a, a_bits, out, hist, record, ws, n,
                 inj_off, inj_idx, inj_val,
                 exc, exc_w, inh, inh_w, phi,
                 has_cond, cmask, cond_tabs,
                 has_uni, unis,
                 window, decoded,
                 dense, par_work, nthreads):
    """T iterations of the generic :func:`pipeline` (flat grids; ``a_bits`` is ``a``'s unsigned view).

    ``cond_tabs[t]`` is step t's (n_conditions, n_shifted_axes) table, used when
    ``has_cond[t]``; ``unis[t]`` its uniform shift, used when ``has_uni[t]``. The
    activity stays a box buffer between steps (:func:`box_step`): the next step's box is
    found from the box (:func:`occupied_box` finds the arcs :func:`pipeline` finds on the
    whole grid), decoding reads the box (:func:`decode_box`, with the sines and cosines of the
    grid tabulated once), and the grid is written only for ``hist`` and, at the end, to
    ``out``. Each step thus computes what :func:`pipeline` computes, on the same box.
    """
    d = n.shape[0]
    occupied, proto, bufs, s, m = start_box(a, a_bits, out, ws, n, inj_idx[inj_off[0]:inj_off[1]], dense)
    if not occupied:
        return 0
    ts = np.empty(d, np.int64)
    tm = np.empty(d, np.int64)
    trig = trig_table(n)
    cur = np.int64(0)
    for t in range(decoded.shape[0]):
        lo = inj_off[t]
        hi = inj_off[t + 1]
        inj = inj_idx[lo:hi]
        if t > 0 and not dense:
            if not occupied_box(bufs[cur][:box_size(m)].view(np.uint64), s, m, n, inj, ts, tm):
                return t
            same = True
            for k in range(d):
                if ts[k] != s[k] or tm[k] != m[k]:
                    same = False
            if not same:
                crop(bufs[cur], s, m, bufs[1 - cur], ts, tm, n)
                cur = 1 - cur
                s[:] = ts
                m[:] = tm
        status, cur = box_step(
            bufs, cur, s, m, n,
            inj, inj_val[lo:hi],
            np.bool_(True), exc, exc_w, inh, inh_w, phi,
            has_cond[t], cmask, cond_tabs[t],
            has_uni[t], unis[t],
            proto, dense, par_work, nthreads,
        )
        if status != STATUS_OK:
            return t
        decode_box(bufs[cur], s, m, n, unravel(box_argmax(bufs[cur], s, m, n), n), window, decoded[t], trig)
        if record:
            scatter(bufs[cur], s, m, hist[t], n)
    scatter(bufs[cur], s, m, out, n)
    return -1


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
