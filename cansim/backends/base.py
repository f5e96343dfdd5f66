"""The backend contract: the kernels every backend implements with the same names.

A backend works on host NumPy arrays (C-contiguous, float32 or float64) so the
three implementations are interchangeable and testable against each other.
Every function leaves its input ``a`` untouched and writes its result to ``out``
(a distinct array of the same shape and dtype) or to a new array when ``out`` is
None, and returns the array holding the result. Index/shift arguments are
validated by :class:`cansim.population.Population` before they reach a backend.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Optional, Sequence

import numpy as np

__all__ = ["Backend"]


class Backend(ABC):
    """Abstract CAN backend. Subclasses implement the six kernels below.

    The conformance suite (``tests/test_backend_conformance.py``) runs every test
    against every available backend with the numpy backend as the oracle.
    """

    #: registry name, e.g. ``"numpy"``
    name: str = "abstract"

    @abstractmethod
    def dynamics(
        self,
        a: np.ndarray,
        exc: Sequence[np.ndarray],
        inh: Sequence[np.ndarray],
        phi: float,
        out: Optional[np.ndarray] = None,
    ) -> Optional[np.ndarray]:
        """Local excitation, local inhibition, global inhibition and normalisation.

        ``e = a (*) E`` (periodic, separable, scatter form of Alg 3);
        ``b = e - e (*) I`` (Alg 4, OpenRatSLAM semantics);
        ``c = max(b - phi, 0)`` (Alg 5); ``out = c / sum(c)``.

        Parameters
        ----------
        a : ndarray, shape (n_0, ..., n_{d-1})
            Activity, not modified.
        exc, inh : sequence of ndarray, one 1-D odd-length float64 tap array per axis
            Separable excitation / inhibition kernels, centre at ``len // 2``.
        phi : float
            Global inhibition threshold.
        out : ndarray or None
            Destination, distinct from ``a``.

        Returns
        -------
        ndarray or None
            The normalised activity, or None when ``sum(c)`` is not > 0 (nothing
            is normalised; the caller reports the collapse).
        """

    @abstractmethod
    def shift(self, a: np.ndarray, shifts: np.ndarray, out: Optional[np.ndarray] = None) -> np.ndarray:
        """Shift the whole grid by a real number of cells per axis (SPEC §1.4).

        Along each axis a shift ``s`` is an integer roll by ``floor(s)`` plus a linear split
        ``(1 - f, f)``, ``f = s - floor(s)``, between ``floor(s)`` and ``floor(s) + 1``;
        axes are applied one after another (their product). Positive ``s`` moves
        activity toward higher indices. Total activity is conserved.

        Parameters
        ----------
        shifts : ndarray, shape (ndim,), float64
            Shift per axis in cells; any magnitude.
        """

    @abstractmethod
    def shift_conditional(
        self,
        a: np.ndarray,
        shift_axes: tuple[int, ...],
        shifts: np.ndarray,
        out: Optional[np.ndarray] = None,
    ) -> np.ndarray:
        """Shift each slice along ``shift_axes`` by its own real vector (heading-dependent translation).

        Parameters
        ----------
        shift_axes : tuple of int, ascending
            The axes that are translated (e.g. ``(0, 1)`` for x', y').
        shifts : ndarray, float64, shape ``cond_shape + (len(shift_axes),)``
            ``cond_shape`` is the shape of the remaining axes in their order; entry
            ``shifts[c]`` is the shift in cells applied to the slice at condition index ``c``.
        """

    @abstractmethod
    def inject(
        self,
        a: np.ndarray,
        flat_index: np.ndarray,
        values: np.ndarray,
        out: Optional[np.ndarray] = None,
    ) -> np.ndarray:
        """``out = a`` plus ``values`` scatter-added at flat (C-order) indices (repeats add up)."""

    @abstractmethod
    def decode(self, a: np.ndarray, window: int) -> np.ndarray:
        """Population-vector decoding around the most active cell (SPEC §1.6, Eq 5.11-5.12).

        Takes the first argmax cell (C order), a window of ``+-window`` cells on every
        axis with wrap-around (clipped to the axis so no cell counts twice), sums the
        window over all other axes, and returns per axis the activity-weighted
        circular mean index in ``[0, n)``, float64, shape (ndim,).
        """

    def step(
        self,
        a: np.ndarray,
        *,
        flat_index: Optional[np.ndarray],
        values: Optional[np.ndarray],
        exc: Sequence[np.ndarray],
        inh: Sequence[np.ndarray],
        phi: float,
        shift_axes: Optional[tuple[int, ...]],
        cond_shifts: Optional[np.ndarray],
        uniform_shifts: Optional[np.ndarray],
        window: int,
        out: Optional[np.ndarray] = None,
    ) -> tuple[Optional[np.ndarray], Optional[np.ndarray]]:
        """One full iteration in SPEC §1.2 order: inject, dynamics, conditional shift,
        uniform shift, decode. Returns ``(activity, decoded)`` or ``(None, None)`` when
        the dynamics collapse to zero. Backends may override with a fused kernel.
        """
        cur = a
        if flat_index is not None and len(flat_index):
            cur = self.inject(cur, flat_index, values)
        cur = self.dynamics(cur, exc, inh, phi, out=out)
        if cur is None:
            return None, None
        if cond_shifts is not None:
            cur = self.shift_conditional(cur, shift_axes, cond_shifts)
        if uniform_shifts is not None and np.any(uniform_shifts != 0):
            cur = self.shift(cur, uniform_shifts)
        return cur, self.decode(cur, window)
