"""The one rigid-body pose type of the distribution (sensor, hardware, records, maps).

A :class:`Pose` is a proper rigid transform, e.g. the pose of the tool
(end-effector) frame E in the robot base frame B, ``T_BE`` in the notation of
Eq 5.1-5.2 of the thesis:

* ``position_m``: shape (3,), metres;
* ``quaternion_xyzw``: shape (4,), **scalar-last** ``[x, y, z, w]`` (the order of
  :class:`scipy.spatial.transform.Rotation` and of ROS ``geometry_msgs``), unit
  norm, canonical sign ``w >= 0`` (q and -q are the same rotation; the sign is
  fixed so that equal rotations compare equal).

All rotation arithmetic is done by scipy's ``Rotation``.

The quaternion rule (one rule, used everywhere a quaternion enters)
-------------------------------------------------------------------
A quaternion must be finite and have a norm within :data:`QUAT_NORM_TOL`
(relative) of 1; it is then divided by its norm (a norm within 1e-12 of 1 is
kept as given, so a logged pose reads back bit-identical). Anything else - a
zero, NaN/inf or overflowing quaternion, or one far from unit norm such as a
scalar-first quaternion typed with a stray factor - raises
:class:`~whisker_io.errors.InvalidInputError`: it is a bug upstream, and
silently normalising it would hide it.

The rotation block of a 4x4 transform must be orthonormal (``R R^T = I`` within
1e-6) with determinant +1 - a reflection is not a pose - and the last row must
be ``(0, 0, 0, 1)``.

Conversions: :meth:`Pose.from_matrix` / :attr:`Pose.matrix` (4x4 homogeneous
transform); :meth:`Pose.from_rotvec` / :attr:`Pose.rotvec_rad` (rotation vector);
:meth:`Pose.from_ur` / :meth:`Pose.as_ur` (the Universal Robots TCP pose
``[x, y, z, rx, ry, rz]`` of ``getActualTCPPose``/``moveL``/``servoL``).
:func:`as_pose` is the one coercion from any :data:`PoseLike`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import finite_array, finite_vector

__all__ = ["Pose", "PoseLike", "as_pose", "QUAT_NORM_TOL", "ORTHONORMAL_TOL"]

#: Largest relative deviation of a quaternion's norm from 1 that is normalised away.
QUAT_NORM_TOL: float = 1e-3
#: Largest entry of ``R R^T - I`` accepted for the rotation block of a transform.
ORTHONORMAL_TOL: float = 1e-6


def _unit_quaternion(value: ArrayLike, name: str = "quaternion_xyzw") -> NDArray[np.float64]:
    q = finite_vector(value, 4, name)
    with np.errstate(over="ignore"):
        norm = float(np.linalg.norm(q))
    if not abs(norm - 1.0) <= QUAT_NORM_TOL:  # also catches an overflowing norm
        raise InvalidInputError(
            f"{name} {q.tolist()} has norm {norm:.9g}; a pose needs unit norm "
            f"(within {QUAT_NORM_TOL:g}; scalar-last [x, y, z, w]) - normalise it "
            "(q / |q|) or check the component order"
        )
    if abs(norm - 1.0) > 1e-12:
        q = q / norm
    if q[3] < 0 or (q[3] == 0 and next((v for v in q[:3] if v != 0), 0.0) < 0):
        q = -q
    return q + 0.0  # no negative zeros


@dataclass(frozen=True, eq=False, init=False)
class Pose:
    """A proper rigid transform: position (m) + unit quaternion (scalar-last).

    Parameters
    ----------
    position_m : array_like, shape (3,)
        Translation in metres.
    quaternion_xyzw : array_like, shape (4,), default identity
        Orientation ``[x, y, z, w]`` (scalar last); see the module's quaternion
        rule. Stored unit-norm with ``w >= 0``.

    Attributes
    ----------
    position_m : ndarray (3,), read-only
    quaternion_xyzw : ndarray (4,), read-only

    Raises
    ------
    ShapeError
        Wrong shapes.
    InvalidInputError
        Non-finite values or a quaternion that is not unit within :data:`QUAT_NORM_TOL`.

    Examples
    --------
    >>> p = Pose([0.1, 0.0, 0.3], [0.0, 0.0, 0.0, 1.0])
    >>> (p @ p.inverse()).position_m.tolist()
    [0.0, 0.0, 0.0]
    """

    position_m: NDArray[np.float64]
    quaternion_xyzw: NDArray[np.float64]

    def __init__(self, position_m: ArrayLike, quaternion_xyzw: ArrayLike = (0.0, 0.0, 0.0, 1.0)) -> None:
        p = finite_vector(position_m, 3, "position_m") + 0.0
        q = _unit_quaternion(quaternion_xyzw)
        p.setflags(write=False)
        q.setflags(write=False)
        object.__setattr__(self, "position_m", p)
        object.__setattr__(self, "quaternion_xyzw", q)

    # ----------------------------------------------------------- constructors
    @classmethod
    def identity(cls) -> Pose:
        """The identity transform."""
        return cls(np.zeros(3))

    @classmethod
    def from_rotation(cls, position_m: ArrayLike, rotation: Rotation) -> Pose:
        """Pose from a position (3,) in m and a single scipy ``Rotation``."""
        if not isinstance(rotation, Rotation) or not rotation.single:
            raise InvalidInputError(f"rotation must be a single scipy Rotation, got {rotation!r}")
        return cls(position_m, rotation.as_quat())

    @classmethod
    def from_rotvec(cls, position_m: ArrayLike, rotvec_rad: ArrayLike) -> Pose:
        """Pose from a position (3,) in m and a rotation vector (3,) in rad (axis * angle)."""
        v = finite_vector(rotvec_rad, 3, "rotvec_rad")
        return cls(position_m, Rotation.from_rotvec(v).as_quat())

    @classmethod
    def from_matrix(cls, matrix: ArrayLike) -> Pose:
        """Pose from a 4x4 homogeneous transform (translation in m).

        Raises
        ------
        ShapeError
            Not 4x4.
        InvalidInputError
            Non-finite entries, a last row other than ``(0, 0, 0, 1)``, or a
            rotation block that is not orthonormal within :data:`ORTHONORMAL_TOL`
            or has determinant -1 (a reflection).
        """
        T = finite_array(matrix, (4, 4), "matrix")
        R = T[:3, :3]
        if not np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0]):
            raise InvalidInputError(
                f"matrix is not a rigid transform: its last row must be (0, 0, 0, 1), got {T[3].tolist()}")
        if not np.max(np.abs(R @ R.T - np.eye(3))) <= ORTHONORMAL_TOL:
            raise InvalidInputError(
                "matrix is not a rigid transform: its rotation block is not orthonormal "
                f"(R R^T != I within {ORTHONORMAL_TOL:g}); re-orthonormalise it")
        if np.linalg.det(R) < 0:
            raise InvalidInputError(
                "matrix is not a rigid transform: its rotation block has determinant -1 (a "
                "reflection, e.g. a flipped axis); use a right-handed frame")
        return cls(T[:3, 3], Rotation.from_matrix(R).as_quat())

    @classmethod
    def from_ur(cls, tcp_pose: ArrayLike) -> Pose:
        """Pose from a UR TCP pose ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad)."""
        v = finite_vector(tcp_pose, 6, "UR TCP pose [x, y, z, rx, ry, rz]")
        return cls.from_rotvec(v[:3], v[3:])

    # ------------------------------------------------------------ conversions
    @property
    def rotation(self) -> Rotation:
        """Orientation as a scipy ``Rotation``."""
        return Rotation.from_quat(np.array(self.quaternion_xyzw))

    @property
    def matrix(self) -> NDArray[np.float64]:
        """The 4x4 homogeneous transform, shape (4, 4) (a new array each call)."""
        T = self.__dict__.get("_matrix")
        if T is None:  # computed once: the pose is immutable
            T = np.eye(4)
            T[:3, :3] = self.rotation.as_matrix()
            T[:3, 3] = self.position_m
            T.setflags(write=False)
            object.__setattr__(self, "_matrix", T)
        return T.copy()

    @property
    def rotvec_rad(self) -> NDArray[np.float64]:
        """Rotation vector (axis * angle), shape (3,), rad, angle in [0, pi]."""
        return self.rotation.as_rotvec()

    def as_ur(self) -> list[float]:
        """UR TCP pose ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad)."""
        return [float(v) for v in np.concatenate([self.position_m, self.rotvec_rad])]

    def tool_axis(self) -> NDArray[np.float64]:
        """The frame's z-axis expressed in the parent frame, shape (3,), unit."""
        return self.rotation.apply([0.0, 0.0, 1.0])

    def apply(self, points_m: ArrayLike) -> NDArray[np.float64]:
        """Transform points from this frame to the parent frame.

        Parameters
        ----------
        points_m : array_like, shape (3,) or (n, 3)

        Returns
        -------
        ndarray, same shape
        """
        p = finite_array(points_m, None, "points_m")
        if p.shape[-1:] != (3,) or p.ndim > 2:
            raise ShapeError(f"points_m must have shape (3,) or (n, 3), got {p.shape}")
        return self.rotation.apply(p) + self.position_m

    # ------------------------------------------------------------- arithmetic
    def __matmul__(self, other: Pose) -> Pose:
        """Compose ``self @ other``: ``other`` expressed in ``self``'s frame (T_AB @ T_BC = T_AC)."""
        if not isinstance(other, Pose):
            return NotImplemented
        return Pose(self.position_m + self.rotation.apply(np.array(other.position_m)),
                    (self.rotation * other.rotation).as_quat())

    def inverse(self) -> Pose:
        """The inverse transform (``p @ p.inverse()`` is the identity)."""
        inv = self.rotation.inv()
        return Pose(-inv.apply(np.array(self.position_m)), inv.as_quat())

    def distance_to(self, other: Pose) -> tuple[float, float]:
        """(translation in m, rotation angle in rad in [0, pi]) from ``self`` to ``other``."""
        dt = float(np.linalg.norm(other.position_m - self.position_m))
        dr = float((self.rotation.inv() * other.rotation).magnitude())
        return dt, dr

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Pose):
            return NotImplemented
        return bool(np.array_equal(self.position_m, other.position_m)
                    and np.array_equal(self.quaternion_xyzw, other.quaternion_xyzw))

    def __hash__(self) -> int:
        return hash((self.position_m.tobytes(), self.quaternion_xyzw.tobytes()))

    def __repr__(self) -> str:
        p = ", ".join(f"{v:.6g}" for v in self.position_m)
        q = ", ".join(f"{v:.6g}" for v in self.quaternion_xyzw)
        return f"Pose(position_m=[{p}], quaternion_xyzw=[{q}])"


