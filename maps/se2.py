"""SE(2) geometry of the 3-DoF experience map, with OpenRatSLAM's arithmetic (Eq 2.23-2.25).

A map pose is ``(x m, y m, theta rad)``; the dead-reckoning accumulator holds the
displacement ``(dx, dy)`` since the current experience (world frame) and the
current facing. Odometry rotates first, then translates (OpenRatSLAM ``on_odo``). A
link stores ``(d m, heading rad, facing rad)``: the distance travelled, its
direction relative to the source's facing and the relative facing. Relaxation
(Eq 2.25) pulls both ends of a link toward the pose the link predicts, by
``correction`` of the residual, Gauss-Seidel (numba kernel
:func:`maps._relax_numba.relax_links`).

The angle helpers reproduce OpenRatSLAM's ``clip_rad_180``, ``clip_rad_360`` and
``get_signed_delta_rad`` bit for bit: the wraps are :func:`whisker_io.angles.wrap_scalar`
(the C++ subtraction loop's result within a few turns, constant time beyond - odometry
that large is rejected earlier anyway, see :mod:`maps.odometry`).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from maps.odometry import PlanarOdometry
from whisker_io.angles import TWO_PI, wrap_scalar
from whisker_io.validation import config_field

__all__ = ["SE2Geometry", "clip_rad_180", "signed_delta_rad"]

_TWO_PI = TWO_PI


def clip_rad_180(angle: float) -> float:
    """Wrap a finite angle to (-pi, pi] radians exactly as OpenRatSLAM's ``clip_rad_180``."""
    return wrap_scalar(angle, -math.pi, True)


def _clip_rad_360(angle: float) -> float:
    return wrap_scalar(angle, 0.0, False)


def signed_delta_rad(angle1: float, angle2: float) -> float:
    """Signed smallest rotation from ``angle1`` to ``angle2`` (rad), as OpenRatSLAM's ``get_signed_delta_rad``."""
    direction = clip_rad_180(angle2 - angle1)
    delta = abs(_clip_rad_360(angle1) - _clip_rad_360(angle2))
    if delta < _TWO_PI - delta:
        return delta if direction > 0 else -delta
    return _TWO_PI - delta if direction > 0 else -(_TWO_PI - delta)


class SE2Geometry:
    """Planar map geometry for :class:`maps.experience_map.ExperienceMap`.

    Parameters
    ----------
    initial_heading_deg : float
        Facing (deg) of the dead reckoning before the first experience
        (OpenRatSLAM ``exp_initial_em_deg``, default 90; thesis Table 3.1: 180).
    heading_axis : int or None
        Pose-cell axis whose view offset (cells) is a panoramic rotation
        (OpenRatSLAM ``vt_delta_pc_th``); None: offsets carry no rotation.
    heading_cells : int
        Cells on that axis (2 pi per ``heading_cells``).
    """

    name = "se2"
    pose_width = 3
    link_width = 3
    accum_width = 3
    pose_fields = ("x_m", "y_m", "th_rad")
    link_fields = ("d_m", "heading_rad", "facing_rad")

    def __init__(self, initial_heading_deg: float = 90.0, heading_axis: int | None = 2, heading_cells: int = 36) -> None:
        self.initial_heading_deg = float(config_field(initial_heading_deg, "initial_heading_deg", float))
        axis = config_field(heading_axis, "heading_axis", int, minimum=0, optional=True)
        self.heading_axis = None if axis is None else int(axis)  # a Python int: saved as JSON with the map
        self.heading_cells = int(config_field(heading_cells, "heading_cells", int, minimum=1))

    def params(self) -> dict[str, Any]:
        """Constructor arguments (saved with the map)."""
        return {"initial_heading_deg": self.initial_heading_deg, "heading_axis": self.heading_axis, "heading_cells": self.heading_cells}

    def odometry(self, *args: Any) -> PlanarOdometry:
        """Coerce ``(odometry)`` or ``(v, omega, dt)`` to a validated :class:`PlanarOdometry`."""
        if len(args) == 1 and isinstance(args[0], PlanarOdometry):
            return args[0]
        return PlanarOdometry(*args)

    def initial_accumulator(self) -> list[float]:
        """``[dx m, dy m, facing rad]`` before the first experience."""
        return [0.0, 0.0, math.radians(self.initial_heading_deg)]

    def accumulate(self, acc: list[float], odo: PlanarOdometry) -> None:
        """Dead-reckon one sample in place: rotate first, then translate."""
        dist = odo.v * odo.dt
        acc[2] = clip_rad_180(acc[2] + odo.omega * odo.dt)
        acc[0] = acc[0] + dist * math.cos(acc[2])
        acc[1] = acc[1] + dist * math.sin(acc[2])

    def offset_rotation(self, offset_cells: np.ndarray | None) -> float:
        """The panoramic rotation (rad) that a view offset (cells) stands for."""
        if offset_cells is None or self.heading_axis is None:
            return 0.0
        return float(offset_cells[self.heading_axis]) * 2.0 * math.pi / self.heading_cells

    def new_pose(self, base: np.ndarray | None, acc: Sequence[float]) -> tuple[float, float, float]:
        """Pose of a new experience: the current one's plus the accumulated odometry."""
        x0, y0 = (0.0, 0.0) if base is None else (base[0], base[1])
        return (x0 + acc[0], y0 + acc[1], clip_rad_180(acc[2]))

    dead_reckoned = new_pose

    def link(self, from_pose: np.ndarray, acc: Sequence[float], rotation: float) -> tuple[float, float, float]:
        """Link data ``(d, heading, facing)`` from the accumulated odometry (OpenRatSLAM ``on_create_link``)."""
        th_from = float(from_pose[2])
        dx, dy = acc[0], acc[1]
        return (
            math.sqrt(dx * dx + dy * dy),
            signed_delta_rad(th_from, math.atan2(dy, dx)),
            signed_delta_rad(th_from, clip_rad_180(acc[2] + rotation)),
        )

    def reset_accumulator(self, acc: list[float], pose: np.ndarray, rotation: float) -> None:
        """After switching to an experience: zero displacement, facing = its facing + the view rotation."""
        acc[0] = 0.0
        acc[1] = 0.0
        acc[2] = clip_rad_180(float(pose[2]) + rotation)

    def relax(self, order: np.ndarray, ends: np.ndarray, links: np.ndarray, poses: np.ndarray, c: float, n: int, start: int) -> int:
        """``n`` Gauss-Seidel Eq 2.25 link updates in place from position ``start``; returns the next start."""
        from maps._relax_numba import relax_links

        return int(relax_links(order, ends, links, poses, c, n, start))

    def link_cost(self, link: np.ndarray) -> tuple[float, float]:
        """``(w_t m, w_r rad)`` of Eq 6.3: the link's length and absolute relative facing."""
        return float(link[0]), abs(float(link[2]))

    def check_poses(self, poses: np.ndarray) -> str | None:
        """None when saved poses are valid, else the problem."""
        return None
