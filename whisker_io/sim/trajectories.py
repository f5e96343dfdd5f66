"""Arm trajectories around an object: loops of whisk poses with the array facing the surface.

The thesis explores each object along loops that visit its surface region by
region: in Ch.5 trajectory "A" builds the object maps and a different, novel
trajectory "B" gathers the validation data (Sec 5.2.1, Fig 5.14); in Ch.6 the
visited regions are the faces of an ellipsoid fitted around the object, or of a
sphere (Sec 6.1.3.1, 6.1.3.2), over two loops. The step between whisks is about
11 cm and 12 deg, 3 cm and 3 deg for the Box (Sec 5.2.2.1).

Construction (decisions)
------------------------
1. **Fitted surface** (:func:`fit_surface`): the axis-aligned bounding box of the
   mesh (centre ``c``, half-extents ``h``; the objects of
   :mod:`whisker_io.sim.objects` stand upright) gives the ellipsoid with
   semi-axes ``sqrt(3) h``, the smallest one of that shape through the box's
   corners, or the sphere of radius ``|h|`` through them. Either encloses the
   object, so every point on it is outside the mesh.
2. **Loop** (:class:`LoopShape`): a closed curve on the fitted surface, azimuth
   once around the vertical axis while the elevation oscillates,
   ``el(s) = offset + amplitude sin(waves 2 pi s + phase)``. Family "A" and family
   "B" (:data:`TRAJECTORY_FAMILIES`) differ in start azimuth, direction, number of
   waves, phase and amplitude, so B passes the object's regions at other
   latitudes, in the other order and from other viewpoints.
3. **Facing the surface**: for a point ``P`` of the loop the surface point ``S``
   is the point of the mesh nearest to ``P``; the array axis (+y of the
   end-effector frame, rostral, see :mod:`whisker_io.array.geometry`) points from
   ``P`` toward ``S``, which is along the surface normal at ``S`` wherever the
   surface is smooth. These directions are averaged over ``smoothing_deg`` of the
   loop, so the array turns gradually round edges and where ``S`` jumps (to a
   handle), and the faced point is where the averaged axis from ``P`` meets the
   mesh. The end-effector origin is placed at ``faced point - standoff y``,
   ``standoff = clearance_m +`` the most rostral whisker base's distance along
   the axis (0.2019 m for the thesis array), so the whisker bases stay
   ``clearance_m`` in front of the surface and the 60-160 mm whiskers reach it
   while protracting. If a whisker base would still be inside or behind the
   object (a concave region, a handle) the pose backs off along the axis in
   5-mm steps until the segments from the origin to every base are free.
4. **Roll about the axis**: the "maintain yaw" rule of Alg 8 (the frame's z-axis
   is the world up direction made perpendicular to the axis, ``x = y x z``; when
   the axis is vertical the previous z is kept), then a fixed roll about the
   axis, ``roll_deg`` (default 90 deg: E's x-axis points down). The six columns
   of Fig 2.15 sit about 50-60 deg apart around the axis; rolled by 90 deg,
   columns A, B and E lie near the vertical plane and reach the surface of the
   upright, vertically curved objects (Mug, Barrel: 8-9 contacts at mid-height
   against 5 with ``roll_deg = 0``, where only C and D do). The roll is the same
   for every pose, so the yaw stays consistent along the loop. A flat object (a torus
   lying flat, a shallow bowl) lies between the rows of the array rolled by 90 deg:
   :func:`reaching_roll_deg` picks, per object, the roll at which a reaching loop
   (item 6) is touched by 3 whiskers more than 10 % of its poses more often (on the
   recognition study's 50 objects, trajectory A: the four flat tori 0.00-0.21 -> 0.56-1.00,
   two bowls 0.00 / 0.44 -> 0.45 / 1.00 and one duck variant 0.61 -> 0.73 take 0 deg;
   the other 43 and the three novel shapes keep 90).
5. **Steps**: the loop is sampled densely (``samples_per_loop`` poses built as
   above, more where the array turns by over 2 deg between them, e.g. round an
   edge, up to 4096) and the whisk poses are placed at equal increments of the step cost
   ``max(translation / step_m, rotation / step_deg)`` along the closed loop,
   interpolated between the dense poses (position linearly, orientation by
   slerp) and rounded up to a whole number of steps. Both measures of a step are
   then at most their bound (the cost of a chord never exceeds the cost along
   the path) and one of them about equal to it; a pose that has to back off
   (item 3) can exceed it by the back-off. Where the nearest surface point
   jumps (from a handle to the body) the interpolated poses bridge the jump.
   The loop is then repeated ``n_loops`` times (revisits).
6. **Reaching the surface** (optional, ``reach_contacts``): the thesis array's whiskers
   splay outward, so the space straight ahead of its front bases is swept by none; a
   part of the object narrower than that space (a duck's head, a handle, a blob's
   waist) faced at the standoff of item 3 is touched by no whisker, or by one or two.
   With ``reach_contacts = k > 0`` every whisk pose whose rigid sweep
   (:func:`whisker_io.sim.sweep.sweep_array`, no refinement) touches with fewer than
   ``k`` whiskers moves forward along its own axis in 1-cm steps until ``k`` touch, at
   most ``max_advance_m``, and never to where a segment from the origin to a whisker
   base would cross the mesh (item 3's check); it stops at the first step with ``k``
   touching, else at the step with the most (the nearest of equals; none more: the pose
   stays). Orientations are unchanged, so the steps' rotations keep their bound and an
   advanced pose's translation may exceed ``step_m`` by its advance (as a backed-off
   pose's does). Share of the whisks of one loop touching with 3 whiskers or more, fixed
   standoff -> ``reach_contacts=3`` (rigid sweeps, thesis step, A / B): duck 0.17 / 0.38
   -> 0.66 / 0.69, blob 0.57 / 0.44 -> 0.92 / 0.92, skull 0.65 / 0.62 -> 0.95 / 0.90,
   upright torus 0.57 / 0.47 -> 0.79 / 0.73, jug 0.74 / 0.78 -> 1.00 / 0.95, Mug 0.89 /
   0.89 -> 1.00 / 1.00, Box 0.93 / 0.95 -> 1.00 / 1.00; the held-out knot 0.50 / 0.58 ->
   0.70 / 0.77 and mushroom 0.30 / 0.00 -> 0.79 / 0.66 (a median advance of 2 cm).

All poses are :class:`~whisker_io.pose.Pose` s of the end-effector frame in the
mesh's (world) frame, metres.
"""

