"""Object identification by registering whisks to the surfaces the object maps felt.

The thesis identifies an object by leaky integration of re-localisations into the
experiences of each object map (Sec 5.2.2.2, 6.1.2.4; :mod:`maps.recognition`): a
re-localisation needs a whisk whose region features (PFH + SDA, Eq 5.5) match a stored
region, i.e. a whisk from (nearly) a pose already visited. Presented along another path
(Ch.5's trajectory B, Fig 5.17) few whisks re-localise and the object is rarely
identified. This module identifies the *surface* instead of the *view*:

1. **Stored surface.** Every object map keeps the contact points of every whisk in the
   frame of the experience they were felt from
   (:meth:`maps.object_map.ObjectMap.record_contacts`); placed by the experience poses
   and by the pose of the map's frame in the arm's frame (the *anchor*: the arm pose at
   which the map started, known to the arm; objects are presented at the place they
   were mapped, within noise) they are each object's surface in one common frame
   (:class:`SurfaceLibrary`). Each stored point gets a normal (principal axes of its
   nearest stored neighbours).
2. **Pose hypothesis.** The exploring arm dead-reckons its pose from the odometry (Eq
   5.7, integrated as the object map does, Eq 5.13) from its known start pose. A whisk's
   contacts (end-effector frame) are placed by it.
3. **Registration per object.** Dead reckoning drifts (Sec 6.1.3.1.1's noise: about
   1 cm and 4 deg per whisk), so every library object ``k`` keeps its own correction
   ``C_k`` of the hypothesis, a rigid transform tracked from whisk to whisk: each whisk's
   contacts, placed by ``C_k``, are registered to ``k``'s surface by a few Gauss-Newton
   iterations of point-to-plane ICP (nearest stored point within ``gate_m``) with a
   Gaussian prior on the increment (``step_sigma_m``, ``step_sigma_deg`` per whisk since
   the last update, the odometry noise), about the contacts' centroid.
4. **Residual and evidence.** After registration each contact's residual is its
   point-to-plane distance to the nearest stored point, ``cap_m`` when no stored point
   lies within ``gate_m`` (a contact where object ``k`` has no surface), capped at
   ``cap_m``; a whisk's score adds to the sum of its squared residuals the change of the
   correction it needed (its Mahalanobis norm under the prior, times
   ``motion_weight * contact_sigma_m**2``: an object that fits only by moving far pays
   for it), and the evidence ``E_k`` is the root mean square of these over the contacts
   of the last ``window_whisks`` whisks with contacts.
5. **Impulse.** Object ``k`` gets an impulse (into its leaky integrator,
   :func:`maps.recognition.leaky_step`, so the RC / IC decisions of Ch.5 / Ch.6 are
   unchanged) only when the window holds at least ``min_window_contacts`` contacts,
   ``E_k <= tolerance_m`` and ``E_k <= ratio * E_j`` for every other object ``j``: the
   object is clearly the best and fits within the tolerance, so a novel object (no
   stored surface fits) gets no decision. The tolerance is calibrated from data
   (:func:`calibrate_tolerance`: a quantile of the same-object evidence, with the
   fraction of different-object evidence under it).

Status (measured; not yet the default anywhere)
------------------------------------------------
Scratch runs (sweep-path whisks, true radial distance with 0.3 x Sec 6.1.3.1.2 contact
noise, Eq 6.4-6.11 odometry noise; maps built with
:meth:`cansim.models.whisker_ratslam.WhiskerRatSLAMConfig.mapping`, 3 loops of trajectory A;
Mug, Blob, Box, Barrel, Plane, seed 0, 300 whisks):

* **The stored surface is the bottleneck.** The maps' experience poses are 0.11-0.24 m
  and 11-37 deg (medians) from the truth (relative to the first experience): dead
  reckoning drifts about 4 deg per whisk and re-localisations on loops 2-3 close the
  loop but do not undo loop 1's distortion. Placed by them the stored contacts lie a
  median 31-34 mm (Mug, Box, Barrel), 67 mm (Plane) and 111 mm (Blob) from the mesh, and
  a whisk's fan (0.3-0.45 m) spans contacts mapped several whisks (several degrees of
  drift) apart. Against these surfaces the matcher does not identify: 300 whisks along
  B, 1 of 5 correct IC decisions (threshold 300) and 1 wrong (Plane as Barrel), along A
  1 of 5; the own object's evidence (median 11-18 mm) is no lower than the best other
  object's (7-13 mm), also with noise-free odometry for the presentation (own 9-12 mm).
* **On an accurate surface the matcher is better, not yet good enough.** With each
  library surface made of contacts placed at the true poses of 2 loops of A, the same
  presentation along B (3 loops, noisy dead reckoning tracked as above) scores the own
  object best in 89 % (Mug), 96 % (Blob), 96 % (Box) and 75 % (Barrel) of whisks (own
  median 4-7 mm against 5-13 mm), but the Plane only in 3 % (own 19 mm: the thin plate
  is lost by the tracker); impulses: Mug 56 own / 3 other, Blob 26 / 0, Box 193 / 0,
  Barrel 37 / 11, Plane 0 / 46 (the IC decision fires for the Box only, correctly, over
  these 93-258-whisk runs). On a Mug / Blob / Barrel library, 2 loops of B, seeds 0-5, the
  own object gets most impulses in 14 of 18 presentations (the Mug loses to the Barrel on
  seeds 0-1, the Blob on seeds 1 and 3) and own impulses outnumber wrong ones 1.7 times
  (seed 1) to 48 times (seed 5; none wrong on seed 2) (``tests/test_surface_match.py``, end-to-end test).
* **With less odometry noise** (mapping and presentation at a fraction of Sec 6.1.3.1.1,
  400 whisks): at 0.5 the maps are better and A gives 3 of 5 correct (1 wrong), B 2 of 5
  (1 wrong); at 0.25 (experience poses 3-6 cm / 6-9 deg, surface 10-25 mm from the mesh)
  A gives 5 of 5 correct and B 2 of 5 (Mug, Box; none wrong).
* **Scan-to-model tracking while mapping** (each whisk registered to the contacts felt
  so far, to correct the stored surface) made it worse (Mug 99 mm from the mesh): the
  stored contacts are 3-8 cm apart, so the normals of their local planes are biased on
  curved surfaces, and the bias accumulates even with exact odometry.
* **Surfaces from a pose graph of the whisk poses** (:func:`maps.pose_graph.whisk_surface`:
  every whisk a node, the odometry of every loop and one closure per re-localisation, least
  squares over SE(3)) lie 10-49 mm from the mesh instead of the maps' 16-130 mm (2 loops of
  A; table in :mod:`maps.pose_graph`). Still not enough: presented along 2 loops of B
  against the 8 pose-graph surfaces of Mug, Box, Blob, Barrel, Plane, duck, bear, jug (seed
  0) the own object has the lowest evidence in 19/75 (Mug), 127/170 (Box), 15/71 (Blob),
  16/61 (Barrel), 45/121 (Plane), 1/79 (duck), 8/89 (bear), 24/81 (jug) windows (own median
  10-24 mm, best other 8-13 mm). In the recognition study (``--matchers surface``, same 8
  objects, 200 whisks) it gives 1/8 correct IC decisions along A, 0/8 along B, none wrong.
* **Cost**: 2.7 / 3.6 / 5.7 ms per whisk at 12 / 25 / 50 objects of 1,500 stored points
  (8 contacts a whisk, 3 iterations): over the 2-ms target at 50 objects.

One look-up per iteration serves every object: each object's nearest stored point is
tabulated on a 1-cm grid around its surface (built once with
:class:`scipy.spatial.cKDTree`), so the query of all objects' hypotheses is array
indexing; the Gauss-Newton steps of all objects are one batched solve.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from maps.object_library import ObjectLibrary
from maps.object_map import ObjectMap
from maps.odometry import SpatialOdometry
from maps.se3 import SE3Geometry
from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.validation import config_field, finite_array

__all__ = [
    "SurfaceMatchConfig",
    "SurfaceLibrary",
    "SurfaceMatcher",
    "ToleranceCalibration",
    "calibrate_tolerance",
]

_MAX_CELLS = 8_000_000  # largest look-up table of one object (cells)


@dataclass(frozen=True)
class SurfaceMatchConfig:
    """Parameters of the surface matcher (module docstring).

    Parameters
    ----------
    gate_m : float
        A contact whose nearest stored point of object ``k`` is farther than this is
        off ``k``'s stored surface (residual ``cap_m``, not used by the registration).
    cap_m : float
        Largest residual of one contact, m.
    normal_neighbours : int
        Stored points whose principal axes give a stored point's normal (>= 3).
    icp_iterations : int
        Gauss-Newton iterations per whisk and object (>= 1).
    contact_sigma_m : float
        Standard deviation of a contact's point-to-plane residual on the right object
        (weights the data against the prior), m.
    step_sigma_m, step_sigma_deg : float
        Standard deviation of the drift of the pose hypothesis per whisk (translation
        at the contacts, m; rotation, deg): the growth of the correction's covariance.
    initial_sigma_m, initial_sigma_deg : float
        Standard deviation of the correction before the first whisk (how far the object
        and the maps may be from where the hypothesis puts them: placement, map distortion).
    motion_weight : float
        Weight of the correction's change (its Mahalanobis norm under the prior, in units
        of ``contact_sigma_m**2``) added to a whisk's sum of squared residuals (0: the
        residuals alone).
    window_whisks : int
        Whisks with contacts over which the evidence is pooled.
    min_window_contacts : int
        Fewest contacts in the window for an impulse.
    min_contacts : int
        Fewest contacts of a whisk that is registered (fewer: dead reckoning only).
    tolerance_m : float
        Largest evidence (RMS residual, m) of an object that gets an impulse.
    ratio : float
        The best object's evidence must be at most ``ratio`` times every other's, in (0, 1].
    """

    gate_m: float = 0.08
    cap_m: float = 0.03
    normal_neighbours: int = 8
    icp_iterations: int = 3
    contact_sigma_m: float = 0.008
    step_sigma_m: float = 0.02
    step_sigma_deg: float = 4.5
    motion_weight: float = 1.0
    initial_sigma_m: float = 0.05
    initial_sigma_deg: float = 15.0
    window_whisks: int = 8
    min_window_contacts: int = 12
    min_contacts: int = 3
    tolerance_m: float = 0.012
    ratio: float = 0.75

    def __post_init__(self) -> None:
        config_field(self.motion_weight, "motion_weight", float, minimum=0)
        for name in ("gate_m", "cap_m", "contact_sigma_m", "step_sigma_m", "step_sigma_deg", "initial_sigma_m",
                     "initial_sigma_deg", "tolerance_m"):
            config_field(getattr(self, name), name, float, above=0)
        config_field(self.ratio, "ratio", float, above=0, maximum=1)
        config_field(self.normal_neighbours, "normal_neighbours", int, minimum=3)
        config_field(self.icp_iterations, "icp_iterations", int, minimum=1)
        config_field(self.window_whisks, "window_whisks", int, minimum=1)
        config_field(self.min_window_contacts, "min_window_contacts", int, minimum=1)
        config_field(self.min_contacts, "min_contacts", int, minimum=1)


def _pose7(pose: Any, name: str) -> np.ndarray:
    try:
        p = np.asarray(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be 7 numbers (x, y, z m, qx, qy, qz, qw), got {pose!r}") from None
    if p.shape != (7,):
        raise ShapeError(f"{name} must be (x, y, z m, qx, qy, qz, qw), 7 numbers; got shape {p.shape}")
    if not np.isfinite(p).all() or abs(float(np.linalg.norm(p[3:])) - 1.0) > 1e-6:
        raise InvalidInputError(f"{name} must be finite with a unit quaternion (scalar-last), got {p.tolist()}")
    return p


def _apply(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (n, 3) of a frame at ``pose`` (7,) in the outer frame (scipy needs a writable array)."""
    return pose[:3] + Rotation.from_quat(pose[3:]).apply(np.array(points, dtype=np.float64))


