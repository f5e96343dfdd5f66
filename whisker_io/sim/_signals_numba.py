"""Compiled kernel of the whisk-cycle synthesis (:func:`whisker_io.sim.signals.simulate_whisk_cycle`).

One pass over the (n, T) samples does what :func:`~whisker_io.sim.signals.deflection_counts`
followed by :func:`~whisker_io.sim.signals.add_sensor_noise` do in about twenty numpy
passes: rotation past contact (with slip-off), the tapered-cantilever deflection
``G k(a) max(theta - theta_c, 0)`` split on the sensor axes and saturated, the
pre-drawn sensor noise, quantisation and ADC clipping. Every sample goes through the
same IEEE operations in the same order as the numpy functions (no fast-math, so no
fused multiply-add), so the outputs are the same bits; ``tests/test_signals.py``
compares the two on random contacts.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["synthesise_cycle"]


@njit(cache=True, inline="always")
def _clip(v: float, lim: float) -> float:  # pragma: no cover - compiled
    """``v`` saturated at +-``lim`` (the ADC range; ``np.clip``'s result, comparisons only)."""
    if v < -lim:
        return -lim
    if v > lim:
        return lim
    return v


@njit(cache=True)
def synthesise_cycle(
    angles: np.ndarray,
    theta_c: np.ndarray,
    slip: np.ndarray,
    gain_k: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
    lim: float,
    noise: np.ndarray,
    noise_std: float,
    angle_noise_std: float,
    quantize: bool,
    x: np.ndarray,
    y: np.ndarray,
    th: np.ndarray,
    first_past: np.ndarray,
    peak_index: np.ndarray,
    peak_y: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Fill the measured ``x``, ``y``, ``th`` (all (n, T)) and, per whisker, the ground truth of
    the noise-free saturated y-deflection ``y_clean``.

    ``angles`` (n, T) true whisk angles; per whisker ``theta_c`` (inf: free), ``slip``
    (inf: none), ``gain_k = G k(a)`` (0: free) and the sensor split ``fx``, ``fy``;
    ``noise`` (3, n, T) standard-normal draws for x, y and the angle. Per whisker out:
    ``first_past`` the first sample with ``angles > theta_c`` (-1: none), ``peak_index``
    the first sample of the largest ``|y_clean|`` (``np.argmax(np.abs(y_clean))``) and
    ``peak_y`` the ``y_clean`` there (0: no deflection in the cycle).
    """
    n, T = angles.shape
    for i in range(n):
        first_past[i] = -1
        best = -1.0
        peak_index[i] = 0
        peak_y[i] = 0.0
        tc = theta_c[i]
        s = slip[i]
        slipping = s < np.inf
        g = gain_k[i]
        ax = fx[i]
        ay = fy[i]
        run = 0.0
        for k in range(T):
            a = angles[i, k]
            v = a - tc
            past = v if v >= 0.0 else 0.0  # np.maximum(v, 0.0) for non-NaN v
            if slipping:
                run = past if k == 0 else (run if run >= past else past)  # np.maximum.accumulate
                if run >= s:
                    past = 0.0
            d = g * past
            dx = _clip(d * ax, lim)
            dy = _clip(d * ay, lim)
            if first_past[i] < 0 and a > tc:
                first_past[i] = k
            ady = abs(dy)
            if ady > best:
                best = ady
                peak_index[i] = k
                peak_y[i] = dy
            mx = dx + noise_std * noise[0, i, k]
            my = dy + noise_std * noise[1, i, k]
            if quantize:
                mx = np.rint(mx)
                my = np.rint(my)
            x[i, k] = _clip(mx, lim)
            y[i, k] = _clip(my, lim)
            th[i, k] = a + angle_noise_std * noise[2, i, k]


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
