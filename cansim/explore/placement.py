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

Decision (cone half-angle, calibrated on the array): the thesis does not print
``delta_theta``. The thesis array (Fig 2.15) has six columns of 60/100/160-mm whiskers
that splay outward: against a flat wall faced squarely 0.235 m along y from the
end-effector origin (the band middle) its 18 contacts form rings about the y-axis of
radius 0.104 m (the 60-mm whiskers), 0.151 m and 0.221 m, with no contact closer to the
axis, i.e. 23.9, 32.7 and 43.2 deg off y seen from ``p_ee`` (:func:`ring_half_angle_rad`).
The median contact therefore lies inside the innermost ring's cone when the contacts
come from more than one side of the array (the surface is centred in the array's
view; on the wall the median is 9.9 deg off y, 11.3 deg at the trajectories' 0.217 m)
and outside it when only the outer whiskers of one side touch (the surface is off to
that side: turn toward it). The default ``delta_theta_rad`` is that cone, 24 deg
(:data:`DEFAULT_CONE_HALF_ANGLE_RAD`).
Measured on the Box and Box-Stack (one loop of trajectory A each, the poses perturbed by
2 cm / 8 deg as noisy odometry would, Sec 6.1.3.1.2 contact noise, tip contacts): with
25 deg the SPC settles (goal == current pose) within 5 steps from 99 % (Box) and
95 % (Box-Stack) of the starts, median 1 step; with the 10-deg cone 65 % of the starts
settle within 5 steps and 27-29 % are still turning after 10, the median of a few
contacts jumping between columns on either side of objects narrower (0.2 m) than
the contact rings (0.46 m across). Even squarely faced at the centre of a Box face the
median lies 15-18 deg (median) off y from ``p_ee``: a 10-deg cone is below the
measurement's spread for this array.

Decision (reference point): the cone and the distance are measured from ``p_ee`` as in
Alg 7 (``reference_point_m`` None); the contact rings are centred on the y-axis there
(the six 60-mm contacts at 0.111-0.112 m from it). ``reference_point_m`` moves the apex
for an array whose sensing origin is elsewhere; measured from the whisker bases'
centroid instead (0.18 m along y) the median lies 63-67 deg off y on the Box
trajectories and the SPC never settles from half of the starts.
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
from whisker_io.validation import ConfigDataclass, checked, finite_vector, validate_fields

__all__ = ["DEFAULT_CONE_HALF_ANGLE_RAD", "PlacementParams", "maintain_yaw", "place", "ring_half_angle_rad"]

_MAX_CONTACT_DISTANCE_M = 10.0
#: Default ``delta_theta`` (rad): 24 deg, the innermost contact ring of the thesis array
#: at the band middle, :func:`ring_half_angle_rad` (23.9 deg) to a whole degree (module docstring).
DEFAULT_CONE_HALF_ANGLE_RAD = math.radians(24.0)


@dataclass(frozen=True)
class PlacementParams(ConfigDataclass):
    """Parameters of the SPC (the thesis does not print them; defaults are this project's).

    Parameters
    ----------
    mu : int
        Fewest contacts for an adjustment (default 3, the fewest that give a PFH).
    delta_theta_rad : float
        Half-angle of the cone about the array's y-axis the median contact must lie
        in (default :data:`DEFAULT_CONE_HALF_ANGLE_RAD`, 24 deg: the innermost contact
        ring of the thesis array, see the module docstring and :func:`ring_half_angle_rad`).
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
        module docstring.
    """

    mu: int = checked(3, int, minimum=1)
    delta_theta_rad: float = checked(DEFAULT_CONE_HALF_ANGLE_RAD, float)  # in (0, pi): checked in __post_init__
    delta_l_m: float = checked(0.21, float)
    delta_u_m: float = checked(0.26, float)
    rotation_steps: int = checked(2, int, minimum=1)
    translation_steps: int = checked(2, int, minimum=1)
    max_rotation_step_rad: float | None = None
    roll_rad: float = checked(0.0, float)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    reference_point_m: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        validate_fields(self)
        if not 0 < self.delta_theta_rad < math.pi:
            raise ConfigError(f"delta_theta_rad must lie in (0, pi), got {self.delta_theta_rad}")
        if not 0 <= self.delta_l_m < self.delta_u_m:
            raise ConfigError(f"need 0 <= delta_l_m < delta_u_m, got {self.delta_l_m}, {self.delta_u_m}")
        m = self.max_rotation_step_rad
        if m is not None and (isinstance(m, bool) or not isinstance(m, (int, float)) or not 0 < m < math.inf):
            raise ConfigError(f"max_rotation_step_rad must be a positive number or None, got {m!r}")
        try:  # the shared validator: text such as "0" is not a number here
            g = finite_vector(self.up, 3, "up")
        except InvalidInputError:
            g = np.zeros(3)
        if not np.linalg.norm(g) > 0:
            raise ConfigError(f"up must be 3 finite numbers, not all zero, got {self.up!r}")
        r = self.reference_point_m
        if r is not None:
            try:
                ra = finite_vector(r, 3, "reference_point_m")
            except InvalidInputError:
                raise ConfigError(f"reference_point_m must be 3 finite numbers (m) or None, got {r!r}") from None
            if np.abs(ra).max() > _MAX_CONTACT_DISTANCE_M:
                raise ConfigError(f"reference_point_m must be 3 finite numbers within {_MAX_CONTACT_DISTANCE_M} m, got {r!r}")
            object.__setattr__(self, "reference_point_m", tuple(float(x) for x in ra))

    @property
    def rotation_cap_rad(self) -> float:
        """The largest turn per call."""
        return self.delta_theta_rad if self.max_rotation_step_rad is None else float(self.max_rotation_step_rad)


def ring_half_angle_rad(array: object | None = None, distance_m: float = 0.235, step_rad: float = math.radians(0.05)) -> float:
    """Half-angle, seen from the end-effector origin about y, of the innermost contact ring on a flat wall.

    The wall is the plane ``y = distance_m`` of the end-effector frame (faced squarely).
    Each of the shortest whiskers sweeps from retraction to protraction (Eq 5.1,
    ``T_EWi Rz(theta)``); its contact is the first angle at which its shaft reaches the
    plane (the point ``b + r s`` with ``0 <= r <= L``, ``b`` the base, ``s`` the shaft
    direction, ``L`` the length). The result is the median over those whiskers of the
    contact's angle from the y-axis, ``atan2(sqrt(x^2 + z^2), y)``. With the thesis array
    at the band middle of :class:`PlacementParams` (0.235 m) it is 23.9 deg (27.3 deg at
    0.217 m); the 60-mm whiskers reach no wall beyond about 0.245 m.

    Parameters
    ----------
    array : whisker_io.array.geometry.WhiskerArray, optional
        Default the thesis array (Fig 2.15).
    distance_m : float
        Wall distance along y from the end-effector origin, m (> 0).
    step_rad : float
        Resolution of the sweep, rad (> 0, at most 1 deg).

    Returns
    -------
    float
        Radians, in (0, pi/2).

    Raises
    ------
    InvalidInputError
        Not a WhiskerArray, a non-finite or non-positive distance or step, or a wall that
        none of the shortest whiskers reaches.
    """
    from whisker_io.array.geometry import WhiskerArray
    from whisker_io.array.kinematics import shaft_directions

    arr = WhiskerArray.thesis() if array is None else array
    if not isinstance(arr, WhiskerArray):
        raise InvalidInputError(f"array must be a WhiskerArray, got {type(arr).__name__}")
    for name, v in (("distance_m", distance_m), ("step_rad", step_rad)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
            raise InvalidInputError(f"{name} must be a finite number, got {v!r}")
    if not 0 < distance_m <= _MAX_CONTACT_DISTANCE_M:
        raise InvalidInputError(f"distance_m must lie in (0, {_MAX_CONTACT_DISTANCE_M}] m, got {distance_m!r}")
    if not 0 < step_rad <= math.radians(1.0):
        raise InvalidInputError(f"step_rad must lie in (0, 1 deg], got {step_rad!r}")
    lengths = np.asarray(arr.lengths_m, dtype=float)
    idx = np.flatnonzero(np.isclose(lengths, lengths.min()))
    theta = arr.whisk_angles(step_rad)  # retraction -> protraction
    s = shaft_directions(arr, Pose.identity(), np.tile(theta, (len(arr), 1)))  # (N, M, 3), end-effector frame
    b = np.asarray(arr.positions_m, dtype=float)
    angles = []
    for i in idx:
        sy = s[i, :, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = (distance_m - b[i, 1]) / sy
        hit = np.flatnonzero((sy > 0) & (r >= 0) & (r <= lengths[i]))
        if hit.size:
            c = b[i] + r[hit[0]] * s[i, hit[0]]
            angles.append(math.atan2(math.hypot(c[0], c[2]), c[1]))
    if not angles:
        raise InvalidInputError(f"none of the shortest whiskers reaches a wall {distance_m} m along y; "
                                "give a distance within their reach")
    return float(np.median(angles))


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