from __future__ import annotations

import inspect
import logging
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from whisker_io.array.geometry import WhiskerArray
from whisker_io.errors import ConfigError, InvalidInputError
from whisker_io.pose import Pose
from whisker_io.sim.sweep import MeshTarget, SweepParams, sweep_array
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, finite_vector, validate_fields, whole_number

__all__ = [
    "FittedSurface",
    "LoopShape",
    "TRAJECTORY_FAMILIES",
    "fit_surface",
    "facing_pose",
    "step_sizes",
    "object_trajectory",
    "reaching_roll_deg",
    "touch_share",
    "ReachChoice",
    "choose_reach",
    "MIN_STANDOFF_SHARE",
    "REACH_CONTACTS",
]

logger = logging.getLogger(__name__)

_BACKOFF_STEP_M = 0.005
_MAX_DENSE_TURN_RAD = math.radians(2.0)  # finer dense sampling where the array turns faster
_MAX_DENSE = 4096
_MAX_BACKOFF_STEPS = 40


@dataclass(frozen=True, eq=False)
class FittedSurface:
    """An axis-aligned ellipsoid (or sphere) around an object.

    Attributes
    ----------
    centre_m : ndarray (3,)
        Centre, m.
    semi_axes_m : ndarray (3,)
        Semi-axes along world x, y, z, m (all equal for a sphere).
    """

    centre_m: NDArray[np.float64]
    semi_axes_m: NDArray[np.float64]

    def point(self, azimuth_rad: ArrayLike, elevation_rad: ArrayLike) -> NDArray[np.float64]:
        """Points of the surface at azimuth (about +z from +x) and elevation, shape (..., 3), m."""
        az = np.asarray(azimuth_rad, dtype=float)
        el = np.asarray(elevation_rad, dtype=float)
        unit = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)
        return self.centre_m + unit * self.semi_axes_m


def fit_surface(mesh: trimesh.Trimesh, shape: Literal["ellipsoid", "sphere"] = "ellipsoid") -> FittedSurface:
    """The ellipsoid (semi-axes ``sqrt(3) h``) or sphere (radius ``|h|``) through the corners of
    the mesh's bounding box (centre ``c``, half-extents ``h``); see the module docstring.

    Raises
    ------
    InvalidInputError
        Not a non-empty ``trimesh.Trimesh``, a flat or non-finite bounding box, or
        an unknown shape.
    """
    _check_mesh(mesh)
    lo, hi = np.asarray(mesh.bounds, dtype=float)
    h = 0.5 * (hi - lo)
    if not (np.all(np.isfinite(h)) and np.all(h > 0)):
        raise InvalidInputError(f"the mesh's bounding box {mesh.bounds.tolist()} is flat or not finite")
    if shape == "ellipsoid":
        axes = math.sqrt(3.0) * h
    elif shape == "sphere":
        axes = np.full(3, float(np.linalg.norm(h)))
    else:
        raise InvalidInputError(f"unknown fitted shape {shape!r}; use 'ellipsoid' or 'sphere'")
    centre = 0.5 * (hi + lo)
    centre.setflags(write=False)
    axes.setflags(write=False)
    return FittedSurface(centre, axes)


