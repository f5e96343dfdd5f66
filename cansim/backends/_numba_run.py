"""Compiled multi-step runs of the numba backend: one call for T iterations.

Each loop calls, once per step, the very kernel :meth:`cansim.backends.numba_backend.NumbaBackend.step`
calls for that grid (the ring kernel of :mod:`cansim.backends._numba_ring`, the generic
N-D pipeline of :mod:`cansim.backends._numba_kernels`; the small-grid loop lives with its
generated step in :mod:`cansim.backends._numba_small`) with the arguments the step would
pass, so a run equals T calls of ``step`` bit for bit; only the Python call per step is
gone. The activity ping-pongs between two buffers, so the input is never written.

Per-step inputs arrive as arrays with a leading step axis: injections in CSR form
(``inj_off[t]:inj_off[t + 1]`` slices ``inj_idx`` / ``inj_val``), shifts as (T, ...)
tables with a per-step flag. Each loop returns -1 after the last step, or the index of
the first step whose dynamics collapsed (the buffers then hold partial results the
caller discards).
"""

from __future__ import annotations

from numba import njit

from cansim.backends._numba_kernels import STATUS_OK, pipeline
from cansim.backends._numba_ring import ring_step

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
def pipeline_run(a, a_bits, buf0, bits0, buf1, bits1, hist, record, ws, n,
                 inj_off, inj_idx, inj_val,
                 exc, exc_w, inh, inh_w, phi,
                 has_cond, cmask, cond_tabs,
                 has_uni, unis,
                 window, decoded,
                 dense, par_work, nthreads):
    """T iterations of the generic :func:`pipeline` (flat grids; ``*_bits`` are the unsigned views).

    ``cond_tabs[t]`` is step t's (n_conditions, n_shifted_axes) table, used when
    ``has_cond[t]``; ``unis[t]`` its uniform shift, used when ``has_uni[t]``.
    """
    src = a
    src_bits = a_bits
    for t in range(decoded.shape[0]):
        if t % 2 == 0:
            dst = buf0
            dst_bits = bits0
        else:
            dst = buf1
            dst_bits = bits1
        lo = inj_off[t]
        hi = inj_off[t + 1]
        status = pipeline(
            src, src_bits, dst, ws, n,
            inj_idx[lo:hi], inj_val[lo:hi],
            True, exc, exc_w, inh, inh_w, phi,
            has_cond[t], cmask, cond_tabs[t],
            has_uni[t], unis[t],
            True, window, decoded[t],
            dense, par_work, nthreads,
        )
        if status != STATUS_OK:
            return t
        if record:
            hist[t, :] = dst
        src = dst
        src_bits = dst_bits
    return -1
