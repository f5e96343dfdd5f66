"""The one pose form that crosses the hardware interfaces.

A :class:`Pose` is the pose of the tool (end-effector) frame E in the robot
base frame B, ``T_BE`` in the notation of Eq 5.1-5.2 of the thesis:

* ``position``: shape (3,), metres, in the base frame;
* ``quaternion``: shape (4,), **scalar-last** ``[x, y, z, w]`` (the
  convention of :class:`scipy.spatial.transform.Rotation`), unit norm,
  canonical sign ``w >= 0``.

Conversions: :meth:`Pose.as_matrix` / :meth:`Pose.from_matrix` for 4x4
homogeneous transforms; :meth:`Pose.as_ur` / :meth:`Pose.from_ur` for the
Universal Robots TCP pose ``[x, y, z, rx, ry, rz]`` (metres and a rotation
vector in radians, as returned by ``RTDEReceiveInterface.getActualTCPPose``
and expected by ``moveL``/``servoL``). All rotation arithmetic is done by
scipy's ``Rotation``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError

__all__ = ["Pose", "PoseLike", "as_pose"]


def _vector(value, n: int, name: str) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be {n} numbers; got {value!r}") from exc
    if arr.shape != (n,):
        raise InvalidInputError(f"{name} must have shape ({n},); got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name} must be finite; got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Pose:
    """Tool pose in the robot base frame (position + scalar-last quaternion).

    Parameters
    ----------
    position : array_like, shape (3,)
        Tool-centre-point position in metres.
    quaternion : array_like, shape (4,)
        Orientation as ``[x, y, z, w]`` (scalar last). It is normalised and
        its sign made canonical (``w >= 0``) on construction.

    Raises
    ------
    InvalidInputError
        Wrong shape, non-finite values or a zero quaternion.
    """

    position: np.ndarray
    quaternion: np.ndarray

    def __post_init__(self) -> None:
        p = _vector(self.position, 3, "position")
        q = np.array(_vector(self.quaternion, 4, "quaternion"))
        norm = float(np.linalg.norm(q))
        if not norm > 1e-12:
            raise InvalidInputError("quaternion must be non-zero (scalar-last [x, y, z, w])")
        q /= norm
        if q[3] < 0:
            q = -q
        q.setflags(write=False)
        object.__setattr__(self, "position", p)
        object.__setattr__(self, "quaternion", q)

    # ----------------------------------------------------------- constructors
    @classmethod
    def identity(cls) -> "Pose":
        """The base frame itself."""
        return cls(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))

    @classmethod
    def from_rotation(cls, position, rotation: Rotation) -> "Pose":
        """Pose from a position (3,) in m and a scipy ``Rotation``."""
        return cls(position, rotation.as_quat())

    @classmethod
    def from_matrix(cls, matrix) -> "Pose":
        """Pose from a 4x4 homogeneous transform ``T_BE`` (translation in m)."""
        try:
            T = np.asarray(matrix, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"matrix must be a 4x4 array; got {matrix!r}") from exc
        if T.shape != (4, 4):
            raise InvalidInputError(f"matrix must have shape (4, 4); got {T.shape}")
        if not np.all(np.isfinite(T)):
            raise InvalidInputError("matrix must be finite")
        R = T[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
            raise InvalidInputError("matrix rotation block must be a proper rotation (R R^T = I, det 1)")
        return cls(T[:3, 3], Rotation.from_matrix(R).as_quat())

    @classmethod
    def from_ur(cls, tcp_pose) -> "Pose":
        """Pose from a UR TCP pose ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad)."""
        v = _vector(tcp_pose, 6, "UR TCP pose [x, y, z, rx, ry, rz]")
        try:
            quat = Rotation.from_rotvec(np.array(v[3:])).as_quat()
        except ValueError as exc:  # e.g. a rotation vector too long to evaluate
            raise InvalidInputError(f"invalid rotation vector {v[3:].tolist()}: {exc}") from exc
        return cls(v[:3], quat)

    # ------------------------------------------------------------ conversions
    @property
    def rotation(self) -> Rotation:
        """Orientation as a scipy ``Rotation``."""
        return Rotation.from_quat(np.array(self.quaternion))

    def as_matrix(self) -> np.ndarray:
        """4x4 homogeneous transform ``T_BE``, shape (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = self.rotation.as_matrix()
        T[:3, 3] = self.position
        return T

    def as_ur(self) -> list[float]:
        """UR TCP pose ``[x, y, z, rx, ry, rz]`` (m, rotation vector in rad)."""
        return [float(v) for v in np.concatenate([self.position, self.rotation.as_rotvec()])]

    def tool_axis(self) -> np.ndarray:
        """The tool z-axis in the base frame, shape (3,), unit."""
        return self.rotation.apply([0.0, 0.0, 1.0])

    # ------------------------------------------------------------- arithmetic
    def __matmul__(self, other: "Pose") -> "Pose":
        """Compose ``self @ other`` (apply ``other`` in ``self``'s frame)."""
        return Pose(self.position + self.rotation.apply(np.array(other.position)),
                    (self.rotation * other.rotation).as_quat())

    def inverse(self) -> "Pose":
        """The inverse transform."""
        inv = self.rotation.inv()
        return Pose(-inv.apply(np.array(self.position)), inv.as_quat())

    def distance_to(self, other: "Pose") -> tuple[float, float]:
        """(translation in m, rotation angle in rad) from ``self`` to ``other``."""
        dt = float(np.linalg.norm(other.position - self.position))
        dr = float((self.rotation.inv() * other.rotation).magnitude())
        return dt, dr

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Pose):
            return NotImplemented
        return bool(np.array_equal(self.position, other.position)
                    and np.array_equal(self.quaternion, other.quaternion))

    def __hash__(self) -> int:
        return hash((self.position.tobytes(), self.quaternion.tobytes()))

    def __repr__(self) -> str:
        p = ", ".join(f"{v:.4f}" for v in self.position)
        q = ", ".join(f"{v:.4f}" for v in self.quaternion)
        return f"Pose(position=[{p}], quaternion_xyzw=[{q}])"


PoseLike = Union[Pose, np.ndarray, list, tuple]
"""A :class:`Pose`, a 4x4 transform, or a UR TCP pose ``[x, y, z, rx, ry, rz]``."""


def as_pose(value: PoseLike) -> Pose:
    """Convert a :data:`PoseLike` to a :class:`Pose`.

    Accepts a ``Pose`` (returned as is), a 4x4 homogeneous transform, or a
    6-vector UR TCP pose (m + rotation vector in rad).

    Raises
    ------
    InvalidInputError
        Any other shape, or non-finite values.
    """
    if isinstance(value, Pose):
        return value
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"cannot read a pose from {value!r}; give a Pose, "
                                "a 4x4 transform or [x, y, z, rx, ry, rz]") from exc
    if arr.shape == (4, 4):
        return Pose.from_matrix(arr)
    if arr.shape == (6,):
        return Pose.from_ur(arr)
    raise InvalidInputError(f"a pose must be a Pose, a 4x4 transform or a UR 6-vector; "
                            f"got shape {arr.shape}")
