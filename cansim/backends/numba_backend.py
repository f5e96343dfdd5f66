"""Compiled CPU backend: numba kernels that work only where the activity packet is.

After global inhibition (Alg 5) the activity of an attractor network is non-zero in a
small packet. This backend finds, per axis, the smallest circular arc holding every
non-zero cell (the complement of the largest empty gap) and runs the whole step
(injection, excitation, inhibition, global inhibition, normalisation, conditional and
uniform shifts, decoding) in one compiled call on that box, grown by the kernel
half-widths and shift extents as it goes. Several packets far enough apart each get a
box of their own (:mod:`cansim.backends._numba_packets`, the same bits as one box round
them all); packets too close to keep apart share one. With a spread-out activity the box
covers the grid and the same code is the dense path. Small hypercube grids that
the excitation kernel covers whole (e.g. 5^6) have no box to gain and run a step generated
for their shape (:mod:`cansim.backends._numba_small`); 1-D rings have their own kernel
(:mod:`cansim.backends._numba_ring`). Results equal the numpy
reference backend (float64 sums in its order, storage-dtype rounding where it stores).

Kernels compile on first use (``cache=True`` keeps them across runs); importing this
module compiles nothing. See :mod:`cansim.backends._numba_kernels`.
"""

from __future__ import annotations

import threading
from typing import Optional, Sequence

import numpy as np

from cansim.backends import _numba_kernels as _k
from cansim.backends import _numba_packets as _p
from cansim.backends.base import Backend, RunInputs, RunResult
from cansim.errors import InvalidInputError

__all__ = ["NumbaBackend"]

_NO_INDEX = np.empty(0, dtype=np.int64)
_NO_VALUES = np.empty(0, dtype=np.float64)
_NO_COND = np.zeros((1, 1), dtype=np.float64)
_NO_DECODE = np.empty(0, dtype=np.float64)
_NO_LINES = np.zeros((1, 1), dtype=np.int64)
_BITS = {4: np.uint32, 8: np.uint64}

#: passes with at least this many multiply-adds run on several threads. A parallel
#: launch costs ~10-50 us (about 100k multiply-adds on one core), and when the machine
#: has more busy processes than cores the threads wait for each other: on the 2-core
#: development machine with other jobs running, a 10^6-cell 6-D step took 16 ms serial
#: and 19-35 ms on 2 threads (11 ms of main-thread time, so ~11 ms on a quiet machine).
#: The default keeps grids up to ~10^6 cells serial; pass ``parallel_work=1_000_000``
#: on a dedicated multi-core machine.
DEFAULT_PARALLEL_WORK = 8_000_000