PoseLike = Union[Pose, ArrayLike, tuple[ArrayLike, ArrayLike]]
"""A :class:`Pose`, a 4x4 transform, a ``(position_m (3,), quaternion_xyzw (4,))``
pair, or a UR TCP pose ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad)."""


def as_pose(value: PoseLike) -> Pose:
    """Convert a :data:`PoseLike` to a :class:`Pose` (the one pose coercion).

    Parameters
    ----------
    value : Pose, (4, 4) array_like, (position_m, quaternion_xyzw) tuple or (6,) UR pose
        A ``Pose`` is returned as is.

    Raises
    ------
    InvalidInputError
        Any other form, non-finite values, a reflection or non-orthonormal
        matrix, or a non-unit quaternion (see the module docstring).
    """
    if isinstance(value, Pose):
        return value
    if isinstance(value, tuple) and len(value) == 2:
        return Pose(*value)
    try:
        shape = np.shape(value)
    except (TypeError, ValueError):
        shape = None
    if shape == (4, 4):
        return Pose.from_matrix(value)
    if shape == (6,):
        return Pose.from_ur(value)
    raise InvalidInputError(
        f"cannot read a pose from {value!r}: give a Pose, a 4x4 transform, a "
        "(position_m, quaternion_xyzw) pair or a UR pose [x, y, z, rx, ry, rz]")
