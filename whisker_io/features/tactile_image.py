"""Tactile image of Ch.3 (Sec 3.1.1, Fig 3.2): one pixel per whisker, grey = contact height.

Layout: a ``uint8`` array of shape ``(3, 6)`` for the thesis array, i.e. an image
6 pixels wide (whisker columns A-F, left to right) and 3 high (rows 1-3, top to
bottom) -- the "6 x 3" template of Table 3.1 (``template_x_size 6``,
``template_y_size 3``) and the shape :mod:`cansim.frontends.tactile` expects.
For another array the image has one row per distinct module row and one column
per distinct module column, both sorted.

Pixel value (decision): the contact point's height ``h`` along the world's
vertical axis (from forward kinematics, Eq 5.1-5.2) scaled linearly from
``height_range_m = (h_min, h_max)`` to 1-255, clipped at both ends; 0 is
reserved for "no contact", so a contact at ``h_min`` stays distinguishable from
none. Default range 0-0.30 m: the Ch.3 array whisks 77 mm above the maze floor
and its 160 mm whiskers reach about 0.25 m up, so walls of any height in the
maze map into the range.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from whisker_io.errors import ConfigError, InvalidInputError
from whisker_io.validation import number_tuple
from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import contact_points
from whisker_io.pose import PoseLike
from whisker_io.sim.sweep import SweepContact

__all__ = [
    "TactileImageParams",
    "pixel_layout",
    "tactile_image",
    "tactile_image_from_angles",
    "tactile_image_from_contacts",
]


@dataclass(frozen=True)
class TactileImageParams:
    """Scaling of contact heights to grey levels (Sec 3.1.1).

    Attributes
    ----------
    height_range_m : (float, float)
        Heights (metres, world frame) mapped to grey 1 and 255. Default (0, 0.3).
    up : (float, float, float)
        World vertical direction; height = ``point . up``. Default +z.
    """

    height_range_m: tuple[float, float] = (0.0, 0.3)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        lo, hi = number_tuple(self.height_range_m, "height_range_m", length=2)
        up = number_tuple(self.up, "up", length=3)
        if not hi > lo:
            raise InvalidInputError(f"height_range_m must be (low, high) with high > low, got {self.height_range_m!r}")
        if not np.linalg.norm(up) > 0:
            raise InvalidInputError("up must be a non-zero vector")


def pixel_layout(array: WhiskerArray) -> tuple[NDArray[np.int64], NDArray[np.int64], tuple[int, int]]:
    """Image row and column of every module, and the image shape.

    Returns
    -------
    rows, cols : ndarray (N,) int
        Pixel of module ``i`` is ``image[rows[i], cols[i]]``.
    shape : (int, int)
        ``(n_rows, n_columns)``; ``(3, 6)`` for the thesis array.
    """
    row_labels = sorted({m.row for m in array.modules})
    col_labels = sorted({m.column for m in array.modules})
    rows = np.array([row_labels.index(m.row) for m in array.modules])
    cols = np.array([col_labels.index(m.column) for m in array.modules])
    if len(set(zip(rows.tolist(), cols.tolist()))) != len(array):
        raise ConfigError(
            "two modules share a (column, row) label, so they would share a tactile pixel; "
            "give every module a unique column/row pair"
        )
    return rows, cols, (len(row_labels), len(col_labels))


def tactile_image(
    array: WhiskerArray, points: ArrayLike, params: TactileImageParams = TactileImageParams()
) -> NDArray[np.uint8]:
    """Tactile image from per-module contact points (Sec 3.1.1).

    Parameters
    ----------
    array : WhiskerArray
    points : array_like (N, 3)
        World contact point of each module in array order, metres; a row of
        NaN means no contact (pixel 0).
    params : TactileImageParams

    Returns
    -------
    ndarray uint8, shape (n_rows, n_columns) -- (3, 6) for the thesis array
    """
    p = np.asarray(points, dtype=float)
    if p.shape != (len(array), 3):
        raise InvalidInputError(f"points must have shape ({len(array)}, 3), got {p.shape}")
    rows, cols, shape = pixel_layout(array)
    up = np.asarray(params.up, dtype=float)
    up = up / np.linalg.norm(up)
    contact = np.all(np.isfinite(p), axis=1)
    lo, hi = params.height_range_m
    h = np.where(contact, np.nan_to_num(p) @ up, lo)
    grey = 1.0 + np.round(254.0 * np.clip((h - lo) / (hi - lo), 0.0, 1.0))
    img = np.zeros(shape, dtype=np.uint8)
    img[rows[contact], cols[contact]] = grey[contact].astype(np.uint8)
    return img


def tactile_image_from_angles(
    array: WhiskerArray,
    pose: PoseLike,
    contact_angles_rad: ArrayLike,
    radial_distance_m: ArrayLike | None = None,
    params: TactileImageParams = TactileImageParams(),
) -> NDArray[np.uint8]:
    """Tactile image from contact angles by forward kinematics (Sec 3.1.1, Eq 5.1-5.2).

    Parameters
    ----------
    array : WhiskerArray
    pose : PoseLike
        End-effector pose ``T_BE`` at the whisk.
    contact_angles_rad : array_like (N,)
        Whisk angle at contact per module (max angle or contact angle of Ch.3);
        NaN = no contact.
    radial_distance_m : array_like (N,), optional
        Distance of the contact along the shaft; default the whisker length
        (the tip assumption Ch.3 relies on).
    """
    theta = np.asarray(contact_angles_rad, dtype=float)
    if theta.shape != (len(array),):
        raise InvalidInputError(f"contact_angles_rad must have shape ({len(array)},), got {theta.shape}")
    contact = np.isfinite(theta)
    r = array.lengths_m if radial_distance_m is None else np.asarray(radial_distance_m, dtype=float)
    pts = contact_points(array, pose, np.where(contact, theta, 0.0), np.where(contact, r, 0.0))
    pts[~contact] = np.nan
    return tactile_image(array, pts, params)


def tactile_image_from_contacts(
    array: WhiskerArray,
    contacts: Sequence[SweepContact | None],
    params: TactileImageParams = TactileImageParams(),
) -> NDArray[np.uint8]:
    """Tactile image from simulator contacts (:func:`whisker_io.sim.sweep.sweep_array` output)."""
    if len(contacts) != len(array):
        raise InvalidInputError(f"need one contact (or None) per module: {len(array)}, got {len(contacts)}")
    pts = np.array([np.full(3, np.nan) if c is None else c.point for c in contacts])
    return tactile_image(array, pts, params)
