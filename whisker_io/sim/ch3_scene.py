"""The scene of the Ch.3 maze experiment: the terrain and the predetermined path (Sec 3.1-3.2, Fig 3.3).

Terrain (:func:`ch3_terrain`). In the thesis the array moves "in a plane set 77 mm
above the maze", a height that "prevents the whiskers from contacting the floor and
limits contact to the protruding walls", and each tactile pixel is "proportional to
the approximate vertical height of any obstacle". The walls and posts therefore
stand below the array. :func:`whisker_io.sim.objects.make_maze` builds the 1.35 x 1 m
maze with walls of 6-25 cm (a layout in the spirit of Fig 3.1); the Ch.3 terrain is
that maze with every height scaled by one factor so that the tallest obstacle is
``max_height_m`` (default 7 cm, below the 77 mm plane; the border becomes 4.2 cm,
the lowest post 1.7 cm). Footprint and layout are unchanged.

Route (:class:`MazeRoute`). The arm moved the array "to a set of hard-coded
positions on a planar surface" loop after loop; the path itself is only shown as a
plot (Fig 3.3), so :data:`CH3_MAZE_WAYPOINTS_M` is a loop in its spirit through the
corridors of the maze: along the bottom corridor between the border and the long
wall, up past the post at (1.1, 0.25), back along the middle row between the wall
and two posts, and down beside the short wall. It keeps the array's axis at least
7.7 cm from every wall and post (and the whisker bases, 77-117 mm up, pass above the
terrain anyway). :class:`MazeRoute` rounds the corners of a closed polyline with circular
arcs and splits it into places of equal arc length, one per RatSLAM iteration. It
has the ``places()`` method of the synthetic routes of :mod:`cansim.testing.worlds`,
so the same multi-loop runs (directions, turns on the spot, odometry noise,
kidnapping) can be generated over it.

Example
-------
>>> from whisker_io.sim.ch3_scene import MazeRoute, ch3_terrain
>>> route = MazeRoute()
>>> route.n_places, round(route.perimeter_m, 3)
(125, 1.875)
>>> round(float(ch3_terrain().bounds[1, 2]), 3)
0.07
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray

from whisker_io.errors import InvalidInputError
from whisker_io.sim.objects import make_maze
from whisker_io.sim.planar_chain import MAX_COORDINATE_M
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_scalar, validate_fields

__all__ = ["CH3_MAZE_WAYPOINTS_M", "CH3_OBSTACLE_HEIGHT_M", "MAX_PLACES", "MazeRoute", "ch3_terrain"]

CH3_MAZE_WAYPOINTS_M: tuple[tuple[float, float], ...] = (
    (0.45, 0.125),
    (1.22, 0.125),
    (1.22, 0.40),
    (1.04, 0.355),
    (0.45, 0.34),
)
"""Corners of the default route in the maze frame (x, y metres), counter-clockwise."""

CH3_OBSTACLE_HEIGHT_M: float = 0.07
"""Height of the tallest obstacle of :func:`ch3_terrain`, metres (below the 77 mm plane of the array)."""

MAX_PLACES: int = 1_000_000
"""Most places a :class:`MazeRoute` may have (a guard against a step far too small for the route)."""

_ARC_POINTS = 64  # polyline points per rounded corner before resampling


def ch3_terrain(max_height_m: float = CH3_OBSTACLE_HEIGHT_M) -> trimesh.Trimesh:
    """The Ch.3 terrain: :func:`~whisker_io.sim.objects.make_maze` with heights scaled to ``max_height_m``.

    Parameters
    ----------
    max_height_m : float
        Height of the tallest wall or post, metres, in (0, 1]; the others keep their
        ratios to it. Default 0.07.

    Returns
    -------
    trimesh.Trimesh
        Floor corner at the origin, x in [0, 1.35], y in [0, 1.0], z up (no floor slab).
    """
    h = finite_scalar(max_height_m, "max_height_m")
    if not 0.0 < h <= 1.0:
        raise InvalidInputError(f"max_height_m must be in (0, 1] m, got {max_height_m!r}")
    mesh = make_maze()
    mesh.apply_scale([1.0, 1.0, h / float(mesh.bounds[1, 2])])
    return mesh


@dataclass(frozen=True)
class MazeRoute(ConfigDataclass):
    """A closed route of straight legs joined by circular arcs, split into equal places.

    Parameters
    ----------
    waypoints_m : sequence of (x, y)
        Corners of the closed polyline, metres (``|x|, |y| <= 1000``), counter-clockwise, at least 3.
    corner_radius_m : float
        Radius of the arc that rounds every corner, metres (> 0; the arcs of two
        neighbouring corners must fit on the leg between them).
    step_m : float
        Desired distance between places, metres; the actual step is
        ``perimeter_m / n_places`` (Table 3.1: ``pc_cell_x_size`` 0.015 m = one
        pose cell per iteration).

    Raises
    ------
    InvalidInputError
        Non-finite or too few waypoints, repeated consecutive waypoints, a
        clockwise polyline, a radius whose arcs do not fit, or a step that is not
        positive or gives fewer than 4 or more than :data:`MAX_PLACES` places.
    """

    waypoints_m: tuple[tuple[float, float], ...] = CH3_MAZE_WAYPOINTS_M
    corner_radius_m: float = checked(0.08, float, above=0, error=InvalidInputError, reader=finite_scalar,
                                     message="{name} must be > 0, got {value!r}", store=True)
    step_m: float = checked(0.015, float, above=0, error=InvalidInputError, reader=finite_scalar,
                            message="{name} must be > 0, got {value!r}", store=True)

    def __post_init__(self) -> None:
        given_waypoints = self.waypoints_m  # as given, for the message (validate_fields makes a list a tuple)
        validate_fields(self)  # the radius and the step; the route's shape below
        wp = finite_array(given_waypoints, (None, 2), "waypoints_m")
        if wp.shape[0] < 3:
            raise InvalidInputError(f"waypoints_m needs at least 3 corners of a closed route, got {wp.shape[0]}")
        if np.any(np.abs(wp) > MAX_COORDINATE_M):
            raise InvalidInputError(f"waypoints_m has a coordinate above {MAX_COORDINATE_M:g} m; give the corners in metres in the maze frame")
        legs = np.roll(wp, -1, axis=0) - wp
        lengths = np.hypot(legs[:, 0], legs[:, 1])
        if np.any(lengths < 1e-9):
            raise InvalidInputError("waypoints_m holds two equal consecutive corners; remove the duplicate")
        area = 0.5 * float(np.sum(wp[:, 0] * np.roll(wp[:, 1], -1) - np.roll(wp[:, 0], -1) * wp[:, 1]))
        if not area > 0:
            raise InvalidInputError("waypoints_m must run counter-clockwise (positive signed area); reverse the list")
        r = self.corner_radius_m
        turns = self._turns(wp)
        if np.any(np.abs(turns) > math.pi - 1e-6):
            raise InvalidInputError("a corner of waypoints_m turns back on itself (180 deg); add a corner")
        tangents = r * np.tan(np.abs(turns) / 2.0)  # tangent length at corner i
        need = tangents + np.roll(tangents, -1)  # leg i runs from corner i to corner i+1
        if np.any(need > lengths + 1e-12):
            i = int(np.argmax(need - lengths))
            raise InvalidInputError(
                f"corner_radius_m {r} is too large: the arcs at corners {i} and {(i + 1) % len(wp)} need "
                f"{need[i]:.3f} m of a {lengths[i]:.3f} m leg; use a smaller radius"
            )
        step = self.step_m
        object.__setattr__(self, "waypoints_m", tuple((float(x), float(y)) for x, y in wp))
        places = self.perimeter_m / step
        if not 4 <= places <= MAX_PLACES:
            raise InvalidInputError(
                f"step_m {step} gives {places:.3g} places on a {self.perimeter_m:.3g} m route; "
                f"choose a step that gives 4 to {MAX_PLACES} places"
            )

    @staticmethod
    def _turns(wp: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed turning angle at every corner (left positive), radians."""
        d_in = wp - np.roll(wp, 1, axis=0)
        d_out = np.roll(wp, -1, axis=0) - wp
        cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
        dot = np.einsum("ij,ij->i", d_in, d_out)
        return np.arctan2(cross, dot)

    def _polyline(self) -> NDArray[np.float64]:
        """Dense closed polyline: from the middle of the first leg, straight legs and corner arcs."""
        wp = np.asarray(self.waypoints_m, dtype=np.float64)
        n, r = len(wp), self.corner_radius_m
        turns = self._turns(wp)
        pts = [0.5 * (wp[0] + wp[1])]
        for j in range(1, n + 1):
            i = j % n
            d_in = wp[i] - wp[i - 1]
            d_in = d_in / np.hypot(*d_in)
            d_out = wp[(i + 1) % n] - wp[i]
            d_out = d_out / np.hypot(*d_out)
            phi = float(turns[i])
            t = r * math.tan(abs(phi) / 2.0)
            start = wp[i] - t * d_in
            if abs(phi) < 1e-12:
                pts.append(wp[i])
                continue
            left = np.array([-d_in[1], d_in[0]]) * math.copysign(1.0, phi)
            centre = start + r * left
            a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
            ang = a0 + phi * np.linspace(0.0, 1.0, _ARC_POINTS + 1)
            pts.extend(centre + r * np.column_stack([np.cos(ang), np.sin(ang)]))
        pts.append(pts[0])
        return np.asarray(pts)

    @property
    def perimeter_m(self) -> float:
        """Length of the route, metres (straight legs plus arcs)."""
        wp = np.asarray(self.waypoints_m, dtype=np.float64)
        legs = np.hypot(*(np.roll(wp, -1, axis=0) - wp).T).sum()
        phi = np.abs(self._turns(wp))
        r = self.corner_radius_m
        return float(legs - np.sum(2.0 * r * np.tan(phi / 2.0)) + np.sum(r * phi))

    @property
    def n_places(self) -> int:
        """Number of places (iterations per loop)."""
        return max(4, int(round(self.perimeter_m / self.step_m)))

    def places(self) -> NDArray[np.float64]:
        """Place positions, shape (n_places, 2), metres, counter-clockwise from the middle of the first leg."""
        poly = self._polyline()
        seg = np.hypot(*np.diff(poly, axis=0).T)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        targets = np.arange(self.n_places) * (s[-1] / self.n_places)
        return np.column_stack([np.interp(targets, s, poly[:, 0]), np.interp(targets, s, poly[:, 1])])