def _normals(points: np.ndarray, k: int) -> np.ndarray:
    """Unit normals (n, 3): the least principal axis of each point's ``k`` nearest points."""
    n = len(points)
    if n < 3:
        return np.tile([0.0, 0.0, 1.0], (n, 1))
    kk = min(k, n)
    _, idx = cKDTree(points).query(points, k=kk)
    nb = points[idx]  # (n, kk, 3)
    d = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", d, d)
    _, vec = np.linalg.eigh(cov)
    return vec[:, :, 0]


class _NearestGrid:
    """Nearest stored point of each object on a regular grid (one flat table for all objects).

    Each cell within ``reach`` of an object's bounding box holds the index of the stored
    point nearest to the cell's centre (:class:`scipy.spatial.cKDTree`, built once); a
    query reads its cell and measures the exact distance to that point. The point found
    is the true nearest one or one at most a cell diagonal farther.
    """

    def __init__(self, surfaces: list[np.ndarray], cell_m: float, reach_m: float) -> None:
        self.cell = cell_m
        lo, shape, start, tables = [], [], [], []
        offset, base = 0, 0
        for pts in surfaces:
            a = pts.min(axis=0) - reach_m
            n = np.ceil((pts.max(axis=0) + reach_m - a) / cell_m).astype(np.int64) + 1
            axes = [a[i] + cell_m * np.arange(n[i]) for i in range(3)]
            centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            d, i = cKDTree(pts).query(centres, k=1, distance_upper_bound=reach_m + cell_m)
            tables.append(np.where(np.isfinite(d), i + base, -1).astype(np.int64))
            lo.append(a), shape.append(n), start.append(offset)
            offset += int(np.prod(n))
            base += len(pts)
        self.lo, self.shape = np.array(lo), np.array(shape)
        self.start = np.array(start, dtype=np.int64)
        self.table = np.concatenate(tables)

    def nearest(self, x: np.ndarray, obj: np.ndarray, gate: float, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ijk = np.floor((x - self.lo[obj]) / self.cell + 0.5).astype(np.int64)
        sh = self.shape[obj]
        inside = np.all((ijk >= 0) & (ijk < sh), axis=1)
        ijk = np.where(inside[:, None], ijk, 0)
        flat = self.start[obj] + (ijk[:, 0] * sh[:, 1] + ijk[:, 1]) * sh[:, 2] + ijk[:, 2]
        idx = np.where(inside, self.table[flat], -1)
        found = idx >= 0
        d = np.full(len(x), np.inf)
        d[found] = np.linalg.norm(x[found] - points[idx[found]], axis=1)
        far = ~(d <= gate)
        d[far] = np.inf
        idx[far] = len(points)
        return d, idx


class SurfaceLibrary:
    """The stored surfaces of several objects in one frame, with normals and one k-d tree.

    Parameters
    ----------
    surfaces_m : sequence of array_like (n_k, 3)
        Each object's stored points in the common (arm) frame, m; at least 3 each.
    names : sequence of str
        Distinct object names, one per surface.
    normal_neighbours : int
        Neighbours of a point's normal (>= 3).

    Raises
    ------
    InvalidInputError, ShapeError
        No object, fewer than 3 points, non-finite points, names that are not distinct or
        do not match the surfaces.
    """

    def __init__(self, surfaces_m: Sequence[Any], names: Sequence[str], normal_neighbours: int = 8,
                 grid_cell_m: float = 0.01, grid_reach_m: float = 0.1) -> None:
        surfaces, names = list(surfaces_m), [str(n) for n in names]
        if not surfaces:
            raise InvalidInputError("a SurfaceLibrary needs at least one object surface")
        if len(names) != len(surfaces) or len(set(names)) != len(names):
            raise InvalidInputError(f"need one distinct name per surface, got {len(names)} names for {len(surfaces)} surfaces")
        config_field(normal_neighbours, "normal_neighbours", int, minimum=3)
        config_field(grid_cell_m, "grid_cell_m", float, above=0)
        config_field(grid_reach_m, "grid_reach_m", float, above=0)
        pts = [finite_array(s, (None, 3), f"surface {names[k]!r}") for k, s in enumerate(surfaces)]
        for k, p in enumerate(pts):
            if len(p) < 3:
                raise InvalidInputError(f"object {names[k]!r} has {len(p)} stored contact points (need >= 3): map it with contacts")
            cells = np.prod(np.ceil((np.ptp(p, axis=0) + 2 * grid_reach_m) / grid_cell_m) + 1)
            if cells > _MAX_CELLS:
                raise InvalidInputError(f"object {names[k]!r} spans {np.ptp(p, axis=0).round(2).tolist()} m: its look-up table would "
                                        f"need {cells:.3g} cells (at most {_MAX_CELLS:g}); surfaces must be in metres, or use a "
                                        "larger grid_cell_m")
        self.names: tuple[str, ...] = tuple(names)
        self.points_m = np.concatenate(pts)
        self.normals = np.concatenate([_normals(p, normal_neighbours) for p in pts])
        self.point_object = np.repeat(np.arange(len(pts), dtype=np.int64), [len(p) for p in pts])
        self._grid = _NearestGrid(pts, grid_cell_m, grid_reach_m)

    @property
    def n_objects(self) -> int:
        """Number of objects."""
        return len(self.names)

    @classmethod
    def from_object_maps(cls, maps: Sequence[ObjectMap], names: Sequence[str], anchors: Sequence[Any],
                         normal_neighbours: int = 8) -> "SurfaceLibrary":
        """The library of object maps whose frames sit at ``anchors`` in the arm's frame.

        Parameters
        ----------
        maps : sequence of ObjectMap
            Maps that kept their contacts (:meth:`ObjectMap.record_contacts`).
        names : sequence of str
        anchors : sequence of array_like (7,)
            Pose of each map's frame (its first experience's frame: where the arm was when
            mapping began) in the arm's frame, ``(x, y, z m, qx, qy, qz, qw)``.
        """
        maps, anchors = list(maps), list(anchors)
        if len(maps) != len(anchors) or any(not isinstance(m, ObjectMap) for m in maps):
            raise InvalidInputError("need one ObjectMap and one anchor pose per object")
        return cls([_apply(_pose7(a, "anchor"), m.surface_points()) for m, a in zip(maps, anchors)], names, normal_neighbours)

    @classmethod
    def from_object_library(cls, library: ObjectLibrary, anchors: Sequence[Any], normal_neighbours: int = 8) -> "SurfaceLibrary":
        """The library of appended object maps (:func:`maps.object_library.append_object_maps`)."""
        if not isinstance(library, ObjectLibrary):
            raise InvalidInputError(f"library must be an ObjectLibrary, got {type(library).__name__}")
        anchors = list(anchors)
        if len(anchors) != len(library.names):
            raise InvalidInputError(f"need one anchor per object ({len(library.names)}), got {len(anchors)}")
        om = library.object_map
        obj = library.exp_object[om.contact_experiences]
        world = om.surface_points()
        parts = [_apply(_pose7(a, "anchor"), world[obj == k]) for k, a in enumerate(anchors)]
        return cls(parts, library.names, normal_neighbours)

    def nearest(self, points_m: np.ndarray, objects: np.ndarray, gate_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Nearest stored point of the given object for each point.

        Parameters
        ----------
        points_m : ndarray (n, 3)
        objects : ndarray (n,) int
            Object whose surface each point is matched to.
        gate_m : float
            Largest distance searched.

        Returns
        -------
        (distance_m, index) : ndarray (n,) each
            Euclidean distance (inf beyond the gate) and the stored point's index
            (``len(points_m)`` of the library beyond the gate).
        """
        return self._grid.nearest(np.asarray(points_m, dtype=np.float64), np.asarray(objects), float(gate_m), self.points_m)

    def residuals(self, points_m: Any, config: SurfaceMatchConfig = SurfaceMatchConfig()) -> np.ndarray:
        """Each object's RMS residual of fixed points (no registration), (n_objects,) m.

        A point's residual on object ``k`` is the point-to-plane distance to ``k``'s
        nearest stored point within ``config.gate_m`` (``cap_m`` if none), capped at
        ``cap_m`` (module docstring, item 4).

        Raises
        ------
        ShapeError, InvalidInputError
            Not a non-empty (n, 3) array of finite numbers.
        """
        p = finite_array(points_m, (None, 3), "points_m")
        if len(p) == 0:
            raise InvalidInputError("residuals need at least one point")
        K = self.n_objects
        x = np.broadcast_to(p, (K, len(p), 3))
        r = self._point_residuals(x, config)
        return np.sqrt(np.mean(r**2, axis=1))

    def _point_residuals(self, x: np.ndarray, cfg: SurfaceMatchConfig) -> np.ndarray:
        """(K, m) capped point-to-plane residuals of points x (K, m, 3), point set k on object k."""
        K, m = x.shape[:2]
        obj = np.repeat(np.arange(K), m)
        d, i = self.nearest(x.reshape(-1, 3), obj, cfg.gate_m)
        ok = np.isfinite(d)
        r = np.full(K * m, cfg.cap_m)
        ii = i[ok]
        r[ok] = np.abs(np.einsum("ij,ij->i", self.normals[ii], x.reshape(-1, 3)[ok] - self.points_m[ii]))
        return np.minimum(r, cfg.cap_m).reshape(K, m)


class _Corrections:
    """Rigid corrections ``x' = R x + t`` of K pose hypotheses, tracked with their covariance.

    The state of each is the correction and the covariance ``P`` (6 x 6, rotation vector
    then translation, about the registered points' centroid) of its error; ``P`` grows by
    ``Q`` per whisk and shrinks to the Gauss-Newton posterior after a registration
    (module docstring, item 3).
    """

    def __init__(self, k: int, cfg: SurfaceMatchConfig) -> None:
        self.R = np.tile(np.eye(3), (k, 1, 1))
        self.t = np.zeros((k, 3))
        r0, t0 = math.radians(cfg.initial_sigma_deg) ** 2, cfg.initial_sigma_m**2
        self.P = np.tile(np.diag([r0, r0, r0, t0, t0, t0]), (k, 1, 1))
        rq, tq = math.radians(cfg.step_sigma_deg) ** 2, cfg.step_sigma_m**2
        self.Q = np.diag([rq, rq, rq, tq, tq, tq])
        self.since = 0  # whisks since the last registration

    def register(self, world: np.ndarray, nearest: Any, points: np.ndarray, normals: np.ndarray,
                 cfg: SurfaceMatchConfig) -> tuple[np.ndarray, np.ndarray]:
        """Register ``world`` (m, 3) to each hypothesis' surface; the registered points (K, m, 3)
        and the Mahalanobis norm of each correction's change (K,).

        ``nearest(x (n, 3), obj (n,))`` returns the distance (inf beyond the gate) and the
        index into ``points`` / ``normals`` of the nearest stored point of object ``obj``.
        """
        K, m = len(self.R), len(world)
        x = np.einsum("kij,mj->kmi", self.R, world) + self.t[:, None, :]
        info = np.linalg.inv(self.P + self.Q * max(self.since, 1))  # prior information of this whisk's increment
        xi = np.zeros((K, 6))  # this whisk's accumulated increment (rotation vector, translation)
        w_data = 1.0 / cfg.contact_sigma_m**2
        obj = np.repeat(np.arange(K), m)
        H = info
        for _ in range(cfg.icp_iterations):
            d, i = nearest(x.reshape(-1, 3), obj)
            ok = np.isfinite(d)
            ii = np.where(ok, i, 0)
            nrm = normals[ii].reshape(K, m, 3)
            c = x.mean(axis=1, keepdims=True)
            e = np.einsum("kmi,kmi->km", nrm, x - points[ii].reshape(K, m, 3))
            w = ok.reshape(K, m) * w_data / (1.0 + (e / cfg.cap_m) ** 2)  # robust (Cauchy) weights
            J = np.concatenate([np.cross(x - c, nrm), nrm], axis=2)  # (K, m, 6)
            Jw = J * w[:, :, None]
            H = np.einsum("kmi,kmj->kij", Jw, J) + info
            g = np.einsum("kmi,km->ki", Jw, e) + np.einsum("kij,kj->ki", info, xi)
            delta = -np.linalg.solve(H, g[:, :, None])[:, :, 0]
            xi += delta
            Rd = Rotation.from_rotvec(delta[:, :3]).as_matrix()  # (K, 3, 3)
            cc = c[:, 0, :]
            x = np.einsum("kij,kmj->kmi", Rd, x - c) + c + delta[:, None, 3:]
            self.R = np.einsum("kij,kjl->kil", Rd, self.R)
            self.t = np.einsum("kij,kj->ki", Rd, self.t - cc) + cc + delta[:, 3:]
        self.P = np.linalg.inv(H)
        self.since = 0
        return x, np.einsum("ki,kij,kj->k", xi, info, xi)

    def correct(self, pose: np.ndarray, k: int = 0) -> np.ndarray:
        """Hypothesis ``k``'s correction applied to a pose (7,)."""
        pos = self.R[k] @ pose[:3] + self.t[k]
        q = (Rotation.from_matrix(self.R[k]) * Rotation.from_quat(pose[3:])).as_quat()
        return np.concatenate([pos, q])


class SurfaceMatcher:
    """Per-whisk impulses from registering the whisk to every library object (module docstring).

    Parameters
    ----------
    library : SurfaceLibrary
    start_pose : array_like (7,)
        The arm's end-effector pose at the first whisk, in the library's frame.
    config : SurfaceMatchConfig

    Attributes
    ----------
    evidence_m : ndarray (n_objects,)
        RMS residual per object over the window (inf before any registered whisk).
    last_scores_m : ndarray (n_objects,)
        RMS residual per object of the last registered whisk.
    window_contacts : int
        Contacts in the evidence window.
    """

    def __init__(self, library: SurfaceLibrary, start_pose: Any, config: SurfaceMatchConfig = SurfaceMatchConfig()) -> None:
        if not isinstance(library, SurfaceLibrary):
            raise InvalidInputError(f"library must be a SurfaceLibrary, got {type(library).__name__}")
        if not isinstance(config, SurfaceMatchConfig):
            raise InvalidInputError(f"config must be a SurfaceMatchConfig, got {type(config).__name__}")
        self.library, self.config = library, config
        self._geometry = SE3Geometry()
        self._pose = list(_pose7(start_pose, "start_pose"))
        K = library.n_objects
        self._corr = _Corrections(K, config)
        self._window: list[tuple[np.ndarray, int]] = []  # (sum of squared residuals (K,), n contacts)
        self.evidence_m = np.full(K, np.inf)
        self.last_scores_m = np.full(K, np.inf)
        self.window_contacts = 0

    @property
    def pose(self) -> np.ndarray:
        """The dead-reckoned end-effector pose (7,) of the last whisk."""
        return np.array(self._pose)

    @property
    def corrected_poses(self) -> np.ndarray:
        """The pose hypothesis corrected for each object, (n_objects, 7)."""
        p = np.asarray(self._pose)
        return np.stack([self._corr.correct(p, k) for k in range(self.library.n_objects)])

    def step(self, odometry: SpatialOdometry | None, contact_points_m: Any) -> np.ndarray:
        """One whisk: move the hypothesis by ``odometry``, register its contacts, return the impulses.

        Parameters
        ----------
        odometry : SpatialOdometry or None
            Body-frame motion since the previous whisk (Eq 5.7); None for none (the first
            whisk, at the start pose).
        contact_points_m : array_like (k, 3) or None
            The whisk's contacts in the end-effector frame, m (None or fewer than
            ``min_contacts``: dead reckoning only).

        Returns
        -------
        ndarray (n_objects,) bool
            The impulse per object (at most one True).

        Raises
        ------
        InvalidInputError, ShapeError
            Odometry that is not a SpatialOdometry, malformed contact points.
        """
        if odometry is not None:
            if not isinstance(odometry, SpatialOdometry):
                raise InvalidInputError(f"odometry must be a SpatialOdometry or None, got {type(odometry).__name__}")
        pts = None if contact_points_m is None else finite_array(contact_points_m, (None, 3), "contact_points_m")
        if odometry is not None:
            self._geometry.accumulate(self._pose, odometry)
            self._corr.since += 1
        K, cfg = self.library.n_objects, self.config
        impulses = np.zeros(K, dtype=bool)
        if pts is None or len(pts) < cfg.min_contacts:
            return impulses
        lib = self.library
        x, motion = self._corr.register(_apply(np.asarray(self._pose), pts),
                                        lambda q, o: lib.nearest(q, o, cfg.gate_m), lib.points_m, lib.normals, cfg)
        r = lib._point_residuals(x, cfg)
        sq = np.sum(r**2, axis=1) + cfg.motion_weight * cfg.contact_sigma_m**2 * motion
        self.last_scores_m = np.sqrt(sq / len(pts))
        self._window.append((sq, len(pts)))
        if len(self._window) > cfg.window_whisks:
            self._window.pop(0)
        n = self.window_contacts = sum(c for _, c in self._window)
        self.evidence_m = np.sqrt(sum(s for s, _ in self._window) / n)
        if n >= cfg.min_window_contacts:
            order = np.argsort(self.evidence_m)
            best = int(order[0])
            second = self.evidence_m[order[1]] if K > 1 else np.inf
            if self.evidence_m[best] <= cfg.tolerance_m and self.evidence_m[best] <= cfg.ratio * second:
                impulses[best] = True
        return impulses


@dataclass(frozen=True)
class ToleranceCalibration:
    """A tolerance from same-object and different-object evidence samples.

    Attributes
    ----------
    tolerance_m : float
        The ``quantile`` of the same-object evidence.
    quantile : float
    same_median_m, different_median_m : float
        Medians of the two samples.
    different_below : float
        Fraction of the different-object evidence at or under the tolerance.
    n_same, n_different : int
    """

    tolerance_m: float
    quantile: float
    same_median_m: float
    different_median_m: float
    different_below: float
    n_same: int
    n_different: int


def calibrate_tolerance(same_m: Any, different_m: Any, quantile: float = 0.9) -> ToleranceCalibration:
    """The impulse tolerance: a quantile of the evidence of the right object (module docstring, item 5).

    Parameters
    ----------
    same_m : array_like (n,)
        Evidence (m) of the presented object's own surface, one value per whisk (finite).
    different_m : array_like (n',)
        Evidence of the other objects' surfaces (or of a novel object on the library).
    quantile : float
        In (0, 1).

    Raises
    ------
    InvalidInputError, ShapeError
        Empty or non-finite samples, negative values, a quantile outside (0, 1).
    """
    s = finite_array(same_m, (None,), "same_m")
    d = finite_array(different_m, (None,), "different_m")
    if len(s) == 0 or len(d) == 0:
        raise InvalidInputError("calibrate_tolerance needs at least one same-object and one different-object value")
    if s.min() < 0 or d.min() < 0:
        raise InvalidInputError("evidence values are residuals, >= 0 m")
    if isinstance(quantile, bool) or not isinstance(quantile, (int, float)) or not 0.0 < quantile < 1.0:
        raise InvalidInputError(f"quantile must be a number in (0, 1), got {quantile!r}")
    tol = float(np.quantile(s, quantile))
    return ToleranceCalibration(tol, float(quantile), float(np.median(s)), float(np.median(d)),
                                float(np.mean(d <= tol)), len(s), len(d))
