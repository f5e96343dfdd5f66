"""Recurrent connectivity of a spiking attractor: the rate model's kernels as synapses.

The rate step (thesis Alg 3-5) maps activity ``A`` to ``e = A * K_E`` and then to
``e - e * K_I`` (periodic convolutions with the separable excitation and inhibition
kernels of :class:`cansim.params.AttractorParams`). The spiking population uses the
same linear map as its synaptic kernel: a spike of cell ``j`` raises the synaptic
current of cell ``i`` by

``W_ij = w_rec * K(i - j - delta) - w_global``,   ``K = K_E * (delta_0 - K_I)``

where ``delta_0`` is the unit impulse, ``w_global`` the global inhibition every spike
sends to every cell, and ``delta`` (cells per axis) a velocity-dependent shift of the
kernel - the asymmetric, velocity-modulated connectivity of Zhang (1996): with
``delta != 0`` the packet is pushed ahead and moves. A fractional shift uses the same
linear split ``(1 - frac, frac)`` as the rate model's path integration (Fig 5.11).

The composite kernel ``K`` is stored densely but only over its support (width
``w_E + w_I - 1`` per axis, folded onto the axis when wider), so a spike costs
``prod(widths)`` additions and no ``N x N`` matrix is ever built for simulation;
:meth:`RecurrentKernel.dense_matrix` exists for NIR export and tests of small grids.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.params import AttractorParams

__all__ = ["RecurrentKernel", "composite_kernel"]


def _conv_full(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.convolve(a, b, mode="full")


def composite_kernel(params: AttractorParams, ndim: int) -> np.ndarray:
    """The dense kernel ``K_E * (delta_0 - K_I)`` of an ``ndim``-axis grid.

    Parameters
    ----------
    params : AttractorParams
        Excitation and inhibition kernels (their taps are used unchanged).
    ndim : int
        Number of axes.

    Returns
    -------
    ndarray, float64, shape ``(w_E[a] + w_I[a] - 1 for a in axes)``
        Centre at ``shape // 2`` on every axis. Its sum is ``sum(K_E) * (1 - sum(K_I))``
        (0 for normalised kernels: excitation and inhibition balance).
    """
    exc, inh = params.kernels(ndim)
    e = exc.dense()
    ie = np.ones((), dtype=np.float64)
    for te, ti in zip(exc.taps, inh.taps):
        ie = np.multiply.outer(ie, _conv_full(te, ti))
    pad = [((ie.shape[a] - e.shape[a]) // 2,) * 2 for a in range(ndim)]
    return np.pad(e, pad) - ie


@dataclass(frozen=True)
class RecurrentKernel:
    """A shift-invariant synaptic kernel on a periodic grid, stored over its support.

    A spike at cell ``p`` adds ``weights[k]`` to the synaptic current of cell
    ``(p + offset + k) mod shape`` for every multi-index ``k`` of ``weights``.

    Parameters
    ----------
    weights : ndarray, float64, shape ``(w_0, ..., w_{d-1})``
        Current jump per spike (threshold units), already scaled by ``w_rec``.
    offset : tuple of int
        Position of ``weights[0, ..., 0]`` relative to the presynaptic cell, per axis.
    shape : tuple of int
        The grid.
    """

    weights: np.ndarray
    offset: tuple[int, ...]
    shape: tuple[int, ...]

    @classmethod
    def from_params(cls, params: AttractorParams, shape: Sequence[int], recurrent_weight: float) -> "RecurrentKernel":
        """``recurrent_weight * K_E * (delta_0 - K_I)``, centred, folded onto ``shape``."""
        shape = tuple(int(n) for n in shape)
        w = float(recurrent_weight)
        if not (math.isfinite(w) and w >= 0):
            raise ConfigError(f"recurrent_weight must be finite and >= 0, got {recurrent_weight!r}")
        k = composite_kernel(params, len(shape)) * w
        return cls(k, tuple(-(s // 2) for s in k.shape), shape).folded()

    def folded(self) -> "RecurrentKernel":
        """Wrap axes wider than the grid onto it (exact: the grid is periodic)."""
        w, off = self.weights, list(self.offset)
        for ax, n in enumerate(self.shape):
            if w.shape[ax] > n:
                out = np.zeros(w.shape[:ax] + (n,) + w.shape[ax + 1 :], dtype=np.float64)
                for k in range(w.shape[ax]):  # target (off + k) mod n, stored from index 0 = off mod n
                    dst = (k + off[ax]) % n - off[ax] % n
                    sl_out = [slice(None)] * w.ndim
                    sl_in = [slice(None)] * w.ndim
                    sl_out[ax], sl_in[ax] = dst % n, k
                    out[tuple(sl_out)] += w[tuple(sl_in)]
                w = out
            off[ax] %= n  # the grid is periodic: keep offsets small whatever the shift
        w = np.ascontiguousarray(w, dtype=np.float64)
        w.setflags(write=False)
        return RecurrentKernel(w, tuple(off), self.shape)

    def shifted(self, cells: Sequence[float]) -> "RecurrentKernel":
        """The kernel moved by a real number of cells per axis (linear split, Fig 5.11).

        Parameters
        ----------
        cells : sequence of float, shape (ndim,)
            Shift per axis in cells; finite.
        """
        s = np.asarray(cells, dtype=np.float64).reshape(-1)
        if s.shape != (len(self.shape),):
            raise ShapeError(f"shift must have {len(self.shape)} entries (one per axis), got {s.shape[0]}")
        if not np.isfinite(s).all():
            raise InvalidInputError(f"shift must be finite, got {s.tolist()}; check the velocity input")
        w, off = self.weights, list(self.offset)
        for ax, d in enumerate(s):
            if d == 0.0:
                continue
            lo = math.floor(d)
            f = float(d - lo)
            off[ax] += lo
            if f != 0.0:
                n = w.shape[ax]
                out = np.zeros(w.shape[:ax] + (n + 1,) + w.shape[ax + 1 :], dtype=np.float64)
                sl = [slice(None)] * w.ndim
                sl[ax] = slice(0, n)
                out[tuple(sl)] += (1.0 - f) * w
                sl[ax] = slice(1, n + 1)
                out[tuple(sl)] += f * w
                w = out
        return RecurrentKernel(w, tuple(off), self.shape).folded()

    def dense_matrix(self, global_weight: float = 0.0) -> np.ndarray:
        """The full ``N x N`` matrix ``W[i, j]`` (post ``i``, pre ``j``, C-order flat cells).

        For NIR export and tests of small grids only: memory is ``8 N^2`` bytes.
        """
        n = int(np.prod(self.shape))
        mat = np.full((n, n), -float(global_weight), dtype=np.float64)
        targets = scatter_targets(np.arange(n, dtype=np.int64), self)  # (n_pre, K)
        vals = self.weights.ravel()
        for j in range(n):
            np.add.at(mat[:, j], targets[j], vals)
        return mat


def scatter_targets(pre: np.ndarray, kernel: RecurrentKernel) -> np.ndarray:
    """Flat target cells of every kernel entry for each presynaptic flat index.

    Returns
    -------
    ndarray, int64, shape ``(len(pre), kernel.weights.size)``; entries in C order of the kernel.
    """
    shape = kernel.shape
    coords = np.unravel_index(np.asarray(pre, dtype=np.int64), shape)
    strides = np.cumprod((1,) + shape[::-1])[-2::-1] if len(shape) > 1 else np.array([1])
    flat = np.zeros((len(pre),) + (1,) * len(shape), dtype=np.int64)
    for ax, n in enumerate(shape):
        t = (coords[ax][:, None] + kernel.offset[ax] + np.arange(kernel.weights.shape[ax])[None, :]) % n
        bshape = [len(pre)] + [1] * len(shape)
        bshape[ax + 1] = kernel.weights.shape[ax]
        flat = flat + t.reshape(bshape) * int(strides[ax])
    return flat.reshape(len(pre), -1)