@dataclass(frozen=True)
class LoopShape(ConfigDataclass):
    """One closed loop on a fitted surface (see the module docstring, item 2).

    Attributes
    ----------
    azimuth_start_deg : float
        Azimuth of the first pose, degrees (about +z, from +x).
    direction : int
        +1 counter-clockwise seen from above, -1 clockwise.
    elevation_amplitude_deg : float
        Amplitude of the elevation oscillation, degrees (0 for a ring of latitude).
    elevation_waves : int
        Oscillations per loop (>= 0).
    elevation_phase_deg : float
        Phase of the oscillation, degrees.
    elevation_offset_deg : float
        Mean elevation, degrees; ``|offset| + amplitude`` must stay below 80 deg.
    """

    azimuth_start_deg: float = checked(0.0, float, error=InvalidInputError, reader=finite_scalar)
    direction: int = 1
    elevation_amplitude_deg: float = checked(25.0, float, error=InvalidInputError, reader=finite_scalar)
    elevation_waves: int = checked(2, int, minimum=0, error=InvalidInputError, reader=whole_number)
    elevation_phase_deg: float = checked(0.0, float, error=InvalidInputError, reader=finite_scalar)
    elevation_offset_deg: float = checked(0.0, float, error=InvalidInputError, reader=finite_scalar)

    def __post_init__(self) -> None:
        validate_fields(self)
        if self.direction not in (1, -1) or isinstance(self.direction, bool):  # a set (1.0 passes), not a kind
            raise ConfigError(f"direction must be +1 or -1, got {self.direction!r}")
        if not (self.elevation_amplitude_deg >= 0
                and abs(self.elevation_offset_deg) + self.elevation_amplitude_deg < 80.0):
            raise ConfigError(
                "elevation_amplitude_deg must be >= 0 and |elevation_offset_deg| + amplitude < 80 deg "
                "(near the poles the loop degenerates)")

    def angles(self, s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Azimuth and elevation (rad) at loop parameter ``s`` in [0, 1)."""
        az = math.radians(self.azimuth_start_deg) + self.direction * 2.0 * math.pi * s
        el = math.radians(self.elevation_offset_deg) + math.radians(self.elevation_amplitude_deg) * np.sin(
            2.0 * math.pi * self.elevation_waves * s + math.radians(self.elevation_phase_deg))
        return az, el


TRAJECTORY_FAMILIES: dict[str, LoopShape] = {
    "A": LoopShape(azimuth_start_deg=0.0, direction=1, elevation_amplitude_deg=25.0,
                   elevation_waves=2, elevation_phase_deg=0.0),
    "B": LoopShape(azimuth_start_deg=35.0, direction=-1, elevation_amplitude_deg=18.0,
                   elevation_waves=3, elevation_phase_deg=90.0, elevation_offset_deg=5.0),
}
"""The two Ch.5 families: "A" builds the object maps, "B" is the novel validation trajectory."""


def _check_mesh(mesh: object) -> None:
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InvalidInputError(f"mesh must be a non-empty trimesh.Trimesh, got {type(mesh).__name__}")


def _frames(y_axes: NDArray[np.float64], up: NDArray[np.float64],
            previous_z: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Rotations (n, 3, 3) with columns (x, y, z): y given (unit), z = up made perpendicular
    to y, x = y x z (Alg 8); where y is vertical the previous row's z (or ``previous_z``) is kept."""
    z = up - (y_axes @ up)[:, None] * y_axes
    norm = np.linalg.norm(z, axis=1)
    for i in np.flatnonzero(norm < 1e-6):  # axis vertical: keep the previous roll
        prev = z[i - 1] if i > 0 else (previous_z if previous_z is not None else np.array([1.0, 0.0, 0.0]))
        for ref in (prev, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):  # a previous z along y: x instead
            z[i] = ref - (ref @ y_axes[i]) * y_axes[i]
            norm[i] = np.linalg.norm(z[i])
            if norm[i] > 1e-6 * np.linalg.norm(ref):
                break
    z = z / norm[:, None]
    return np.stack([np.cross(y_axes, z), y_axes, z], axis=2)


_TINY_AXIS = 1e-150  # a vector shorter than this loses precision in its norm (squares below 1e-300)


def _unit_vector(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` (3,) scaled to length 1; InvalidInputError when it is not finite or is zero. A vector
    shorter than 1e-150, whose squares underflow (the norm of (3e-170, -4e-170, 0) is 0), is scaled to
    its largest component first; longer ones are divided by their norm."""
    v = finite_vector(value, 3, name)
    largest = float(np.abs(v).max())
    if not largest > 0:
        raise InvalidInputError(f"{name} must be a non-zero vector")
    n = float(np.linalg.norm(v))
    if n < _TINY_AXIS:
        v = v / largest
        n = float(np.linalg.norm(v))
    return v / n


def facing_pose(
    surface_point_m: ArrayLike,
    axis: ArrayLike,
    standoff_m: float,
    previous_z: ArrayLike | None = None,
    up: ArrayLike = (0.0, 0.0, 1.0),
) -> Pose:
    """The end-effector pose whose array axis (+y) points along ``axis`` at ``surface_point_m``.

    Parameters
    ----------
    surface_point_m : array_like (3,)
        The surface point the array faces, m.
    axis : array_like (3,)
        Direction of the array axis (toward the surface); normalised here.
    standoff_m : float
        Distance from the end-effector origin to the surface point along the axis, m.
    previous_z : array_like (3,), optional
        The previous pose's z-axis, kept when ``axis`` is vertical (one along the axis: the x-axis
        made perpendicular instead).
    up : array_like (3,)
        World up direction (Alg 8's ``g``).

    Returns
    -------
    Pose
        Origin ``surface_point - standoff axis``, z-axis as close to ``up`` as the
        axis allows, ``x = y x z``.
    """
    s = finite_vector(surface_point_m, 3, "surface_point_m")
    y = _unit_vector(axis, "axis")
    g = _unit_vector(up, "up")
    pz = None if previous_z is None else finite_vector(previous_z, 3, "previous_z")  # used as given (bits kept)
    if pz is not None and not np.abs(pz).max() > 0:
        raise InvalidInputError("previous_z must be a non-zero vector (the previous pose's z-axis)")
    d = finite_scalar(standoff_m, "standoff_m")
    R = _frames(y[None], g, pz)[0]
    return Pose.from_rotation(s - d * y, Rotation.from_matrix(R))


def _bases_blocked(
    target: MeshTarget, origins: NDArray[np.float64], rotations: NDArray[np.float64], bases_e: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Per pose (n,): does a segment from the end-effector origin to a whisker base cross the mesh?"""
    n, m = len(origins), len(bases_e)
    seg = np.einsum("nij,mj->nmi", rotations, bases_e).reshape(-1, 3)
    length = np.linalg.norm(seg, axis=1)
    start = np.repeat(origins, m, axis=0)
    dist, _, _ = target.first_hits(start, seg / length[:, None], length)
    return np.isfinite(dist).reshape(n, m).any(axis=1)


_ADVANCE_STEP_M = 0.01  # step of item 6's advance, m
_MAX_REACH_CONTACTS = 64
#: Share of the fixed-standoff poses touched by 3 whiskers below which :func:`choose_reach` reaches.
MIN_STANDOFF_SHARE = 0.5
#: Whiskers a pose reaches for by default: a region observation of Eq 5.5 needs 3 contacts.
REACH_CONTACTS = 3
_RIGID = SweepParams(refine=False)  # which whiskers touch, not where: no refinement of the contact angle


def _touching(target: MeshTarget, arr: WhiskerArray, pose: Pose) -> int:
    """Whiskers whose rigid sweep from ``pose`` touches the mesh."""
    return sum(c is not None for c in sweep_array(arr, target, pose, _RIGID))


def _advance_to_contact(target: MeshTarget, arr: WhiskerArray, origin: NDArray[np.float64], R: NDArray[np.float64],
                        wanted: int, max_advance_m: float) -> None:
    """Item 6 of the module docstring, in place on ``origin`` (n, 3); ``R`` (n, 3, 3) the poses' rotations."""

    def touching(o: NDArray[np.float64], r: NDArray[np.float64]) -> int:
        return _touching(target, arr, Pose(o, Rotation.from_matrix(r).as_quat()))

    steps = int(math.floor(max_advance_m / _ADVANCE_STEP_M + 1e-9))
    for i in range(len(origin)):
        best = touching(origin[i], R[i])
        if best >= wanted:
            continue
        best_o = origin[i].copy()
        for k in range(1, steps + 1):
            o = origin[i] + k * _ADVANCE_STEP_M * R[i, :, 1]
            if _bases_blocked(target, o[None], R[i][None], arr.positions_m)[0]:
                break
            c = touching(o, R[i])
            if c > best:
                best, best_o = c, o
            if c >= wanted:
                break
        origin[i] = best_o


def _share_and_reach(share: object, share_name: str, reach_contacts: object, trajectory: dict[str, object],
                     caller: str) -> tuple[float, int]:
    """``(share, whiskers)`` checked: a share of poses in [0, 1], a count >= 1, and ``trajectory`` leaving
    the loop's own arguments to ``caller``."""
    value = finite_scalar(share, share_name)
    if not 0.0 <= value <= 1.0:
        raise InvalidInputError(f"{share_name} must be a share of poses in [0, 1], got {share!r}")
    k = _reach_count(reach_contacts)
    for name in ("n_loops", "roll_deg", "reach_contacts"):
        if name in trajectory:
            raise InvalidInputError(f"{caller} sets {name} itself; do not pass it")
    unknown = sorted(set(trajectory) - set(inspect.signature(object_trajectory).parameters))
    if unknown:
        raise InvalidInputError(f"{caller} passes its further arguments to object_trajectory, which takes no "
                                f"{', '.join(unknown)}")
    return value, k


def _reach_count(reach_contacts: object) -> int:
    """Whiskers to reach for, 1 to the array's 64 at most."""
    k = whole_number(reach_contacts, "reach_contacts", minimum=1)
    if k > _MAX_REACH_CONTACTS:
        raise InvalidInputError(f"reach_contacts must be 1-{_MAX_REACH_CONTACTS} whiskers, got {k}")
    return k


def touch_share(
    mesh: trimesh.Trimesh | MeshTarget,
    poses: list[Pose] | tuple[Pose, ...],
    reach_contacts: int = REACH_CONTACTS,
    array: WhiskerArray | None = None,
) -> float:
    """Share of ``poses`` whose rigid sweep touches ``mesh`` with ``reach_contacts`` whiskers or more.

    The measure of items 4 and 6 (module docstring): the whiskers a pose touches with
    (:func:`whisker_io.sim.sweep.sweep_array`, no refinement, no noise), counted the way
    a region observation of Eq 5.5 needs 3 of them. It reads the mesh, so it is for
    planning a simulated trajectory, never for an explorer.

    Parameters
    ----------
    mesh : trimesh.Trimesh or MeshTarget
        The object (metres).
    poses : list or tuple of Pose
        End-effector poses in the mesh's frame (at least one).
    reach_contacts : int, default :data:`REACH_CONTACTS` (3)
        Whiskers a pose must touch with (1-64).
    array : WhiskerArray, optional
        The array (default: the thesis array).

    Returns
    -------
    float
        In [0, 1].

    Raises
    ------
    InvalidInputError
        No pose, something other than :class:`~whisker_io.pose.Pose` s, ``reach_contacts``
        outside 1-64, an ``array`` that is not a :class:`~whisker_io.array.geometry.WhiskerArray`,
        or a mesh :class:`~whisker_io.sim.sweep.MeshTarget` refuses.
    """
    k = _reach_count(reach_contacts)
    poses = list(poses) if isinstance(poses, tuple) else poses
    if not isinstance(poses, list) or not poses or not all(isinstance(p, Pose) for p in poses):
        raise InvalidInputError("poses must be a non-empty list or tuple of Pose (end-effector poses in the mesh's frame)")
    if array is not None and not isinstance(array, WhiskerArray):
        raise InvalidInputError(f"array must be a WhiskerArray or None (the thesis array), got {type(array).__name__}")
    target = mesh if isinstance(mesh, MeshTarget) else MeshTarget(mesh)
    arr = WhiskerArray.thesis() if array is None else array
    return float(np.mean([_touching(target, arr, p) >= k for p in poses]))


@dataclass(frozen=True)
class ReachChoice:
    """How the poses round one object reach its surface (:func:`choose_reach`).

    Attributes
    ----------
    standoff_touch_share : float
        Share (0-1) of one fixed-standoff loop's poses touched by ``reach_contacts`` whiskers
        (3 when the standoff is kept).
    reach_contacts : int
        :func:`object_trajectory`'s ``reach_contacts``: 0 keeps the thesis' fixed standoff.
    roll_deg : float
        :func:`object_trajectory`'s ``roll_deg``, degrees.
    """

    standoff_touch_share: float
    reach_contacts: int
    roll_deg: float


def choose_reach(
    mesh: trimesh.Trimesh,
    family: str | LoopShape = "A",
    reach_contacts: int = REACH_CONTACTS,
    min_share: float = MIN_STANDOFF_SHARE,
    **trajectory: object,
) -> ReachChoice:
    """The thesis' fixed standoff where it touches, poses reaching for ``reach_contacts`` whiskers where it does not.

    One loop of ``family`` at the fixed standoff (items 1-5) is built; when fewer than
    ``min_share`` of its poses are touched by ``reach_contacts`` whiskers or more
    (:func:`touch_share`) - a torus lying flat between the array's rows, a duck's narrow head
    - the poses reach (item 6) at the roll :func:`reaching_roll_deg` picks; otherwise the
    thesis' poses are kept (roll 90 deg). Build the trajectory, of any family, with
    ``object_trajectory(mesh, family, n, reach_contacts=c.reach_contacts, roll_deg=c.roll_deg)``.
    Measured (the WhiskerRatSLAM demo, :mod:`cansim.studies.whisker_ratslam_demo`): the Mug
    (0.89), the Box (0.95) and the Ch.5 objects (0.57-1.00 along A) keep the standoff; a flat
    torus, a mushroom and a bowl (0.00) and the duck (0.17) reach.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    family : {"A", "B"} or LoopShape
        The loop the choice is made on (choose on the mapping loop and use the choice for
        every family, so that one object is always whisked alike).
    reach_contacts : int, default :data:`REACH_CONTACTS` (3)
        Whiskers counted, and reached for (1-64; 3: a region of Eq 5.5).
    min_share : float, default :data:`MIN_STANDOFF_SHARE`
        Share of poses (0-1) below which the poses reach.
    **trajectory
        Further :func:`object_trajectory` arguments (``step_m``, ``step_deg``, ...), not
        ``n_loops``, ``roll_deg`` or ``reach_contacts``.

    Raises
    ------
    InvalidInputError, ConfigError
        ``min_share`` outside [0, 1], or what :func:`reaching_roll_deg` refuses.
    """
    share_min, k = _share_and_reach(min_share, "min_share", reach_contacts, trajectory, "choose_reach")
    loop = object_trajectory(mesh, family, 1, **trajectory)  # type: ignore[arg-type]
    share = touch_share(mesh, loop, k, trajectory.get("array"))  # type: ignore[arg-type]
    if share >= share_min:
        return ReachChoice(share, 0, 90.0)
    return ReachChoice(share, k, float(reaching_roll_deg(mesh, family, k, **trajectory)))


def reaching_roll_deg(
    mesh: trimesh.Trimesh,
    family: str | LoopShape = "A",
    reach_contacts: int = 3,
    candidates_deg: tuple[float, ...] = (90.0, 0.0),
    min_gain: float = 0.1,
    **trajectory: object,
) -> float:
    """The roll (module docstring, item 4) at which one loop around ``mesh`` is touched by
    ``reach_contacts`` whiskers most often.

    The thesis array rolled by 90 deg (the default of :func:`object_trajectory`) reaches
    upright, vertically curved objects with two columns of whiskers; a flat object (a torus
    lying flat, a bowl) lies between its rows and is touched by one or two whiskers wherever
    the poses reach (no region observation, Eq 5.5: no map). For each candidate in order
    this builds one loop of ``family`` reaching for ``reach_contacts`` whiskers (item 6) and
    counts the share of its poses whose rigid sweep touches with that many; the first
    candidate is kept unless another's share exceeds it by more than ``min_gain`` (then the
    one with the highest share; the earlier of equals). A candidate is not built when the
    first's share leaves no room for that gain.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    family : {"A", "B"} or LoopShape
    reach_contacts : int, default 3
        Whiskers a pose should touch with (1-64).
    candidates_deg : tuple of float, default (90, 0)
        Rolls to try, degrees, the preferred first (at least one).
    min_gain : float, default 0.1
        Share of the loop's poses (0-1) by which another roll must do better than the first.
    **trajectory
        Further :func:`object_trajectory` arguments (``step_m``, ``step_deg``, ``array``,
        ``max_advance_m``, ...), the same for every candidate.

    Returns
    -------
    float
        The chosen roll, degrees (one of ``candidates_deg``).

    Raises
    ------
    InvalidInputError, ConfigError
        No candidate, a non-finite candidate, ``min_gain`` outside [0, 1], ``reach_contacts``
        below 1, or anything :func:`object_trajectory` refuses.
    """
    rolls = [finite_scalar(r, "candidates_deg") for r in candidates_deg]
    if not rolls:
        raise InvalidInputError("candidates_deg needs at least one roll, degrees (e.g. (90.0, 0.0))")
    gain, k = _share_and_reach(min_gain, "min_gain", reach_contacts, trajectory, "reaching_roll_deg")
    arr = trajectory.get("array")
    arr = WhiskerArray.thesis() if arr is None else arr
    target = None
    best_roll, best_share, first_share = rolls[0], -1.0, -1.0
    for i, roll in enumerate(rolls):
        if i and first_share > 1.0 - gain:
            break  # no candidate can beat the first by more than the gain
        loop = object_trajectory(mesh, family, 1, roll_deg=roll, reach_contacts=k, **trajectory)  # type: ignore[arg-type]
        target = MeshTarget(mesh) if target is None else target
        share = touch_share(target, loop, k, arr)
        if i == 0:
            first_share = best_share = share
        elif share > first_share + gain and share > best_share:
            best_roll, best_share = roll, share
    return best_roll


def _smoothed_axes(directions: NDArray[np.float64], window: int) -> NDArray[np.float64]:
    """Unit directions averaged over a centred circular window of ``window`` dense samples."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    if window > 1:
        n = len(d)
        idx = (np.arange(n)[:, None] + np.arange(window) - window // 2) % n
        d = d[idx].mean(axis=1)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
    return d


def step_sizes(poses: list[Pose]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Translation (m) and rotation (rad) of each step between successive poses, shape (n - 1,) each."""
    if len(poses) < 2:
        return np.zeros(0), np.zeros(0)
    p = np.array([q.position_m for q in poses])
    r = Rotation.from_quat(np.array([q.quaternion_xyzw for q in poses]))
    return np.linalg.norm(p[1:] - p[:-1], axis=1), (r[:-1].inv() * r[1:]).magnitude()


def object_trajectory(
    mesh: trimesh.Trimesh,
    family: str | LoopShape = "A",
    n_loops: int = 2,
    step_m: float = 0.11,
    step_deg: float = 12.0,
    shape: Literal["ellipsoid", "sphere"] = "ellipsoid",
    clearance_m: float = 0.015,
    array: WhiskerArray | None = None,
    samples_per_loop: int = 240,
    up: ArrayLike = (0.0, 0.0, 1.0),
    roll_deg: float = 90.0,
    smoothing_deg: float = 20.0,
    reach_contacts: int = 0,
    max_advance_m: float = 0.12,
) -> list[Pose]:
    """Whisk poses of ``n_loops`` loops around ``mesh`` (see the module docstring).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The object, world frame, metres, standing along ``up``.
    family : {"A", "B"} or LoopShape
        Loop family (:data:`TRAJECTORY_FAMILIES`) or a custom loop.
    n_loops : int, default 2
        Times the loop is run (>= 1); every loop visits the same poses.
    step_m, step_deg : float
        Largest translation (m) and rotation (degrees) between whisks. Thesis:
        0.11 m and 12 deg; the Box 0.03 m and 3 deg.
    shape : {"ellipsoid", "sphere"}
        Fitted surface that steers the loop (:func:`fit_surface`).
    clearance_m : float, default 0.015
        Gap between the surface and the most rostral whisker base along the axis, m.
    array : WhiskerArray, optional
        The array (default the thesis array); sets the standoff and the base check.
    samples_per_loop : int, default 240
        Dense poses per loop from which the whisk poses are picked (>= 16).
    up : array_like (3,)
        World up direction.
    roll_deg : float, default 90
        Rotation of the array about its own axis from the Alg 8 frame (z up), degrees
        (module docstring, item 4).
    smoothing_deg : float, default 20
        Width of the loop window (degrees of the loop parameter, 0-180) over which
        the facing directions are averaged (module docstring, item 3).
    reach_contacts : int, default 0
        Whiskers a whisk should touch with (0-64): a pose touching with fewer moves
        forward along its axis until that many touch (module docstring, item 6). 0: the
        fixed standoff of item 3.
    max_advance_m : float, default 0.12
        Farthest such a move goes, m (0-1).

    Returns
    -------
    list of Pose
        ``n_loops * m`` poses, ``m >= 3`` per loop, in whisk order.

    Raises
    ------
    InvalidInputError, ConfigError
        A bad mesh, an unknown family or shape, non-positive steps, fewer than one
        loop or non-finite parameters.
    """
    _check_mesh(mesh)
    if isinstance(family, str):
        try:
            loop = TRAJECTORY_FAMILIES[family]
        except KeyError:
            raise ConfigError(f"unknown trajectory family {family!r}; use one of {sorted(TRAJECTORY_FAMILIES)} "
                              "or a LoopShape") from None
    elif isinstance(family, LoopShape):
        loop = family
    else:
        raise ConfigError(f"family must be 'A', 'B' or a LoopShape, got {type(family).__name__}")
    loops = whole_number(n_loops, "n_loops", minimum=1)
    dense = whole_number(samples_per_loop, "samples_per_loop", minimum=16)
    step_t = finite_scalar(step_m, "step_m")
    step_r = math.radians(finite_scalar(step_deg, "step_deg"))
    clearance = finite_scalar(clearance_m, "clearance_m")
    if not (step_t > 0 and step_r > 0):
        raise InvalidInputError(f"step_m and step_deg must be > 0, got {step_m!r} and {step_deg!r}")
    if not 0 <= clearance <= 1.0:
        raise InvalidInputError(f"clearance_m must be in [0, 1] m, got {clearance_m!r}")
    g = _unit_vector(up, "up")
    arr = WhiskerArray.thesis() if array is None else array
    if not isinstance(arr, WhiskerArray):
        raise InvalidInputError(f"array must be a WhiskerArray, got {type(arr).__name__}")
    standoff = clearance + float(arr.positions_m[:, 1].max())
    surface = fit_surface(mesh, shape)
    target = MeshTarget(mesh)
    smoothing = finite_scalar(smoothing_deg, "smoothing_deg")
    if not 0 <= smoothing <= 180:
        raise InvalidInputError(f"smoothing_deg must be in [0, 180], got {smoothing_deg!r}")
    reach = whole_number(reach_contacts, "reach_contacts", minimum=0)
    if reach > min(_MAX_REACH_CONTACTS, len(arr.positions_m)):
        raise InvalidInputError(f"reach_contacts must be in [0, {min(_MAX_REACH_CONTACTS, len(arr.positions_m))}] (the "
                                f"array's {len(arr.positions_m)} whiskers at most), got {reach_contacts!r}")
    advance = finite_scalar(max_advance_m, "max_advance_m")
    if not 0 <= advance <= 1.0:
        raise InvalidInputError(f"max_advance_m must be in [0, 1] m, got {max_advance_m!r}")
    far = 2.0 * float(np.linalg.norm(surface.semi_axes_m))
    roll = Rotation.from_rotvec([0.0, math.radians(finite_scalar(roll_deg, "roll_deg")), 0.0]).as_matrix()

    def back_off(origin: NDArray[np.float64], R: NDArray[np.float64]) -> int:
        """Move poses whose whisker bases are inside or behind the object back along the axis; how many still are."""
        pending = np.arange(len(origin))
        for _ in range(_MAX_BACKOFF_STEPS):
            pending = pending[_bases_blocked(target, origin[pending], R[pending], arr.positions_m)]
            if not pending.size:
                return 0
            origin[pending] -= _BACKOFF_STEP_M * R[pending, :, 1]
        return int(pending.size)

    def dense_loop(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        P = surface.point(*loop.angles(np.arange(n) / n))
        S, _, _ = trimesh.proximity.closest_point(mesh, P)
        S = np.asarray(S, dtype=float)
        axes = _smoothed_axes(S - P, max(1, int(round(n * smoothing / 360.0))))
        hit, _, H = target.first_hits(P, axes, np.full(n, far))
        H = np.where(np.isfinite(hit)[:, None], H, S)  # a ray past a thin part: the nearest point
        R = _frames(axes, g) @ roll
        origin = H - standoff * axes
        back_off(origin, R)
        return origin, R

    def turns(R: NDArray[np.float64]) -> Rotation:
        rot = Rotation.from_matrix(R)
        return rot.inv() * rot[np.roll(np.arange(len(R)), -1)]

    origin, R = dense_loop(dense)
    turn = turns(R)
    widest = float(turn.magnitude().max())
    if widest > _MAX_DENSE_TURN_RAD and dense < _MAX_DENSE:  # sharp turns (edges): sample them finer
        dense = min(_MAX_DENSE, int(math.ceil(dense * widest / _MAX_DENSE_TURN_RAD)))
        origin, R = dense_loop(dense)
        turn = turns(R)

    # the closed loop's step costs, then whisk poses at equal cost increments along it
    nxt = np.roll(np.arange(dense), -1)
    rot = Rotation.from_matrix(R)
    cost = np.maximum(np.linalg.norm(origin[nxt] - origin, axis=1) / step_t, turn.magnitude() / step_r)
    cum = np.concatenate([[0.0], np.cumsum(cost)])  # cum[j] at dense pose j, cum[-1] back at pose 0
    n_steps = max(3, int(math.ceil(cum[-1] - 1e-9)))
    targets = cum[-1] * np.arange(n_steps) / n_steps
    seg = np.clip(np.searchsorted(cum, targets, side="right") - 1, 0, dense - 1)
    frac = np.where(cost[seg] > 0, (targets - cum[seg]) / np.where(cost[seg] > 0, cost[seg], 1.0), 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    pos = origin[seg] + frac[:, None] * (origin[nxt[seg]] - origin[seg])
    rots = (rot[seg] * Rotation.from_rotvec(frac[:, None] * turn[seg].as_rotvec())).as_matrix()  # slerp
    inside = back_off(pos, rots)  # the whisk poses (the dense loop's samples above are not whisked)
    if inside:
        meta = getattr(mesh, "metadata", None) or {}
        label = meta.get("name") or meta.get("file_name") or f"the mesh of extents {np.round(mesh.extents, 3).tolist()} m"
        logger.warning("trajectory %s of %s: %d of %d poses still have whisker bases behind the surface after backing "
                       "off %.0f mm (their whisks start inside the object)", getattr(family, "name", family), label,
                       inside, n_steps, 1e3 * _BACKOFF_STEP_M * _MAX_BACKOFF_STEPS)
    if reach > 0:
        _advance_to_contact(target, arr, pos, rots, reach, advance)
    quats = Rotation.from_matrix(rots).as_quat()
    one_loop = [Pose(pos[i], quats[i]) for i in range(n_steps)]
    return one_loop * loops