class NumbaBackend(Backend):
    """Numba-compiled CAN kernels with a locality (packet box) path and a dense fallback.

    Parameters
    ----------
    locality : bool
        Work on the box around the non-zero cells (default). ``False`` forces the dense
        path on the whole grid (same results; for tests and many-packet activity).
    parallel_work : int
        A line pass with at least this many multiply-adds is split over threads; smaller
        passes run serially because a thread launch costs more than they do.
    threads : int or None
        Threads for parallel passes; None uses ``numba.get_num_threads()`` at the first step.
    small_grids : bool
        Run :meth:`step` on grids whose excitation kernels cover every axis (at most
        ``_numba_small.MAX_AXIS`` cells each, e.g. 5^6) with a kernel generated for the
        shape (default). ``False`` keeps them on the generic pipeline (same results).
    """

    name = "numba"

    def __init__(self, *, locality: bool = True, parallel_work: int = DEFAULT_PARALLEL_WORK,
                 threads: Optional[int] = None, small_grids: bool = True) -> None:
        self._dense = not bool(locality)
        self._small = bool(small_grids)
        self._small_cache: dict = {}
        self._par_work = max(int(parallel_work), 0)
        self._threads = threads
        self._local = threading.local()  # per-thread workspace
        self._taps: tuple = (None, None, None)
        self._shapes: dict = {}
        self._masks: dict = {}
        self._ring_kernel = None
        self._ring_taps_cache = None

    # ------------------------------------------------------------------ helpers
    def _nthreads(self) -> int:
        if self._threads is None:
            import numba

            self._threads = int(numba.get_num_threads())
        return max(int(self._threads), 1)

    def _shape(self, shape: tuple[int, ...]) -> np.ndarray:
        arr = self._shapes.get(shape)
        if arr is None:
            arr = np.array(shape, dtype=np.int64)
            self._shapes[shape] = arr
        return arr

    def _workspace(self, size: int) -> np.ndarray:
        ws = getattr(self._local, "ws", None)
        if ws is None or ws.shape[0] < 3 * size:
            ws = np.empty(3 * size, dtype=np.float64)
            self._local.ws = ws
        return ws

    def _packed_taps(self, exc: Sequence[np.ndarray], inh: Sequence[np.ndarray]):
        cached = self._taps
        if cached[0] is exc and cached[1] is inh:
            return cached[2]
        packed = (*_pack(exc), *_pack(inh))
        self._taps = (exc, inh, packed)
        return packed

    def _cmask(self, shift_axes: tuple[int, ...], ndim: int) -> np.ndarray:
        key = (tuple(shift_axes), ndim)
        arr = self._masks.get(key)
        if arr is None:
            arr = np.zeros(ndim, dtype=np.int64)
            arr[list(shift_axes)] = 1
            self._masks[key] = arr
        return arr

    def _staging(self, size: int, bits_dtype: np.dtype, dtype: np.dtype) -> tuple[np.ndarray, np.ndarray]:
        """This thread's staging buffer of at least ``size`` cells of ``dtype`` and the same memory
        viewed as ``bits_dtype`` (kept between calls)."""
        st = getattr(self._local, "st", None)
        if st is None or st[0].shape[0] < size or st[0].dtype != dtype:
            buf = np.empty(size, dtype=dtype)
            st = (buf, buf.view(bits_dtype))
            self._local.st = st
        return st

    @staticmethod
    def new_regions(shape: tuple[int, ...]) -> np.ndarray:
        """A ``regions`` array for :meth:`step` on grids of ``shape``, every list the whole grid (not known).

        Returns
        -------
        ndarray, int64, shape (3, R, 2, ndim)
            Three lists of up to R = ``_numba_packets.MAX_REGIONS`` boxes (see :meth:`step`).
        """
        r = np.zeros((3, _p.MAX_REGIONS, 2, len(shape)), dtype=np.int64)
        r[:, 0, 1] = shape
        return r

    @staticmethod
    def _check_regions(regions, ndim: int) -> None:
        if (type(regions) is not np.ndarray or regions.dtype != np.int64 or not regions.flags.c_contiguous
                or not regions.flags.writeable or regions.shape != (3, _p.MAX_REGIONS, 2, ndim)):
            raise InvalidInputError(
                f"regions must be a writable C-contiguous int64 array of shape (3, {_p.MAX_REGIONS}, 2, {ndim}) "
                "(NumbaBackend.new_regions(shape) makes one), got "
                f"{getattr(regions, 'dtype', type(regions).__name__)} {getattr(regions, 'shape', '')}")

    @staticmethod
    def forget_regions(regions: np.ndarray, which: slice | int, shape: tuple[int, ...]) -> None:
        """Set the lists ``regions[which]`` to the whole grid (nothing known)."""
        r = regions[which]
        r[..., 1, :] = 0
        r[..., 0, :, :] = 0
        r[..., 0, 1, :] = shape

    def _run(self, a, out, *, inj=None, dyn=None, cond=None, uniform=None, window=None, regions=None):
        """One pipeline call; returns (out or None, decoded or None).

        ``regions`` (see :meth:`step`) is used by the fused step on one box per packet; every
        other path writes the whole grid as the result's region.
        """
        if regions is not None and not (a.flags.c_contiguous and (out is None or out.flags.c_contiguous)):
            self.forget_regions(regions, 2, a.shape)
            regions = None
        if not a.flags.c_contiguous:
            a = np.ascontiguousarray(a)
        if out is not None and not out.flags.c_contiguous:
            res, dec = self._run(a, None, inj=inj, dyn=dyn, cond=cond, uniform=uniform, window=window)
            if res is not None:
                out[...] = res
            return (out if res is not None else None), dec
        if out is None:
            out = np.empty_like(a)
        flat = a.reshape(-1)
        bits = flat.view(_BITS[a.dtype.itemsize])
        n = self._shape(a.shape)
        fi, vals = inj if inj is not None else (_NO_INDEX, _NO_VALUES)
        if dyn is not None:
            exc, exc_w, inh, inh_w = self._packed_taps(dyn[0], dyn[1])
            phi = float(dyn[2])
        else:
            exc = inh = _NO_COND
            exc_w = inh_w = _NO_INDEX
            phi = 0.0
        if cond is not None:
            axes = tuple(cond[0])
            cmask = self._cmask(axes, a.ndim)
            ctab = np.ascontiguousarray(cond[1], dtype=np.float64).reshape(-1, len(axes))
        else:
            cmask, ctab = n, _NO_COND
        uni = _NO_VALUES
        if uniform is not None:
            uni = np.ascontiguousarray(uniform, dtype=np.float64).reshape(-1)
        decoded = np.empty(a.ndim, dtype=np.float64) if window is not None else _NO_DECODE
        if dyn is not None and window is not None and not self._dense:  # the fused step: one box per packet
            if regions is None:
                regions = self.new_regions(a.shape)
            st, st_bits = self._staging(flat.shape[0], bits.dtype, flat.dtype)
            status = _p.packets_step(
                flat, bits, out.reshape(-1), self._workspace(flat.shape[0]), n,
                fi, vals,
                exc, exc_w, inh, inh_w, phi,
                cond is not None, cmask, ctab,
                uni.shape[0] > 0, uni,
                int(window), decoded,
                self._par_work, self._nthreads(),
                regions, st, st_bits,
            )
            if status == _p.STATUS_BAD_REGIONS:
                raise InvalidInputError(
                    f"regions out of range for a grid of shape {a.shape}: every box's starts must lie in [0, n) "
                    "and its lengths in [0, n] per axis (NumbaBackend.forget_regions resets a list to the whole grid)")
            if status != _k.STATUS_OK:
                return None, None
            return out, decoded
        if regions is not None:
            self.forget_regions(regions, 2, a.shape)
        status = _k.pipeline(
            flat, bits, out.reshape(-1), self._workspace(flat.shape[0]), n,
            fi, vals,
            dyn is not None, exc, exc_w, inh, inh_w, phi,
            cond is not None, cmask, ctab,
            uni.shape[0] > 0, uni,
            window is not None, int(window or 0), decoded,
            self._dense, self._par_work, self._nthreads(),
        )
        if status != _k.STATUS_OK:
            return None, None
        return out, (decoded if window is not None else None)

    # ------------------------------------------------------------------ contract
    def dynamics(self, a, exc, inh, phi, out=None):
        return self._run(a, out, dyn=(exc, inh, phi))[0]

    def shift(self, a, shifts, out=None):
        return self._run(a, out, uniform=shifts)[0]

    def shift_conditional(self, a, shift_axes, shifts, out=None):
        return self._run(a, out, cond=(shift_axes, shifts))[0]

    def inject(self, a, flat_index, values, out=None):
        a = np.ascontiguousarray(a)
        res = out if out is not None and out.flags.c_contiguous else np.empty_like(a)
        _k.inject_grid(
            a.reshape(-1), res.reshape(-1),
            *_injection_arrays(flat_index, values),
        )
        if out is not None and res is not out:
            out[...] = res
            return out
        return res

    def decode(self, a, window):
        a = np.ascontiguousarray(a)
        res = np.empty(a.ndim, dtype=np.float64)
        _k.decode_grid(a.reshape(-1), self._shape(a.shape), int(window), res)
        return res

    #: :meth:`step` takes ``regions``: where the activity can be non-zero (see there)
    tracks_regions = True

    def step(self, a, *, flat_index, values, exc, inh, phi, shift_axes, cond_shifts,
             uniform_shifts, window, out=None, regions=None):
        """Fused step (Alg 3-5, OpenRatSLAM's step order): one compiled call for injection to decoding.

        ``regions`` (optional; int64, shape (3, R, 2, ndim), from :meth:`new_regions`) spares
        the passes over the whole grid when the caller knows where its arrays can be non-zero.
        Each ``regions[i]`` is a list of up to R boxes, box j per axis an arc (row 0 the
        starts, row 1 the lengths, in cells; a box of no cells is an unused entry):
        ``regions[0]`` holds every non-zero cell of ``a``, ``regions[1]`` every non-zero cell
        of ``out``'s current content (one box of the whole grid: not known). A step that
        returns an activity writes into ``regions[2]`` boxes holding every non-zero cell of the
        result (one per packet; the whole grid where the kernel does not know better). Same
        bits as without, as long as the regions given are true;
        :class:`cansim.population.Population` keeps them for its two grids.

        Raises
        ------
        InvalidInputError
            ``regions`` of another shape or dtype, or a box whose starts are not in ``[0, n)``
            or whose lengths are not in ``[0, n]`` (nothing is read or written).
        """
        if regions is not None:
            self._check_regions(regions, a.ndim)
        if a.ndim == 1 and cond_shifts is None and a.flags.c_contiguous:
            res = self._ring_step(a, flat_index, values, exc, inh, phi, uniform_shifts, window, out)
        elif self._small and a.flags.c_contiguous and (small := self._small_plan(a.shape, exc, inh)) is not None:
            res = self._small_step(a, small, flat_index, values, phi, shift_axes, cond_shifts,
                                   uniform_shifts, window, out)
        else:
            inj = _injection_arrays(flat_index, values)
            cond = (shift_axes, cond_shifts) if cond_shifts is not None else None
            # zero shifts (uniform or per condition) are skipped inside the kernel
            return self._run(a, out, inj=inj, dyn=(exc, inh, phi), cond=cond, uniform=uniform_shifts, window=window,
                             regions=regions)
        if regions is not None:
            self.forget_regions(regions, 2, a.shape)
        return res

    def run(self, a, inputs: RunInputs, *, exc, inh, phi, window, record_activity=False) -> RunResult:
        """T fused steps in one compiled call (:mod:`cansim.backends._numba_run`).

        Chooses the kernel :meth:`step` would choose for every step (ring, small full
        grid or generic pipeline) and calls it in a compiled loop with the same
        arguments, so the result equals T calls of :meth:`step` bit for bit. A 1-D run
        in which some steps carry a conditional shift (not made by cansim's motion
        models) mixes two kernels and takes the step-by-step loop of :class:`Backend`.
        """
        a = np.ascontiguousarray(a)
        T = inputs.n_steps
        d = a.ndim
        if d == 1 and inputs.has_cond.any():
            return super().run(a, inputs, exc=exc, inh=inh, phi=phi, window=window, record_activity=record_activity)
        from cansim.backends import _numba_run as _r

        flat = a.reshape(-1)
        bufs = (np.empty_like(flat), np.empty_like(flat))
        hist = np.empty((T if record_activity else 1, flat.shape[0]), dtype=a.dtype)
        decoded = np.empty((T, d), dtype=np.float64)
        ws = self._workspace(flat.shape[0])
        off, idx, val = inputs.inj_offsets, inputs.inj_index, inputs.inj_values
        uni = inputs.uniform_shifts
        has_uni = inputs.has_uniform
        if uni is None:
            uni = np.zeros((T, d), dtype=np.float64)
        else:
            uni = np.where(has_uni[:, None], uni, 0.0)  # a step without a uniform shift: zeros, as step() plans it
        small = self._small_plan(a.shape, exc, inh) if self._small and d > 1 else None
        if d == 1:
            status = _r.ring_run(flat, bufs[0], bufs[1], hist, bool(record_activity), off, idx, val,
                                 *self._ring_taps(exc, inh),
                                 float(phi), np.ascontiguousarray(uni[:, 0]), int(window), decoded,
                                 self._ring_workspace(flat.shape[0], exc, inh))
        else:
            k = len(inputs.shift_axes) if inputs.shift_axes is not None else 1
            if inputs.cond_shifts is not None:
                ctabs = np.ascontiguousarray(inputs.cond_shifts, dtype=np.float64).reshape(T, -1, k)
            else:
                ctabs = np.zeros((T, 1, 1), dtype=np.float64)
            has_cond = np.ascontiguousarray(inputs.has_cond, dtype=np.bool_)
            if small is not None:
                from cansim.backends._numba_small import small_run

                colmap, axes_arr, glines, lmeta = self._small_lines(a.shape, inputs.shift_axes)
                ew = tuple(len(t) for t in exc)
                iw = tuple(len(t) for t in inh)
                status = small_run(a.shape, ew, iw)(
                    flat, bufs[0], bufs[1], hist, bool(record_activity), ws, off, idx, val, small[1], small[2],
                    float(phi), has_cond, ctabs, colmap, glines, lmeta, axes_arr, uni, int(window), decoded,
                    a.dtype.itemsize == 4)
            else:
                excp, exc_w, inhp, inh_w = self._packed_taps(exc, inh)
                cmask = self._cmask(inputs.shift_axes, d) if inputs.shift_axes is not None else self._shape(a.shape)
                ubits = _BITS[a.dtype.itemsize]
                run_kernel = _r.pipeline_run
                extra = ()
                if not self._dense:  # one box per packet (cansim.backends._numba_packets)
                    run_kernel = _p.packets_run
                    extra = (np.empty(flat.shape[0], dtype=np.float64),)
                status = run_kernel(
                    flat, flat.view(ubits), bufs[0], hist, bool(record_activity), ws, *extra, self._shape(a.shape),
                    off, idx, val,
                    excp, exc_w, inhp, inh_w, float(phi),
                    has_cond, cmask, ctabs,
                    np.ascontiguousarray(has_uni, dtype=np.bool_), uni,
                    int(window), decoded,
                    *((self._dense,) if run_kernel is _r.pipeline_run else ()), self._par_work, self._nthreads(),
                )
        if status >= 0:
            return RunResult(None, None, None, int(status))
        # the ring and small-grid loops alternate between the two buffers; the generic one ends in bufs[0]
        last = bufs[0 if small is None and d > 1 else (T - 1) % 2].reshape(a.shape)
        return RunResult(last, decoded, hist.reshape((T,) + a.shape) if record_activity else None, None)

    def _small_plan(self, shape, exc, inh):
        """(compiled step, packed exc, packed inh) for a small fully covered grid, else None."""
        key = (shape, id(exc), id(inh))
        plan = self._small_cache.get(key)
        if plan is None or plan[3] is not exc or plan[4] is not inh:
            from cansim.backends import _numba_small as _s

            fn = excp = inhp = None
            if _s.applies(shape, exc, inh):
                ew = tuple(len(t) for t in exc)
                iw = tuple(len(t) for t in inh)
                fn, excp, inhp = _s.small_step(shape, ew, iw), _pack(exc)[0], _pack(inh)[0]
            if len(self._small_cache) > 16:
                self._small_cache.clear()
            plan = (fn, excp, inhp, exc, inh)
            self._small_cache[key] = plan
        return plan if plan[0] is not None else None

    def _small_lines(self, shape, shift_axes):
        """(colmap, shift axes, condition lines, condition runs) of the small-grid kernel, cached per
        shape and shifted axes (None: no conditional shift)."""
        key = ("lines", shape, None if shift_axes is None else tuple(shift_axes))
        tables = self._small_cache.get(key)
        if tables is None:
            from cansim.backends._numba_small import condition_lines, condition_runs

            d = len(shape)
            colmap = np.zeros(d, dtype=np.int64)
            if shift_axes is None:
                tables = (colmap, _NO_INDEX, _NO_LINES, np.ones((d, 2), dtype=np.int64))
            else:
                axes = np.asarray(shift_axes, dtype=np.int64)
                colmap[axes] = np.arange(len(axes))
                tables = (colmap, axes, condition_lines(shape, tuple(shift_axes)), condition_runs(shape, tuple(shift_axes)))
            self._small_cache[key] = tables
        return tables

    def _small_step(self, a, plan, flat_index, values, phi, shift_axes, cond_shifts, uniform_shifts, window, out):
        """Small full grids: one generated kernel (see :mod:`cansim.backends._numba_small`), which
        plans the shift cycles as the generic pipeline does (:func:`cansim.backends._numba_small.plan_cycles`)."""
        fn, excp, inhp = plan[0], plan[1], plan[2]
        d = a.ndim
        ctab = _NO_COND
        if cond_shifts is not None:
            ctab = np.ascontiguousarray(cond_shifts, dtype=np.float64).reshape(-1, len(shift_axes))
        colmap, axes_arr, glines, lmeta = self._small_lines(a.shape, None if cond_shifts is None else shift_axes)
        if uniform_shifts is None:
            uni = np.zeros(d, dtype=np.float64)
        else:
            uni = np.ascontiguousarray(uniform_shifts, dtype=np.float64).reshape(d)
        fi, vals = _injection_arrays(flat_index, values)
        dst = out if out is not None and out.flags.c_contiguous else np.empty_like(a)
        decoded = np.empty(d, dtype=np.float64)
        ok = fn(a.reshape(-1), dst.reshape(-1), self._workspace(a.size), fi, vals, excp, inhp, float(phi),
                cond_shifts is not None, ctab, colmap, glines, lmeta, axes_arr, uni, int(window), decoded,
                a.dtype.itemsize == 4)
        if not ok:
            return None, None
        if out is not None and dst is not out:
            out[...] = dst
            dst = out
        return dst, decoded

    def _ring_taps(self, exc, inh) -> tuple[np.ndarray, np.ndarray]:
        """Writable float64 copies of a ring's taps (cached): numba compiles read-only arrays
        (the kernels' taps are) into a kernel about 2x slower."""
        cached = self._ring_taps_cache
        if cached is None or cached[0] is not exc or cached[1] is not inh:
            cached = (exc, inh, np.array(exc[0], dtype=np.float64), np.array(inh[0], dtype=np.float64))
            self._ring_taps_cache = cached
        return cached[2], cached[3]

    def _ring_workspace(self, n: int, exc, inh) -> np.ndarray:
        from cansim.backends._numba_ring import workspace_size

        return self._workspace(-(-workspace_size(n, len(exc[0]), len(inh[0])) // 3))

    def _ring_step(self, a, flat_index, values, exc, inh, phi, uniform_shifts, window, out):
        """1-D rings: a small dedicated kernel (the N-D pipeline's dispatch cost dominates)."""
        kernel = self._ring_kernel
        if kernel is None:
            from cansim.backends._numba_ring import ring_step as kernel

            self._ring_kernel = kernel
        dst = out if out is not None and out.flags.c_contiguous and out is not a else np.empty_like(a)
        fi, vals = _injection_arrays(flat_index, values)
        shift = 0.0 if uniform_shifts is None else float(uniform_shifts[0])
        decoded = np.empty(1, dtype=np.float64)
        if not kernel(a, dst, fi, vals, *self._ring_taps(exc, inh), float(phi), shift, int(window), decoded,
                      self._ring_workspace(a.shape[0], exc, inh)):
            return None, None
        if out is not None and dst is not out:
            out[...] = dst
            dst = out
        return dst, decoded


def _injection_arrays(flat_index, values) -> tuple[np.ndarray, np.ndarray]:
    """The injection as (int64 indices, float64 values), 1-D contiguous; empty arrays for none."""
    if flat_index is None or not len(flat_index):
        return _NO_INDEX, _NO_VALUES
    return _as_contiguous(flat_index, np.int64), _as_contiguous(values, np.float64)


def _as_contiguous(x, dtype) -> np.ndarray:
    """``x`` as a 1-D C-contiguous array of ``dtype``, without a copy when it already is one."""
    if isinstance(x, np.ndarray) and x.dtype == dtype and x.ndim == 1 and x.flags.c_contiguous:
        return x
    return np.ascontiguousarray(x, dtype=dtype).reshape(-1)


def _pack(taps: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis tap arrays as one zero-padded (ndim, max_width) float64 array plus widths."""
    widths = np.array([len(t) for t in taps], dtype=np.int64)
    packed = np.zeros((len(taps), int(widths.max())), dtype=np.float64)
    for k, t in enumerate(taps):
        packed[k, : len(t)] = t
    return packed, widths
