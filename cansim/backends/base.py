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
from dataclasses import dataclass
from typing import NamedTuple, Optional, Sequence

import numpy as np

__all__ = ["Backend", "RunInputs", "RunResult"]


@dataclass(frozen=True)
class RunInputs:
    """The per-step inputs of a run of ``n_steps`` iterations, validated by the caller.

    :meth:`cansim.population.Population.run` builds it; a backend reads it in
    :meth:`Backend.run`. Step ``t`` is the iteration :meth:`Backend.step` would run with
    the keyword arguments :meth:`step_kwargs` gives for ``t``.

    Attributes
    ----------
    n_steps : int
        Number of iterations T (>= 1).
    inj_offsets : ndarray, shape (T + 1,), int64
        Step t injects ``inj_values[inj_offsets[t]:inj_offsets[t + 1]]`` at the flat
        indices ``inj_index[...]`` of the same slice (an empty slice: no injection).
    inj_index : ndarray, shape (M,), int64
        Flat C-order cell indices, in ``[0, size)``.
    inj_values : ndarray, shape (M,), float64
        Energies, finite and >= 0.
    shift_axes : tuple of int or None
        The axes of the heading-conditional translation (the same for every step that has one).
    cond_shifts : ndarray or None
        Shape ``(T,) + cond_shape + (len(shift_axes),)``, cells; row t is used when
        ``has_cond[t]``. None when no step has a conditional shift.
    has_cond : ndarray, shape (T,), bool
    uniform_shifts : ndarray or None
        Shape ``(T, ndim)``, cells; row t is used when ``has_uniform[t]``. None when no step
        has a uniform shift.
    has_uniform : ndarray, shape (T,), bool
    """

    n_steps: int
    inj_offsets: np.ndarray
    inj_index: np.ndarray
    inj_values: np.ndarray
    shift_axes: Optional[tuple[int, ...]]
    cond_shifts: Optional[np.ndarray]
    has_cond: np.ndarray
    uniform_shifts: Optional[np.ndarray]
    has_uniform: np.ndarray

    def injection(self, t: int) -> tuple[Optional[np.ndarray], Optional[np.ndarray]]:
        """``(flat_index, values)`` of step ``t``, or ``(None, None)`` when it injects nothing."""
        lo, hi = int(self.inj_offsets[t]), int(self.inj_offsets[t + 1])
        if hi == lo:
            return None, None
        return self.inj_index[lo:hi], self.inj_values[lo:hi]

    def step_kwargs(self, t: int) -> dict:
        """The per-step keyword arguments of :meth:`Backend.step` for step ``t``."""
        fi, vals = self.injection(t)
        cond = self.cond_shifts[t] if self.cond_shifts is not None and self.has_cond[t] else None
        uni = self.uniform_shifts[t] if self.uniform_shifts is not None and self.has_uniform[t] else None
        return dict(flat_index=fi, values=vals, shift_axes=self.shift_axes if cond is not None else None,
                    cond_shifts=cond, uniform_shifts=uni)


class RunResult(NamedTuple):
    """What :meth:`Backend.run` returns.

    Attributes
    ----------
    activity : ndarray or None
        The activity after the last step (None after a collapse).
    decoded : ndarray or None
        Shape (T, ndim), float64: the decoded position after every step.
    history : ndarray or None
        Shape ``(T,) + a.shape``, the activity after every step, when it was asked for.
    collapsed_at : int or None
        The first step whose dynamics collapsed to zero (the run stops there and the
        other fields are None), or None.
    """

    activity: Optional[np.ndarray]
    decoded: Optional[np.ndarray]
    history: Optional[np.ndarray]
    collapsed_at: Optional[int]


class Backend(ABC):
    """Abstract CAN backend. Subclasses implement the five abstract kernels below
    (``dynamics``, ``shift``, ``shift_conditional``, ``inject``, ``decode``); ``step`` and
    ``run`` have generic versions built on them that a backend may replace with fused ones.

    :func:`cansim.backends.register_backend` names a backend of your own (its ``name``
    attribute must be that name), and the conformance suite
    (:mod:`cansim.testing.conformance`) compares it with the numpy reference.
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
        """Shift the whole grid by a real number of cells per axis (Fig 5.7-5.11).

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
        """Population-vector decoding around the most active cell (Eq 5.11-5.12, Eq 5.11-5.12).

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
        """One full iteration in Alg 3-5, OpenRatSLAM's step order order: inject, dynamics, conditional shift,
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

    def run(
        self,
        a: np.ndarray,
        inputs: RunInputs,
        *,
        exc: Sequence[np.ndarray],
        inh: Sequence[np.ndarray],
        phi: float,
        window: int,
        record_activity: bool = False,
    ) -> RunResult:
        """``inputs.n_steps`` iterations of :meth:`step`, each on the result of the one before.

        The result equals calling :meth:`step` once per step with
        ``inputs.step_kwargs(t)`` bit for bit. This default does exactly that in a
        Python loop, so any backend runs; compiled backends override it with one call
        for the whole run. ``a`` is not modified.

        Returns
        -------
        RunResult
            The last activity, the decoded positions (T, ndim), the activity after
            every step when ``record_activity``, or the first step that collapsed.
        """
        n = inputs.n_steps
        decoded = np.empty((n, a.ndim), dtype=np.float64)
        history = np.empty((n,) + a.shape, dtype=a.dtype) if record_activity else None
        bufs = [np.empty_like(a), np.empty_like(a)]
        k = 0
        cur = a
        for t in range(n):
            new, dec = self.step(cur, exc=exc, inh=inh, phi=phi, window=window, out=bufs[k],
                                 **inputs.step_kwargs(t))
            if new is None:
                return RunResult(None, None, None, t)
            if new is bufs[k]:
                k = 1 - k  # the next step writes the other buffer
            decoded[t] = dec
            if history is not None:
                history[t] = new
            cur = new
        return RunResult(cur.copy() if cur is a else cur, decoded, history, None)
