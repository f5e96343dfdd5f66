"""Pose-graph optimisation of the whisk poses of a mapping run (issue 22, stored surfaces).

An object map places what was felt by its experience poses (:meth:`maps.object_map.ObjectMap.surface_points`),
and those are only as good as dead reckoning and the map's relaxation (Eq 5.13 with
the relaxation of Eq 2.25, OpenRatSLAM ``iterate``). Measured on the Ch.5 mapping runs
(2 loops of trajectory A, Eq 6.4-6.11 odometry noise), relaxing the object map to
convergence does not move its surface: the stored contacts stay 30 mm (Mug) to 78 mm
(Box) from the mesh. Two things the map cannot do are done here:

* **every whisk is a node**, not every experience: a whisk that re-localised keeps
  its own pose instead of being snapped to the experience it matched (the map stores
  its contacts as felt from that experience's pose), and the odometry of every loop is
  kept (the map's duplicate-link rule drops the odometry of an experience pair linked
  before, so loops 2, 3, ... add no information to the map);
* **least squares over SE(3)** (:func:`scipy.optimize.least_squares`, sparse Jacobian):
  each edge ``(a, b, Z)`` is the residual ``log(Z^-1 T_a^-1 T_b)`` (rotation vector,
  translation), weighted by the inverse of its standard deviation, jointly for all
  edges, instead of the incremental per-link relaxation.

The edges (:func:`whisk_graph_edges`) are the odometry between consecutive whisks
(Eq 5.7, integrated as the object map does, Eq 5.13; standard deviation of the Eq 6.6 /
6.9 noise: 2.5 deg per axis, 1 cm) and one loop closure per re-localisation: whisk ``k``
re-localised into experience ``e`` (the model's own decision, never the true pose), so
its pose equals that of the whisk that created ``e`` within the matching tolerance
(``closure_sigma_m``, ``closure_sigma_deg``).

Measured (stored surface vs the mesh: median distance of the contacts, placed from the
first whisk's true pose, to :func:`trimesh.proximity.closest_point`; maps of the
recognition study, 2 loops of trajectory A, 0.3 x Sec 6.1.3.1.2 contact noise, Eq
6.4-6.11 odometry noise; ``/tmp`` scratch script, numbers in the issue-22 report):

=========  ===========  =============  ==========  ===========
object     seed 0 map   seed 0 graph   seed 1 map  seed 1 graph
=========  ===========  =============  ==========  ===========
Mug        30.5 mm      16.3 mm        49.5 mm     18.7 mm
Box        77.6         14.1           45.3        27.2
Blob       23.8         21.8           67.0        48.8
Barrel     17.9         14.1           22.0        13.5
Plane      60.4         30.1           41.6        41.9
duck       16.0         14.8           130.3       49.7
bear       40.2         22.9           66.1        19.5
jug        34.7         30.6           28.2        10.5
=========  ===========  =============  ==========  ===========

Held out of all choices (seed 2): Kettle 37.8 -> 15.9 mm, Skull 22.7 -> 17.0, Box-Stack
71.1 -> 8.6, Mug 28.3 -> 11.5, duck 114.3 -> 78.5 (5 closures only). The graph takes
0.1-1.7 s per map. Contacts placed at the *true* whisk poses lie 0.1-1.4 mm from the mesh
(Plane 11 mm): the remaining error is the whisk poses' (after the graph 3-9 cm and
7-13 deg, median), i.e. the odometry of each loop averaged, not removed (4 loops: Mug 11,
Box 17, Blob 14, duck 17 mm). The issue's 5-10 mm target is met by Box-Stack only.
Tried and not kept: relaxing the object map to convergence (2,000 passes; its surface
moves < 0.5 mm: the map's relaxation had converged, it lacks the information above);
adding point-to-plane / point-to-point terms between the contacts of different whisks
(multi-view registration, nearest contact within 3-5 cm, 4-6 rounds) to the graph: Mug
16 -> 15, Box 14 -> 16, Blob 22 -> 27 mm, at 5-25 s per map; a Cauchy loss on the edges
(against false re-localisations; the upright torus gets worse through the graph, 19 ->
37 mm): scale 3 sigma Box 14 -> 105, Blob 22 -> 30 mm, torus unchanged (local minima).

Conventions: a pose is ``(x, y, z m, qx, qy, qz, qw)`` (scalar-last quaternion), the
relative pose of an edge ``T_a^-1 T_b``; the first node is fixed (the frame of the map).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix
from scipy.spatial.transform import Rotation

from maps.odometry import SpatialOdometry
from maps.se3 import SE3Geometry
from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.pose import as_pose
from whisker_io.validation import ConfigDataclass, checked, config_field, finite_array, scale_factor, scaled_fields, validate_fields

__all__ = ["MIN_NOISE_SCALE", "PoseGraphEdges", "WhiskGraphConfig", "dead_reckoned_poses", "noise_model_scale", "optimise_pose_graph", "whisk_graph_edges", "whisk_surface"]


#: Least multiple of Eq 6.4-6.11's odometry noise that the surface path's noise models assume
#: (:meth:`WhiskGraphConfig.for_odometry_scale`, :meth:`maps.surface_match.SurfaceMatchConfig.for_odometry_scale`),
#: however exact the odometry. With exact odometry a surface matcher whose hypotheses never spread
#: cannot follow its stored surface's own error (contact noise, interpolation), and a pose graph with
#: rigid odometry edges lets one re-localisation that disagrees bend the map. Measured in the
#: recognition study (:mod:`cansim.studies.recognition`, Status): quick settings, seeds 0-2, odometry
#: exact, correct along A / B / viewpoints of 36 with the matcher at 0 / 0.1 / 0.25 x: 33 / 32 / 25,
#: 35 / 35 / 35, 36 / 36 / 34 (chosen there, judged on seeds 3-5).
MIN_NOISE_SCALE = 0.25


@dataclass(frozen=True)
class WhiskGraphConfig(ConfigDataclass):
    """Standard deviations of the whisk graph's edges (module docstring).

    Parameters
    ----------
    odometry_sigma_m, odometry_sigma_deg : float
        Of one whisk's odometry (translation m, rotation deg per axis): Eq 6.9's 1 cm and
        Eq 6.6's 2.5 deg.
    closure_sigma_m, closure_sigma_deg : float
        Of a re-localisation: how far a whisk may be from the whisk whose experience it matched.
    """

    odometry_sigma_m: float = checked(0.01, float, above=0)
    odometry_sigma_deg: float = checked(2.5, float, above=0)
    closure_sigma_m: float = checked(0.01, float, above=0)
    closure_sigma_deg: float = checked(3.0, float, above=0)

    def __post_init__(self) -> None:
        validate_fields(self)

    def for_odometry_scale(self, scale: float) -> WhiskGraphConfig:
        """This graph for odometry whose noise is ``scale`` times Eq 6.4-6.11's: the odometry edges'
        deviations times ``max(scale, MIN_NOISE_SCALE)``, the closures' kept (``scale`` 1: an equal copy).

        Raises
        ------
        InvalidInputError
            A scale that is not a finite number >= 0.
        """
        return scaled_fields(self, noise_model_scale(scale), ("odometry_sigma_m", "odometry_sigma_deg"))


def noise_model_scale(scale: object) -> float:
    """The multiple of Eq 6.4-6.11's noise a model of odometry ``scale`` times as noisy assumes:
    ``max(scale, MIN_NOISE_SCALE)`` (a typed error for a scale that is not a finite number >= 0)."""
    return max(scale_factor(scale, hint=" (a multiple of Eq 6.4-6.11's odometry noise)"), MIN_NOISE_SCALE)


@dataclass(frozen=True)
class PoseGraphEdges:
    """Edges of a pose graph.

    Attributes
    ----------
    ends : ndarray (m, 2) int
        ``(a, b)`` node indices.
    relative : ndarray (m, 7)
        Measured ``T_a^-1 T_b`` as ``(x, y, z m, qx, qy, qz, qw)``.
    sigma_m, sigma_rad : ndarray (m,)
        Standard deviation of the translation (m) and of each rotation-vector component (rad).
    """

    ends: np.ndarray
    relative: np.ndarray
    sigma_m: np.ndarray
    sigma_rad: np.ndarray


def _edges_checked(edges: PoseGraphEdges, n: int) -> PoseGraphEdges:
    if not isinstance(edges, PoseGraphEdges):
        raise InvalidInputError(f"edges must be PoseGraphEdges, got {type(edges).__name__}")
    ends = np.asarray(edges.ends)
    if ends.ndim != 2 or ends.shape[1] != 2 or not np.issubdtype(ends.dtype, np.integer):
        raise ShapeError(f"edge ends must be an (m, 2) integer array, got shape {ends.shape} of {ends.dtype}")
    m = len(ends)
    rel = finite_array(edges.relative, (m, 7), "edge relative poses")
    sm = finite_array(edges.sigma_m, (m,), "edge sigma_m")
    sr = finite_array(edges.sigma_rad, (m,), "edge sigma_rad")
    if m and (ends.min() < 0 or ends.max() >= n or np.any(ends[:, 0] == ends[:, 1])):
        raise InvalidInputError(f"edge ends must be distinct node indices in [0, {n}); got {ends.min()}..{ends.max()}")
    if np.any(sm <= 0) or np.any(sr <= 0):
        raise InvalidInputError("edge standard deviations must be > 0")
    if m and np.any(np.abs(np.linalg.norm(rel[:, 3:], axis=1) - 1.0) > 1e-6):
        raise InvalidInputError("edge rotations must be unit quaternions (scalar-last)")
    return PoseGraphEdges(ends.astype(np.int64), rel, sm, sr)


def optimise_pose_graph(initial_poses: Any, edges: PoseGraphEdges, fixed: int = 0, max_evaluations: int = 200) -> np.ndarray:
    """Poses minimising the weighted squared edge residuals (module docstring).

    Parameters
    ----------
    initial_poses : array_like (n, 7)
        Starting poses ``(x, y, z m, qx, qy, qz, qw)``; node ``fixed`` keeps its pose.
    edges : PoseGraphEdges
    fixed : int
        The node held fixed (the gauge).
    max_evaluations : int
        Most residual evaluations of the solver (>= 1).

    Returns
    -------
    ndarray (n, 7)
        The optimised poses (unit quaternions, ``qw >= 0``).

    Raises
    ------
    InvalidInputError, ShapeError
        Malformed poses or edges, ``fixed`` out of range, a non-positive budget.
    """
    x0 = finite_array(initial_poses, (None, 7), "initial_poses")
    n = len(x0)
    if n == 0:
        raise InvalidInputError("a pose graph needs at least one node")
    if np.any(np.abs(np.linalg.norm(x0[:, 3:], axis=1) - 1.0) > 1e-6):
        raise InvalidInputError("initial poses must have unit quaternions (scalar-last)")
    if isinstance(fixed, bool) or not isinstance(fixed, (int, np.integer)) or not 0 <= fixed < n:
        raise InvalidInputError(f"fixed must be a node index in [0, {n}), got {fixed!r}")
    config_field(max_evaluations, "max_evaluations", int, minimum=1)
    e = _edges_checked(edges, n)
    out = x0.copy()
    free = np.array([i for i in range(n) if i != fixed], dtype=np.int64)
    if len(e.ends) == 0 or len(free) == 0:
        return _canonical(out)
    a, b = e.ends[:, 0], e.ends[:, 1]
    z_inv = Rotation.from_quat(e.relative[:, 3:]).inv()
    z_t = e.relative[:, :3]
    wr, wt = 1.0 / e.sigma_rad, 1.0 / e.sigma_m
    state = np.concatenate([Rotation.from_quat(x0[:, 3:]).as_rotvec(), x0[:, :3]], axis=1)
    fixed_state = state[fixed].copy()

    def unpack(z: np.ndarray) -> np.ndarray:
        s = np.empty((n, 6))
        s[fixed] = fixed_state
        s[free] = z.reshape(-1, 6)
        return s

    def residuals(z: np.ndarray) -> np.ndarray:
        s = unpack(z)
        ra_inv = Rotation.from_rotvec(s[a, :3]).inv()
        rel_r = ra_inv * Rotation.from_rotvec(s[b, :3])
        rel_t = ra_inv.apply(s[b, 3:] - s[a, 3:])
        er = (z_inv * rel_r).as_rotvec() * wr[:, None]
        et = (rel_t - z_t) * wt[:, None]
        return np.concatenate([er, et], axis=1).ravel()

    col = np.full(n, -1, dtype=np.int64)
    col[free] = np.arange(len(free))
    rows, cols = [], []
    for k in range(len(a)):
        for v in (a[k], b[k]):
            if col[v] >= 0:
                r, c = np.meshgrid(np.arange(6 * k, 6 * k + 6), np.arange(6 * col[v], 6 * col[v] + 6), indexing="ij")
                rows.append(r.ravel()), cols.append(c.ravel())
    sparsity = csr_matrix((np.ones(sum(len(r) for r in rows)), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(6 * len(a), 6 * len(free)))
    res = least_squares(residuals, state[free].ravel(), jac_sparsity=sparsity, method="trf", x_scale="jac",
                        max_nfev=max_evaluations)
    s = unpack(res.x)
    out[:, :3] = s[:, 3:]
    out[:, 3:] = Rotation.from_rotvec(s[:, :3]).as_quat()
    return _canonical(out)


def _canonical(p: np.ndarray) -> np.ndarray:
    p = p.copy()
    p[:, 3:] /= np.linalg.norm(p[:, 3:], axis=1, keepdims=True)
    p[p[:, 6] < 0, 3:] *= -1
    return p


def dead_reckoned_poses(odometry: Sequence[SpatialOdometry | None]) -> np.ndarray:
    """Poses (n, 7) of the whisks from integrating their odometry (Eq 5.13) from the identity.

    ``odometry[k]`` is the motion from whisk ``k - 1`` to ``k``; ``odometry[0]`` is ignored.
    """
    g = SE3Geometry()
    acc = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    out = [list(acc)]
    for k, o in enumerate(odometry):
        if k == 0:
            continue
        if not isinstance(o, SpatialOdometry):
            raise InvalidInputError(f"odometry[{k}] must be a SpatialOdometry, got {type(o).__name__}")
        g.accumulate(acc, o)
        out.append(list(acc))
    return _canonical(np.array(out, dtype=np.float64).reshape(-1, 7))


def _relative(pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
    ra = Rotation.from_quat(pa[3:])
    return np.concatenate([ra.inv().apply(pb[:3] - pa[:3]), (ra.inv() * Rotation.from_quat(pb[3:])).as_quat()])


def whisk_graph_edges(odometry: Sequence[SpatialOdometry | None], experience_ids: Any, relocalised: Any,
                      config: WhiskGraphConfig = WhiskGraphConfig()) -> PoseGraphEdges:
    """The whisk graph of a mapping run: odometry edges and one closure per re-localisation.

    Parameters
    ----------
    odometry : sequence of SpatialOdometry (n,)
        Motion from whisk ``k - 1`` to ``k`` (``odometry[0]`` ignored, may be None).
    experience_ids : array_like (n,) int
        The model's current experience after each whisk (e.g. ``SlamState.exp_id``).
    relocalised : array_like (n,) bool
        Whether whisk ``k`` re-localised (switched to an experience created earlier).
    config : WhiskGraphConfig

    Returns
    -------
    PoseGraphEdges
        ``n - 1`` odometry edges ``(k - 1, k)``, then ``(i, k)`` with the identity for each
        re-localised whisk ``k`` whose experience was created (first current) at whisk ``i < k``.

    Raises
    ------
    InvalidInputError, ShapeError
        Lengths that differ, odometry that is not SpatialOdometry.
    """
    if not isinstance(config, WhiskGraphConfig):
        raise InvalidInputError(f"config must be a WhiskGraphConfig, got {type(config).__name__}")
    odo = list(odometry)
    n = len(odo)
    ids = np.asarray(experience_ids)
    rel = np.asarray(relocalised)
    if ids.shape != (n,) or rel.shape != (n,):
        raise ShapeError(f"experience_ids and relocalised need one entry per whisk ({n}), got {ids.shape} and {rel.shape}")
    if n and not np.issubdtype(ids.dtype, np.integer):
        raise InvalidInputError(f"experience_ids must be integers, got {ids.dtype}")
    dr = dead_reckoned_poses(odo)
    ends, relative, sm, sr = [], [], [], []
    so, ro = config.odometry_sigma_m, math.radians(config.odometry_sigma_deg)
    for k in range(1, n):
        ends.append((k - 1, k)), relative.append(_relative(dr[k - 1], dr[k])), sm.append(so), sr.append(ro)
    first: dict[int, int] = {}
    identity = np.array([0.0, 0, 0, 0, 0, 0, 1])
    sc, rc = config.closure_sigma_m, math.radians(config.closure_sigma_deg)
    for k in range(n):
        e = int(ids[k])
        if e < 0:
            continue
        if e not in first:
            first[e] = k
        elif bool(rel[k]) and first[e] != k:
            ends.append((first[e], k)), relative.append(identity), sm.append(sc), sr.append(rc)
    return PoseGraphEdges(np.array(ends, dtype=np.int64).reshape(-1, 2), np.array(relative).reshape(-1, 7),
                          np.array(sm, dtype=np.float64), np.array(sr, dtype=np.float64))


def whisk_surface(odometry: Sequence[SpatialOdometry | None], experience_ids: Any, relocalised: Any,
                  contacts_m: Sequence[Any], config: WhiskGraphConfig = WhiskGraphConfig(),
                  max_evaluations: int = 200, with_viewpoints: bool = False, anchor: Any = None) -> Any:
    """What a mapping run felt, placed by its optimised whisk poses, in the first whisk's frame (or ``anchor``'s).

    The whisk graph (:func:`whisk_graph_edges`) is optimised from dead reckoning
    (:func:`optimise_pose_graph`, the first whisk fixed at the identity) and each whisk's
    contacts are placed by its pose.

    Parameters
    ----------
    odometry, experience_ids, relocalised, config
        As :func:`whisk_graph_edges`.
    contacts_m : sequence (n,) of array_like (k, 3) or None
        Each whisk's contact points in the end-effector frame, m.
    max_evaluations : int
        As :func:`optimise_pose_graph`.
    with_viewpoints : bool
        Also return where each contact was felt from.
    anchor : Pose or pose-like, optional
        The first whisk's pose in the frame wanted (e.g. the arm's, where mapping began):
        points and viewpoints are returned in that frame (``anchor.apply``); default the
        first whisk's own frame.

    Returns
    -------
    ndarray (n_contacts, 3), or (ndarray (n_contacts, 3), ndarray (n_contacts, 3))
        The contact points, m, in whisk order; with ``with_viewpoints`` also each
        contact's whisk position (the optimised end-effector position, m), which orients
        the stored surface's normals (:mod:`maps.surface_field`).

    Raises
    ------
    InvalidInputError, ShapeError
        As :func:`whisk_graph_edges`; a contact list of another length; malformed points;
        an ``anchor`` that is not a pose.
    """
    frame = None if anchor is None else as_pose(anchor)
    contacts = list(contacts_m)
    odo = list(odometry)
    if len(contacts) != len(odo):
        raise ShapeError(f"need one contact array (or None) per whisk ({len(odo)}), got {len(contacts)}")
    edges = whisk_graph_edges(odo, experience_ids, relocalised, config)
    poses = optimise_pose_graph(dead_reckoned_poses(odo), edges, fixed=0, max_evaluations=max_evaluations) if odo else np.zeros((0, 7))
    out, seen = [np.zeros((0, 3))], [np.zeros((0, 3))]
    for k, c in enumerate(contacts):
        if c is None:
            continue
        p = finite_array(c, (None, 3), f"contacts_m[{k}]")
        if len(p):
            out.append(poses[k, :3] + Rotation.from_quat(poses[k, 3:]).apply(np.array(p, dtype=np.float64)))
            seen.append(np.repeat(poses[k, None, :3], len(p), axis=0))
    points, where = np.concatenate(out), np.concatenate(seen)
    if frame is not None:
        points, where = frame.apply(points), frame.apply(where)
    return (points, where) if with_viewpoints else points
