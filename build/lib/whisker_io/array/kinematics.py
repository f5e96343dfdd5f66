"""Forward kinematics of a whisker array on an arm (Eq 5.1-5.2 of the thesis).

``T_BWi = T_BE @ T_EWi`` places whisker ``i``'s base frame in the arm-base (world)
frame B; rotating it by ``Rz(theta)`` (Eq 5.1) gives the shaft's pose at whisk
angle ``theta``; translating by the radial distance ``r`` along that frame's
y-axis (Eq 5.2, ``Ty(r)``; the printed matrix lacks its identity diagonal) gives
the contact point. All functions are vectorised over whiskers (and angles).

Poses at the API boundary are any :data:`whisker_io.pose.PoseLike` (a
:class:`~whisker_io.pose.Pose`, a (4, 4) homogeneous matrix ``T_BE`` or a
``(position_m, quaternion_xyzw)`` pair, quaternion **scalar-last**), converted
once by :func:`whisker_io.pose.as_pose`, so a reflection or a non-unit
quaternion is refused here exactly as everywhere else. Units: metres, radians.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from whisker_io.errors import InvalidInputError
from whisker_io.array.geometry import WhiskerArray
from whisker_io.pose import PoseLike, as_pose
from whisker_io.validation import finite_array

__all__ = [
    "rot_z",
    "whisker_base_transforms",
    "whisker_frames",
    "shaft_directions",
    "rotate_shaft",
    "contact_points",
    "whisker_coordinates",
]


def _transform(pose: PoseLike) -> NDArray[np.float64]:
    """``T_BE`` (4, 4) of a pose argument, through the one coercion :func:`as_pose`."""
    return as_pose(pose).matrix


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


def whisker_base_transforms(array: WhiskerArray, pose: PoseLike) -> NDArray[np.float64]:
    """``T_BWi = T_BE @ T_EWi`` for every module (Sec 5.1.1.1.2).

    Returns
    -------
    ndarray, shape (N, 4, 4)
        Base frames at whisk angle 0 in the world frame.
    """
    return _transform(pose) @ array.T_EW


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


def whisker_frames(array: WhiskerArray, pose: PoseLike, theta: ArrayLike) -> NDArray[np.float64]:
    """Shaft frames ``T_BWi Rz(theta_i)`` at the given whisk angles (Eq 5.1).

    Parameters
    ----------
    array : WhiskerArray
    pose : PoseLike
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


def shaft_directions(array: WhiskerArray, pose: PoseLike, theta: ArrayLike) -> NDArray[np.float64]:
    """Unit shaft directions in the world (the frames' y-axes) at angles ``theta``.

    Equivalent to ``whisker_frames(...)[..., :3, 1]`` but without building the
    4x4 stack (:func:`rotate_shaft`).

    Returns
    -------
    ndarray, shape theta.shape + (3,)
    """
    t = _angles(array, theta)
    R = _transform(pose)[:3, :3] @ array.rotations  # (N, 3, 3)
    x, y = R[:, :, 0], R[:, :, 1]
    if t.ndim == 1:
        return rotate_shaft(x, y, t)
    return rotate_shaft(x[:, None], y[:, None], t)


def contact_points(
    array: WhiskerArray,
    pose: PoseLike,
    theta: ArrayLike,
    radial_distance_m: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Contact points in the world frame (Eq 5.1-5.2): ``T_BWi Rz(theta) Ty(r)``.

    Parameters
    ----------
    array : WhiskerArray
    pose : PoseLike
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
        r = finite_array(radial_distance_m, None, "radial_distance_m")
        try:
            r = np.broadcast_to(r, t.shape)
        except ValueError:
            raise InvalidInputError(
                f"radial_distance_m must be a scalar or shape ({len(array)},), got {r.shape}") from None
    pose = as_pose(pose)  # once, for both uses below
    T_BW = whisker_base_transforms(array, pose)
    return T_BW[:, :3, 3] + r[:, None] * shaft_directions(array, pose, t)


def whisker_coordinates(
    array: WhiskerArray, pose: PoseLike, points: ArrayLike
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
