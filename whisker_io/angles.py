"""Angle wrapping with named conventions, in constant time.

Three conventions, one function each (radians; a scalar gives a ``float``, an
array gives an ndarray of the same shape):

================================  ==============  =====================================
 function                          range           used for
================================  ==============  =====================================
 :func:`wrap_to_pi`                [-pi, pi)       heading errors, metrics
 :func:`wrap_to_pi_closed_above`   (-pi, pi]       OpenRatSLAM's ``clip_rad_180``
 :func:`wrap_to_2pi`               [0, 2 pi)       OpenRatSLAM's ``clip_rad_360``
================================  ==============  =====================================

Decision (exactness and cost): the C++ reference wraps with subtraction loops
(``while (a > pi) a -= 2 pi``), which take time proportional to ``|a|`` - a
heading of 1e17 rad never returns. Here the result is that loop's result, bit
for bit, whenever the loop would stop within :data:`LOOP_TURNS` turns (so an
experience map fed ordinary odometry behaves exactly as OpenRatSLAM's); beyond
that the angle is reduced by an exact floating-point remainder (``np.fmod``)
first. Either way the cost is constant and the result is inside the range.
Non-finite angles raise :class:`~whisker_io.errors.InvalidInputError`.

:func:`wrap_scalar` is the same algorithm on one float, pure arithmetic with no
validation, for hot loops: the SE(2) map calls it directly and its numba relaxation
kernel compiles it (``numba.njit(wrap_scalar)``), so the wrap is written once.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from whisker_io.validation import finite_array, finite_scalar

__all__ = ["TWO_PI", "LOOP_TURNS", "wrap_to_pi", "wrap_to_pi_closed_above", "wrap_to_2pi", "wrap_scalar"]

#: 2 pi, exactly twice the double ``math.pi``.
TWO_PI: float = 2.0 * math.pi
#: Turns within which the result equals the C++ subtraction loop bit for bit.
LOOP_TURNS: int = 4


def wrap_scalar(angle_rad: float, lower_rad: float, closed_above: bool) -> float:
    """One finite angle wrapped into ``[lower, lower + 2 pi)`` (or ``(lower, lower + 2 pi]``).

    The kernel behind the public functions, for callers that have validated already:
    no checks, plain float arithmetic (numba-compilable). ``lower_rad`` is ``-pi``
    (``closed_above``: OpenRatSLAM's ``clip_rad_180``; else :func:`wrap_to_pi`) or
    ``0`` (OpenRatSLAM's ``clip_rad_360``). Bit for bit the subtraction loop's result
    within :data:`LOOP_TURNS` turns; beyond, exact ``fmod`` first (constant time).

    Parameters
    ----------
    angle_rad : float
        A finite angle, radians (NaN gives NaN: validate first).
    lower_rad : float
        ``-math.pi`` or ``0.0``.
    closed_above : bool
        True for the range ``(lower, lower + 2 pi]``.

    Returns
    -------
    float
        The wrapped angle, radians.

    Examples
    --------
    >>> wrap_scalar(3.5 * math.pi, -math.pi, True) == wrap_to_pi_closed_above(3.5 * math.pi)
    True
    """
    upper = lower_rad + TWO_PI  # exact for lower in {-pi, 0}
    r = angle_rad
    if closed_above:
        if lower_rad < r <= upper:  # in range: the loops below would not move it
            return r
        for _ in range(LOOP_TURNS):
            if r > upper:
                r -= TWO_PI
        for _ in range(LOOP_TURNS):
            if r <= lower_rad:
                r += TWO_PI
        if lower_rad < r <= upper:
            return r
    else:
        if lower_rad <= r < upper:
            return r
        for _ in range(LOOP_TURNS):
            if r < lower_rad:
                r += TWO_PI
        for _ in range(LOOP_TURNS):
            if r >= upper:
                r -= TWO_PI
        if lower_rad <= r < upper:
            return r
    # Python's float modulo is the exact remainder (fmod) moved into [0, 2 pi), the same
    # as the array path's fmod-then-shift; numba implements the same semantics.
    f = (angle_rad - lower_rad) % TWO_PI + lower_rad
    if closed_above:
        if f <= lower_rad:
            f += TWO_PI
        if f > upper:
            f -= TWO_PI
    else:
        if f >= upper:
            f -= TWO_PI
        if f < lower_rad:
            f += TWO_PI
    return f


def _wrap(angle: ArrayLike, lower: float, closed_above: bool, name: str) -> float | NDArray[np.float64]:
    if np.ndim(angle) == 0:
        return wrap_scalar(finite_scalar(angle, name), lower, closed_above)
    a = np.atleast_1d(finite_array(angle, None, name))
    upper = lower + TWO_PI  # exact for lower in {-pi, 0}
    r = a.copy()
    # The reference loops, each unrolled LOOP_TURNS times. clip_rad_180 (closed
    # above) first steps down while above the range, then up while at or below
    # it; clip_rad_360 first steps up while below, then down while at or above.
    for phase in ("down", "up") if closed_above else ("up", "down"):
        for _ in range(LOOP_TURNS):
            if phase == "down":
                r = np.where(r > upper if closed_above else r >= upper, r - TWO_PI, r)
            else:
                r = np.where(r <= lower if closed_above else r < lower, r + TWO_PI, r)
    outside = (r > upper) | (r <= lower) if closed_above else (r >= upper) | (r < lower)
    if np.any(outside):
        # Far outside: exact remainder in (-2 pi, 2 pi), shifted into range, then
        # one step of each loop for the rounding at the ends.
        f = np.fmod(a[outside] - lower, TWO_PI)
        f = np.where(f < 0, f + TWO_PI, f) + lower
        if closed_above:
            f = np.where(f <= lower, f + TWO_PI, f)
            f = np.where(f > upper, f - TWO_PI, f)
        else:
            f = np.where(f >= upper, f - TWO_PI, f)
            f = np.where(f < lower, f + TWO_PI, f)
        r[outside] = f
    return r


@overload
def wrap_to_pi(angle_rad: float) -> float: ...
@overload
def wrap_to_pi(angle_rad: NDArray[np.float64]) -> NDArray[np.float64]: ...
def wrap_to_pi(angle_rad):
    """``angle_rad - 2 pi k`` in the half-open range [-pi, pi).

    Parameters
    ----------
    angle_rad : float or array_like
        Finite angle(s), radians; a scalar gives a float, an array the same shape.

    Raises
    ------
    InvalidInputError
        A NaN/inf or non-numeric angle.

    Examples
    --------
    >>> wrap_to_pi(math.pi)
    -3.141592653589793
    """
    return _wrap(angle_rad, -math.pi, False, "angle_rad")


@overload
def wrap_to_pi_closed_above(angle_rad: float) -> float: ...
@overload
def wrap_to_pi_closed_above(angle_rad: NDArray[np.float64]) -> NDArray[np.float64]: ...
def wrap_to_pi_closed_above(angle_rad):
    """The same angle in (-pi, pi] - OpenRatSLAM's ``clip_rad_180`` result within
    :data:`LOOP_TURNS` turns (input, output shape and errors as :func:`wrap_to_pi`).

    >>> wrap_to_pi_closed_above(-math.pi)
    3.141592653589793
    """
    return _wrap(angle_rad, -math.pi, True, "angle_rad")


@overload
def wrap_to_2pi(angle_rad: float) -> float: ...
@overload
def wrap_to_2pi(angle_rad: NDArray[np.float64]) -> NDArray[np.float64]: ...
def wrap_to_2pi(angle_rad):
    """The same angle in [0, 2 pi) - OpenRatSLAM's ``clip_rad_360`` result within
    :data:`LOOP_TURNS` turns (input, output shape and errors as :func:`wrap_to_pi`).

    >>> wrap_to_2pi(-0.5 * math.pi)
    4.71238898038469
    """
    return _wrap(angle_rad, 0.0, False, "angle_rad")
