"""Reference backend in plain NumPy: written for clarity, the oracle of the others."""

from __future__ import annotations

import itertools
from typing import Optional, Sequence

import numpy as np

from cansim.backends.base import Backend
from cansim.decoding import population_vector_window

__all__ = ["NumpyBackend", "periodic_convolve_1d", "dense_periodic_convolve"]


def periodic_convolve_1d(a: np.ndarray, taps: np.ndarray, axis: int) -> np.ndarray:
    """Scatter every cell's activity to its neighbours along ``axis`` with ``taps`` (Alg 3).

    ``out[i + j - c] += a[i] * taps[j]`` with wrap-around, ``c = len(taps) // 2``.
    Taps longer than the axis wrap more than once and add up (as OpenRatSLAM's wrap tables).
    Computed in float64 and returned as float64.
    """
    c = len(taps) // 2
    a64 = a.astype(np.float64, copy=False)
    out = np.zeros(a.shape, dtype=np.float64)
    for j, w in enumerate(taps):
        out += w * np.roll(a64, j - c, axis=axis)
    return out


def separable_periodic_convolve(a: np.ndarray, taps: Sequence[np.ndarray]) -> np.ndarray:
    """Apply one 1-D periodic pass per axis: the product kernel, O(N * sum of widths)."""
    out = a.astype(np.float64)
    for axis, t in enumerate(taps):
        out = periodic_convolve_1d(out, t, axis)
    return out


def dense_periodic_convolve(a: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Dense N-D periodic convolution (scatter form), O(N * prod of widths). Tests only."""
    centre = [s // 2 for s in kernel.shape]
    a64 = a.astype(np.float64)
    out = np.zeros(a.shape, dtype=np.float64)
    for offs in itertools.product(*(range(s) for s in kernel.shape)):
        w = kernel[offs]
        if w != 0:
            out += w * np.roll(a64, [o - c for o, c in zip(offs, centre)], axis=tuple(range(a.ndim)))
    return out


def _fractional_roll(a: np.ndarray, s: float, axis: int) -> np.ndarray:
    """Integer roll by floor(s) plus the linear split (1 - f, f) of Fig 5.11."""
    lo = int(np.floor(s))
    f = s - lo
    out = np.roll(a, lo, axis=axis)
    if f != 0.0:
        out = (1.0 - f) * out + f * np.roll(a, lo + 1, axis=axis)
    return out


class NumpyBackend(Backend):
    """Plain NumPy reference; computes in float64 and stores in the activity's dtype."""

    name = "numpy"

    def dynamics(self, a, exc, inh, phi, out=None):
        e = separable_periodic_convolve(a, exc)
        b = e - separable_periodic_convolve(e, inh)
        c = np.where(b >= phi, b - phi, 0.0)  # Alg 5: cells below phi become 0
        total = c.sum()
        if not (np.isfinite(total) and total > 0):
            return None
        res = c / total
        if out is None:
            return res.astype(a.dtype)
        out[...] = res
        return out

    def shift(self, a, shifts, out=None):
        cur = a.astype(np.float64)
        for axis, s in enumerate(shifts):
            if s != 0.0:
                cur = _fractional_roll(cur, float(s), axis)
        return _store(cur, a.dtype, out)

    def shift_conditional(self, a, shift_axes, shifts, out=None):
        cond_axes = [ax for ax in range(a.ndim) if ax not in shift_axes]
        a64 = a.astype(np.float64)
        res = np.empty_like(a64)
        for cidx in np.ndindex(*[a.shape[ax] for ax in cond_axes]):
            sel: list = [slice(None)] * a.ndim
            for ax, i in zip(cond_axes, cidx):
                sel[ax] = i
            block = a64[tuple(sel)]  # the remaining axes are shift_axes, in order
            for k, s in enumerate(shifts[cidx]):
                if s != 0.0:
                    block = _fractional_roll(block, float(s), k)
            res[tuple(sel)] = block
        return _store(res, a.dtype, out)

    def inject(self, a, flat_index, values, out=None):
        res = a.astype(np.float64).ravel()
        np.add.at(res, np.asarray(flat_index, dtype=np.int64), np.asarray(values, dtype=np.float64))
        return _store(res.reshape(a.shape), a.dtype, out)

    def decode(self, a, window):
        return population_vector_window(a, window)


def _store(res: np.ndarray, dtype: np.dtype, out: Optional[np.ndarray]) -> np.ndarray:
    if out is None:
        return res.astype(dtype)
    out[...] = res
    return out
