"""Forward kinematics of a whisker array on an arm (Eq 5.1-5.2 of the thesis).

``T_BWi = T_BE @ T_EWi`` places whisker ``i``'s base frame in the arm-base (world)
frame B; rotating it by ``Rz(theta)`` (Eq 5.1) gives the shaft's pose at whisk
angle ``theta``; translating by the radial distance ``r`` along that frame's
y-axis (Eq 5.2, ``Ty(r)``; the printed matrix lacks its identity diagonal) gives
the contact point. All functions are vectorised over whiskers (and angles).

Poses at the API boundary are either a (4, 4) homogeneous matrix ``T_BE`` or a
``(position, quaternion)`` pair with the quaternion **scalar-last**
``(x, y, z, w)`` as in :class:`scipy.spatial.transform.Rotation` (ROS
``geometry_msgs/Pose`` uses the same order). Units: metres, radians.
"""

from __future__ import annotations

from typing import Union

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from whisker_io.errors import InvalidInputError
from whisker_io.array.geometry import WhiskerArray

__all__ = [
    "Pose",
    "transform_from_position_quaternion",
    "as_transform",
    "rot_z",
    "whisker_base_transforms",
    "whisker_frames",
    "shaft_directions",
    "rotate_shaft",
    "contact_points",
    "whisker_coordinates",
]

Pose = Union[ArrayLike, tuple[ArrayLike, ArrayLike]]
"""A (4, 4) transform ``T_BE`` or a ``(position (3,), quaternion_xyzw (4,))`` pair."""


def transform_from_position_quaternion(
    position: ArrayLike, quaternion_xyzw: ArrayLike
) -> NDArray[np.float64]:
    """Homogeneous transform from a position (m) and a scalar-last unit quaternion.

    Parameters
    ----------
    position : array_like, shape (3,)
        Translation in metres.
    quaternion_xyzw : array_like, shape (4,)
        Orientation as ``(x, y, z, w)`` (scipy convention); normalised here.

    Returns
    -------
    ndarray, shape (4, 4)
    """
    p = np.asarray(position, dtype=float)
    q = np.asarray(quaternion_xyzw, dtype=float)
    if p.shape != (3,) or q.shape != (4,):
        raise InvalidInputError(
            f"position must have shape (3,) and quaternion (4,) (x, y, z, w); got "
            f"{p.shape} and {q.shape}"
        )
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))) or np.linalg.norm(q) < 1e-12:
        raise InvalidInputError(
            "position and quaternion must be finite and the quaternion non-zero; "
            f"got {p.tolist()}, {q.tolist()}"
        )
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q).as_matrix()
    T[:3, 3] = p
    return T


