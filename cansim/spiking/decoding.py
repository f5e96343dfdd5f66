"""Population-vector decoding of spike counts in a sliding window (thesis Eq 5.11-5.12).

The spike counts of the last ``window_steps`` steps play the role of the rate model's
activity: the estimate is :func:`cansim.decoding.population_vector_window` of the count
grid (argmax, a +-``half_width`` box with wrap-around, a circular mean per axis).
"""

from __future__ import annotations

from collections import deque
from typing import Sequence

import numpy as np

from cansim.axes import Axis
from cansim.decoding import population_vector_window
from cansim.errors import InvalidInputError, ZeroActivityError

__all__ = ["SpikeCountDecoder"]


class SpikeCountDecoder:
    """Sliding-window spike counts of a grid and their population vector.

    Parameters
    ----------
    axes : sequence of Axis
        The grid (as the population's :attr:`axes`).
    window_steps : int
        Length of the sliding window in simulation steps (>= 1).
    half_width : int
        Half-width of the decoding box in cells (>= 0).
    """

    def __init__(self, axes: Sequence[Axis], window_steps: int, half_width: int = 5) -> None:
        axes = tuple(axes)
        if not axes or any(not isinstance(a, Axis) for a in axes):
            raise InvalidInputError("axes must be a non-empty sequence of cansim.Axis")
        for name, val, lo in (("window_steps", window_steps, 1), ("half_width", half_width, 0)):
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < lo:
                raise InvalidInputError(f"{name} must be an integer >= {lo}, got {val!r}")
        self._axes = axes
        self._shape = tuple(a.size for a in axes)
        self._n = int(np.prod(self._shape))
        self._window = int(window_steps)
        self._half = int(half_width)
        self._steps = np.array([a.step for a in axes], dtype=np.float64)
        self.reset()

    @property
    def counts(self) -> np.ndarray:
        """Copy of the spike counts in the window, shape of the grid (int64)."""
        return self._counts.reshape(self._shape).copy()

    @property
    def window_steps(self) -> int:
        """Window length (steps)."""
        return self._window

    def reset(self) -> None:
        """Forget all spikes."""
        self._counts = np.zeros(self._n, dtype=np.int64)
        self._history: deque[np.ndarray] = deque()

    def add(self, spikes: np.ndarray) -> None:
        """Push one step's spikes (flat indices); the oldest step leaves the window."""
        s = np.asarray(spikes)
        if s.size and (s.dtype.kind not in "iu" or s.min() < 0 or s.max() >= self._n):
            raise InvalidInputError(f"spikes must be integer flat indices in [0, {self._n})")
        s = s.astype(np.int64, copy=False).ravel()
        np.add.at(self._counts, s, 1)
        self._history.append(s)
        if len(self._history) > self._window:
            old = self._history.popleft()
            np.subtract.at(self._counts, old, 1)

    def state_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The window (one row per step: its spike count, then the spikes) as named arrays for :meth:`restore_state`."""
        hist = list(self._history)
        return {prefix + "lengths": np.array([len(h) for h in hist], dtype=np.int64),
                prefix + "spikes": np.concatenate(hist) if hist else np.zeros(0, dtype=np.int64)}

    def restore_state(self, arrays, prefix: str = "") -> None:
        """Set the window written by :meth:`state_arrays` (raises CorruptFileError naming a bad field)."""
        from cansim.errors import CorruptFileError

        try:
            lengths = np.asarray(arrays[prefix + "lengths"], dtype=np.int64)
            spikes = np.asarray(arrays[prefix + "spikes"])
        except (KeyError, ValueError, TypeError) as exc:
            raise CorruptFileError(f"missing or malformed ({exc})", field=prefix + "lengths") from exc
        if lengths.ndim != 1 or len(lengths) > self._window or np.any(lengths < 0) or lengths.sum() != spikes.size \
                or spikes.ndim != 1 or (spikes.size and (spikes.dtype.kind not in "iu" or spikes.min() < 0 or spikes.max() >= self._n)):
            raise CorruptFileError("inconsistent spike window", field=prefix + "spikes")
        self.reset()
        for row in np.split(spikes.astype(np.int64), np.cumsum(lengths)[:-1]) if len(lengths) else []:
            self.add(row)

    def decode(self) -> np.ndarray:
        """Fractional cell index per axis, shape (ndim,).

        Raises
        ------
        ZeroActivityError
            No spike in the window: there is nothing to decode.
        """
        if not self._counts.any():
            raise ZeroActivityError("no spikes in the decoding window; run the population longer or seed a packet")
        return population_vector_window(self._counts.reshape(self._shape), self._half)

    def decode_physical(self) -> np.ndarray:
        """:meth:`decode` times each axis' step: radians on angular axes, metres on linear ones."""
        return self.decode() * self._steps
