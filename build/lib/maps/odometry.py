"""Typed odometry, validated once at the model boundary.

Two forms cross the map and pose-cell interfaces:

* :class:`PlanarOdometry` - a ground robot (RatSLAM, thesis Ch.2-3): forward speed
  ``v`` (m/s), yaw rate ``omega`` (rad/s) over ``dt`` (s);
* :class:`SpatialOdometry` - the whisker array on a 6-DoF arm (WhiskerRatSLAM, Eq 5.7):
  linear velocity ``v`` (3,) m/s and angular velocity ``omega`` (3,) rad/s (a
  rotation-vector rate), both in the body (end-effector) frame, over ``dt`` (s).

Construction validates everything (finite, ``dt >= 0``, shapes, no absurd step);
the parts that receive an odometry object trust it, so a sample is checked exactly
once per iteration. A step that moves more than :data:`MAX_STEP_M` metres or turns
more than :data:`MAX_TURN_RAD` radians is rejected as corrupt (split it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Union

import numpy as np

from whisker_io.errors import InvalidInputError
from whisker_io.validation import MAX_STEP_M, MAX_TURN_RAD, finite_scalar, finite_vector

__all__ = ["PlanarOdometry", "SpatialOdometry", "Odometry", "MAX_STEP_M", "MAX_TURN_RAD"]



def _dt(value: object) -> float:
    t = finite_scalar(value, "odometry dt")
    if t < 0:
        raise InvalidInputError(f"odometry dt must be >= 0 s, got {t!r}")
    return t


def _bounded(amount: float, limit: float, what: str) -> None:
    if amount > limit:
        raise InvalidInputError(f"odometry {what} of {amount:g} in one sample exceeds {limit:g}; the sample is corrupt or must be split")


@dataclass(frozen=True)
class PlanarOdometry:
    """One planar odometry sample (validated on construction).

    Parameters
    ----------
    v : float
        Forward speed, m/s (OpenRatSLAM ``vtrans``).
    omega : float
        Yaw rate, rad/s, counter-clockwise positive (OpenRatSLAM ``vrot``).
    dt : float
        Duration, s, >= 0.

    Raises
    ------
    InvalidInputError
        A value is not a finite real number, ``dt < 0``, or the step is absurd.
    """

    v: float
    omega: float
    dt: float

    def __post_init__(self) -> None:
        v, w, t = finite_scalar(self.v, "odometry v"), finite_scalar(self.omega, "odometry omega"), _dt(self.dt)
        _bounded(abs(v) * t, MAX_STEP_M, "translation (m)")
        _bounded(abs(w) * t, MAX_TURN_RAD, "rotation (rad)")
        object.__setattr__(self, "v", v)
        object.__setattr__(self, "omega", w)
        object.__setattr__(self, "dt", t)


def _vec3(value: object, name: str) -> np.ndarray:
    arr = finite_vector(value, 3, f"odometry {name}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class SpatialOdometry:
    """One 6-DoF odometry sample in the body frame (Eq 5.7; validated on construction).

    Parameters
    ----------
    v : array_like (3,)
        Linear velocity, m/s, in the end-effector frame at the start of the sample.
    omega : array_like (3,)
        Angular velocity (rotation-vector rate), rad/s, in the same frame.
    dt : float
        Duration, s, >= 0.

    Raises
    ------
    InvalidInputError, ShapeError
        Wrong shapes, non-finite values, ``dt < 0`` or an absurd step.
    """

    v: np.ndarray
    omega: np.ndarray
    dt: float

    def __post_init__(self) -> None:
        v, w, t = _vec3(self.v, "v"), _vec3(self.omega, "omega"), _dt(self.dt)
        with np.errstate(over="ignore"):  # an overflowing norm is inf and rejected below
            _bounded(float(np.linalg.norm(v)) * t, MAX_STEP_M, "translation (m)")
            _bounded(float(np.linalg.norm(w)) * t, MAX_TURN_RAD, "rotation (rad)")
        object.__setattr__(self, "v", v)
        object.__setattr__(self, "omega", w)
        object.__setattr__(self, "dt", t)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, SpatialOdometry):
            return NotImplemented
        return bool(np.array_equal(self.v, other.v) and np.array_equal(self.omega, other.omega) and self.dt == other.dt)

    @classmethod
    def from_arrays(cls, v: Sequence[float], omega: Sequence[float], dt: float) -> "SpatialOdometry":
        """Same as the constructor (for symmetry with sequences of samples)."""
        return cls(np.asarray(v), np.asarray(omega), dt)


Odometry = Union[PlanarOdometry, SpatialOdometry]