def as_transform(pose: Pose) -> NDArray[np.float64]:
    """Normalise a pose argument to a (4, 4) float transform ``T_BE``.

    Parameters
    ----------
    pose : (4, 4) array_like, or (position (3,), quaternion_xyzw (4,)) tuple
        The end-effector pose in the world (arm base) frame.

    Raises
    ------
    InvalidInputError
        Wrong shape, non-finite entries, or a rotation block that is not orthonormal.
    """
    if isinstance(pose, tuple) and len(pose) == 2:
        return transform_from_position_quaternion(*pose)
    T = np.asarray(pose, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InvalidInputError(
            "pose must be a finite (4, 4) homogeneous matrix or a (position, "
            f"quaternion_xyzw) tuple; got an array of shape {T.shape}"
        )
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or not np.allclose(
        T[3], [0.0, 0.0, 0.0, 1.0]
    ):
        raise InvalidInputError(
            "pose is not a rigid transform: the rotation block must be orthonormal "
            "and the last row (0, 0, 0, 1)"
        )
    return T


def rot_z(theta: ArrayLike) -> NDArray[np.float64]:
    """Homogeneous rotation about z by ``theta`` radians (Eq 5.1).

    Parameters
    ----------
    theta : array_like, any shape S

    Returns
    -------
    ndarray, shape S + (4, 4)
    """
    t = np.asarray(theta, dtype=float)
    c, s = np.cos(t), np.sin(t)
    R = np.zeros(t.shape + (4, 4))
    R[..., 0, 0] = c
    R[..., 0, 1] = -s
    R[..., 1, 0] = s
    R[..., 1, 1] = c
    R[..., 2, 2] = 1.0
    R[..., 3, 3] = 1.0
    return R


def whisker_base_transforms(array: WhiskerArray, pose: Pose) -> NDArray[np.float64]:
    """``T_BWi = T_BE @ T_EWi`` for every module (Sec 5.1.1.1.2).

    Returns
    -------
    ndarray, shape (N, 4, 4)
        Base frames at whisk angle 0 in the world frame.
    """
    return as_transform(pose) @ array.T_EW


def _angles(array: WhiskerArray, theta: ArrayLike) -> NDArray[np.float64]:
    t = np.asarray(theta, dtype=float)
    if t.ndim == 0:
        t = np.full(len(array), float(t))
    if t.shape[:1] != (len(array),) or t.ndim > 2:
        raise InvalidInputError(
            f"theta must be a scalar, shape (N,) or (N, M) with N = {len(array)} "
            f"modules; got shape {t.shape}"
        )
    if not np.all(np.isfinite(t)):
        raise InvalidInputError("theta contains NaN or inf; mask missing contacts first")
    return t


def whisker_frames(array: WhiskerArray, pose: Pose, theta: ArrayLike) -> NDArray[np.float64]:
    """Shaft frames ``T_BWi Rz(theta_i)`` at the given whisk angles (Eq 5.1).

    Parameters
    ----------
    array : WhiskerArray
    pose : Pose
        End-effector pose ``T_BE``.
    theta : array_like, scalar, (N,) or (N, M)
        Whisk angle(s) in radians (+ = protraction).

    Returns
    -------
    ndarray, shape (N, 4, 4) or (N, M, 4, 4)
    """
    t = _angles(array, theta)
    T_BW = whisker_base_transforms(array, pose)
    if t.ndim == 1:
        return T_BW @ rot_z(t)
    return T_BW[:, None] @ rot_z(t)


def rotate_shaft(x_axis: ArrayLike, y_axis: ArrayLike, theta: ArrayLike) -> NDArray[np.float64]:
    """Shaft direction ``Rz(theta)`` applied to a base frame: ``cos(theta) y - sin(theta) x``.

    Parameters
    ----------
    x_axis, y_axis : array_like (..., 3)
        Base-frame x and y axes (world), broadcast against ``theta[..., None]``.
    theta : array_like
        Whisk angle(s), radians.

    Returns
    -------
    ndarray (..., 3)
        Unit shaft direction(s), the y-axis of ``T_BW Rz(theta)`` (Eq 5.1).
    """
    t = np.asarray(theta, dtype=float)[..., None]
    return np.cos(t) * np.asarray(y_axis) - np.sin(t) * np.asarray(x_axis)


def shaft_directions(array: WhiskerArray, pose: Pose, theta: ArrayLike) -> NDArray[np.float64]:
    """Unit shaft directions in the world (the frames' y-axes) at angles ``theta``.

    Equivalent to ``whisker_frames(...)[..., :3, 1]`` but without building the
    4x4 stack (:func:`rotate_shaft`).

    Returns
    -------
    ndarray, shape theta.shape + (3,)
    """
    t = _angles(array, theta)
    R = as_transform(pose)[:3, :3] @ array.rotations  # (N, 3, 3)
    x, y = R[:, :, 0], R[:, :, 1]
    if t.ndim == 1:
        return rotate_shaft(x, y, t)
    return rotate_shaft(x[:, None], y[:, None], t)


def contact_points(
    array: WhiskerArray,
    pose: Pose,
    theta: ArrayLike,
    radial_distance_m: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Contact points in the world frame (Eq 5.1-5.2): ``T_BWi Rz(theta) Ty(r)``.

    Parameters
    ----------
    array : WhiskerArray
    pose : Pose
        End-effector pose ``T_BE``.
    theta : array_like, (N,) or scalar
        Whisk angle at contact, radians.
    radial_distance_m : array_like, (N,) or scalar, optional
        Distance from the base along the shaft, metres. Default: the whisker
        length (the tip assumption of Ch.5).

    Returns
    -------
    ndarray, shape (N, 3)
    """
    t = _angles(array, theta)
    if t.ndim != 1:
        raise InvalidInputError(f"theta must be scalar or (N,), got shape {t.shape}")
    if radial_distance_m is None:
        r = array.lengths_m
    else:
        r = np.broadcast_to(np.asarray(radial_distance_m, dtype=float), t.shape)
        if not np.all(np.isfinite(r)):
            raise InvalidInputError("radial_distance_m contains NaN or inf")
    T_BW = whisker_base_transforms(array, pose)
    return T_BW[:, :3, 3] + r[:, None] * shaft_directions(array, pose, t)


def whisker_coordinates(
    array: WhiskerArray, pose: Pose, points: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Inverse of :func:`contact_points`: express world points in each whisker's base frame.

    For point ``p_i`` and module ``i`` returns the whisk angle ``theta_i`` at
    which the shaft points at ``p_i``'s projection onto the whisking plane,
    the in-plane radial distance ``r_i`` and the out-of-plane offset ``z_i``
    (along the whisk axis). ``contact_points(array, pose, theta, r)`` returns
    ``p`` back when ``z = 0``.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        One world point per module, metres.

    Returns
    -------
    theta : ndarray (N,), radians, in (-pi, pi]
    r : ndarray (N,), metres
    z : ndarray (N,), metres
    """
    p = np.asarray(points, dtype=float)
    if p.shape != (len(array), 3):
        raise InvalidInputError(f"points must have shape ({len(array)}, 3), got {p.shape}")
    T_BW = whisker_base_transforms(array, pose)
    local = np.einsum("nji,nj->ni", T_BW[:, :3, :3], p - T_BW[:, :3, 3])
    theta = np.arctan2(-local[:, 0], local[:, 1])
    r = np.hypot(local[:, 0], local[:, 1])
    return theta, r, local[:, 2]
