"""Surface placement controller (SPC, thesis Alg 7-8, Sec 6.1.1): pure geometry, one goal per call.

Given the end-effector pose ``T_BE`` and the whisk's contact points, with at least
``mu`` contacts (Alg 7, with two misprints of the printed algorithm fixed):

1. ``e = median(c)`` (per coordinate, world frame); ``n = (e - p_ref) / |e - p_ref|``, where
   ``p_ref`` is the reference point (``reference_point_m``, end-effector frame; default
   the end-effector origin ``p_ee`` of Alg 7).
2. If ``acos(y_ee . n) > delta_theta`` the array turns toward the median: the goal's
   y-axis is ``y_ee`` rotated toward ``n`` by ``angle / rotation_steps``, at most
   ``max_rotation_step_rad``, about the end-effector origin (position kept).
3. Otherwise ``e_dy = median((c - p_ref) . y_ee)`` (the median perpendicular distance);
   if it lies outside ``[delta_l, delta_u]`` the array moves along ``y_ee`` by
   ``(e_dy - (delta_l + delta_u) / 2) / translation_steps``.
4. Either goal is made by :func:`maintain_yaw` (Alg 8; the thesis' ``maintain_roll``
   and ``maintain_yaw`` are one rule): ``y`` given, ``z`` the world up direction ``g``
   made perpendicular to ``y`` (on the upward side), ``x = y x z``; when ``y`` is
   parallel to ``g`` the previous ``z`` is kept. A fixed roll about ``y``
   (``roll_rad``) is then applied, as the arm trajectories of
   :func:`whisker_io.sim.trajectories.object_trajectory` do (their ``roll_deg``).

Rotation comes before translation; with fewer than ``mu`` contacts, or with the median
already in the cone and in the band, the goal is the current pose.

Decision (reference point): Alg 7 measures the cone and the distance from ``p_ee``, which
is ambiguous for an array whose whisker bases sit 0.16-0.20 m along y from the flange.
``reference_point_m`` makes the point explicit; :func:`base_centroid` gives the centroid
of the whisker bases (the array's sensing origin) with the band shifted by the
centroid's y (:func:`centroid_params`). Measured on the thesis array (no noise, roll
pi/2, flat wall faced squarely 1-4 cm in front of the bases) the median contact lies
9-12 deg off y from ``p_ee`` but 25-48 deg off from the base centroid (the contacts are
only 2-8 cm in front of it while their median sits ~4 cm off the axis, the array's
whisker lengths being uneven); on the Box trajectories 29 deg (median) from ``p_ee``
and 67 deg from the centroid. The centroid therefore does not bring the median into a
10-deg cone; the default stays ``p_ee`` (Alg 7 as printed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from cansim.errors import ConfigError, InvalidInputError, ShapeError
from whisker_io.pose import Pose, PoseLike, as_pose
from whisker_io.sim.trajectories import facing_pose

__all__ = ["PlacementParams", "base_centroid", "centroid_params", "maintain_yaw", "place"]

_MAX_CONTACT_DISTANCE_M = 10.0


@dataclass(frozen=True)
class PlacementParams:
    """Parameters of the SPC (the thesis does not print them; defaults are this project's).

    Parameters
    ----------
    mu : int
        Fewest contacts for an adjustment (default 3, the fewest that give a PFH).
    delta_theta_rad : float
        Half-angle of the cone about the array's y-axis the median contact must lie
        in (default 10 deg).
    delta_l_m, delta_u_m : float
        Band of the median perpendicular contact distance from the end-effector origin
        (default 0.21-0.26 m: the thesis array's most rostral bases sit 0.20 m along y;
        on the simulated Box at the trajectories' 15-mm clearance the median is 0.215-0.248 m
        (5-95 %), so the band holds the surface within the short whiskers' reach).
    rotation_steps, translation_steps : int
        Divisions of a correction (default 2 each): one call moves 1/steps of the way.
    max_rotation_step_rad : float or None
        Largest turn per call (default ``delta_theta_rad``; None: no cap).
    roll_rad : float
        Fixed roll about y after Alg 8 (default 0; the simulated trajectories use pi/2).
    up : tuple of 3 float
        World up direction, Alg 8's ``g``.
    reference_point_m : tuple of 3 float or None
        Point (end-effector frame, m) the cone and the perpendicular distance are
        measured from (None: the end-effector origin, Alg 7's ``p_ee``); see the
        module docstring and :func:`centroid_params`.
    """

    mu: int = 3
    delta_theta_rad: float = math.radians(10.0)
    delta_l_m: float = 0.21
    delta_u_m: float = 0.26
    rotation_steps: int = 2
    translation_steps: int = 2
    max_rotation_step_rad: float | None = None
    roll_rad: float = 0.0
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    reference_point_m: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("mu", "rotation_steps", "translation_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ConfigError(f"{name} must be an integer >= 1, got {v!r}")
        for name in ("delta_theta_rad", "delta_l_m", "delta_u_m", "roll_rad"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{name} must be a finite number, got {v!r}")
        if not 0 < self.delta_theta_rad < math.pi:
            raise ConfigError(f"delta_theta_rad must lie in (0, pi), got {self.delta_theta_rad}")
        if not 0 <= self.delta_l_m < self.delta_u_m:
            raise ConfigError(f"need 0 <= delta_l_m < delta_u_m, got {self.delta_l_m}, {self.delta_u_m}")
        m = self.max_rotation_step_rad
        if m is not None and (isinstance(m, bool) or not isinstance(m, (int, float)) or not 0 < m < math.inf):
            raise ConfigError(f"max_rotation_step_rad must be a positive number or None, got {m!r}")
        g = np.asarray(self.up, dtype=float)
        if g.shape != (3,) or not np.isfinite(g).all() or not np.linalg.norm(g) > 0:
            raise ConfigError(f"up must be 3 finite numbers, not all zero, got {self.up!r}")
        r = self.reference_point_m
        if r is not None:
            try:
                ra = np.asarray(r, dtype=float)
            except (TypeError, ValueError):
                raise ConfigError(f"reference_point_m must be 3 finite numbers (m) or None, got {r!r}") from None
            if ra.shape != (3,) or not np.isfinite(ra).all() or np.abs(ra).max() > _MAX_CONTACT_DISTANCE_M:
                raise ConfigError(f"reference_point_m must be 3 finite numbers within {_MAX_CONTACT_DISTANCE_M} m, got {r!r}")
            object.__setattr__(self, "reference_point_m", tuple(float(x) for x in ra))

    @property
    def rotation_cap_rad(self) -> float:
        """The largest turn per call."""
        return self.delta_theta_rad if self.max_rotation_step_rad is None else float(self.max_rotation_step_rad)


def base_centroid(array: object | None = None) -> tuple[float, float, float]:
    """Centroid of the whisker bases in the end-effector frame, m (the array's sensing origin).

    Parameters
    ----------
    array : whisker_io.array.geometry.WhiskerArray, optional
        Default the thesis array (Fig 2.15; its centroid is about (-0.002, 0.182, 0.013) m).
    """
    from whisker_io.array.geometry import WhiskerArray

    arr = WhiskerArray.thesis() if array is None else array
    if not isinstance(arr, WhiskerArray):
        raise InvalidInputError(f"array must be a WhiskerArray, got {type(arr).__name__}")
    c = np.asarray(arr.positions_m, dtype=float).mean(axis=0)
    return float(c[0]), float(c[1]), float(c[2])


def centroid_params(params: PlacementParams = PlacementParams(), array: object | None = None) -> PlacementParams:
    """``params`` measured from the base centroid, the band shifted by the centroid's y.

    The band ``[delta_l, delta_u]`` of ``params`` (from the end-effector origin) becomes
    ``[delta_l - y_c, delta_u - y_c]`` (clipped at 0), so the same surface distance lies
    in the band; with the defaults and the thesis array, 0.028-0.078 m.
    """
    if not isinstance(params, PlacementParams):
        raise InvalidInputError(f"params must be a PlacementParams, got {type(params).__name__}")
    c = base_centroid(array)
    lo, hi = max(0.0, params.delta_l_m - c[1]), params.delta_u_m - c[1]
    if not hi > lo:
        raise ConfigError(f"the band [{params.delta_l_m}, {params.delta_u_m}] m lies behind the base centroid (y = {c[1]:.3f} m)")
    from dataclasses import replace

    return replace(params, reference_point_m=c, delta_l_m=lo, delta_u_m=hi)


def _roll(roll_rad: float) -> Rotation:
    return Rotation.from_rotvec([0.0, roll_rad, 0.0])


def maintain_yaw(y_axis: ArrayLike, previous_z: ArrayLike | None = None, up: ArrayLike = (0.0, 0.0, 1.0)) -> Rotation:
    """Alg 8: the orientation with the given y-axis whose z-axis is ``up`` made perpendicular to y.

    Parameters
    ----------
    y_axis : array_like (3,)
        The array axis (toward the surface), any non-zero length.
    previous_z : array_like (3,), optional
        Kept (made perpendicular to y) when ``y_axis`` is parallel to ``up``.
    up : array_like (3,)
        Gravity's opposite, Alg 8's ``g``.

    Returns
    -------
    scipy Rotation
        Columns ``x = y x z``, ``y``, ``z`` (``z . up >= 0``).
    """
    return facing_pose(np.zeros(3), y_axis, 0.0, previous_z, up).rotation


def _contacts_world(pose: Pose, contacts_ee_m: ArrayLike) -> np.ndarray:
    try:
        c = np.asarray(contacts_ee_m, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError("contact points must be an (n, 3) array of metres") from None
    if c.ndim != 2 or c.shape[1] != 3:
        raise ShapeError(f"contact points must have shape (n, 3), got {c.shape}")
    if not np.isfinite(c).all():
        raise InvalidInputError("contact points must be finite; drop whiskers without contact first")
    if c.size and np.abs(c).max() > _MAX_CONTACT_DISTANCE_M:
        raise InvalidInputError(f"a contact point lies beyond {_MAX_CONTACT_DISTANCE_M} m of the end-effector; check the units (m)")
    return pose.apply(c) if c.size else c


def place(ee_pose: PoseLike, contacts_ee_m: ArrayLike, params: PlacementParams = PlacementParams()) -> Pose:
    """One SPC goal (Alg 7-8, see the module docstring).

    Parameters
    ----------
    ee_pose : PoseLike
        Current end-effector pose ``T_BE`` (world frame; quaternion scalar-last).
    contacts_ee_m : array_like (n, 3)
        Contact points of the whisk in the end-effector frame, m (as
        :attr:`whisker_io.features.region.RegionFeatures.contact_points_m`).
    params : PlacementParams

    Returns
    -------
    Pose
        The goal; the current pose itself when fewer than ``mu`` contacts are given or
        the median contact is in the cone and the band.

    Raises
    ------
    InvalidInputError, ShapeError
        A bad pose or contact array (non-finite, not (n, 3), beyond 10 m).
    """
    pose = as_pose(ee_pose)
    if not isinstance(params, PlacementParams):
        raise InvalidInputError(f"params must be a PlacementParams, got {type(params).__name__}")
    c = _contacts_world(pose, contacts_ee_m)
    if len(c) < params.mu:
        return pose
    R = pose.rotation.as_matrix()
    p = pose.position_m if params.reference_point_m is None else pose.apply(np.asarray(params.reference_point_m)[None])[0]
    p_ee = pose.position_m
    y = R[:, 1]
    unrolled = pose.rotation * _roll(params.roll_rad).inv()
    prev_z = unrolled.as_matrix()[:, 2]
    e = np.median(c, axis=0)
    d = e - p
    dn = float(np.linalg.norm(d))
    if not dn > 1e-9:
        return pose  # the median sits at the origin: no direction to turn to
    n = d / dn
    angle = math.acos(float(np.clip(y @ n, -1.0, 1.0)))
    if angle > params.delta_theta_rad:
        turn = min(angle / params.rotation_steps, params.rotation_cap_rad)
        axis = np.cross(y, n)
        an = float(np.linalg.norm(axis))
        if an < 1e-12:  # anti-parallel: turn about the frame's x-axis
            axis, an = R[:, 0], 1.0
        y_new = Rotation.from_rotvec(axis / an * turn).apply(y)
        rot = maintain_yaw(y_new, prev_z, params.up) * _roll(params.roll_rad)
        return Pose.from_rotation(p_ee, rot)
    e_dy = float(np.median((c - p) @ y))
    if params.delta_l_m <= e_dy <= params.delta_u_m:
        return pose
    shift = (e_dy - 0.5 * (params.delta_l_m + params.delta_u_m)) / params.translation_steps
    rot = maintain_yaw(y, prev_z, params.up) * _roll(params.roll_rad)
    return Pose.from_rotation(p_ee + shift * y, rot)
