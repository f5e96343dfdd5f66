"""Implicit surfaces of stored contacts: a signed-distance grid per object (issue 22).

An object map keeps what its whiskers felt: contact points a few centimetres apart
(2 loops of trajectory A leave a median 13-21 mm between a contact felt along trajectory
B and the nearest stored one). A new contact between stored ones lies on the object but
far from any stored point, so a nearest-point residual calls it off the surface. This
module interpolates the surface between the contacts instead:

1. **Normals.** Each stored point's normal is the least principal axis of its
   ``normal_neighbours`` nearest stored points, turned towards the place it was felt
   from (the end-effector position of its whisk, ``viewpoints_m``: the arm is always
   outside the object), so that all normals point out of the object.
2. **Implicit moving least squares** (IMLS, Kolluri 2008): the signed distance of a
   point ``x`` is the Gaussian-weighted mean of its distances to the tangent planes of
   its ``neighbours`` nearest stored points,
   ``f(x) = sum_i w_i (x - p_i) . n_i / sum_i w_i``, ``w_i = exp(-|x - p_i|^2 / h^2)``
   with ``h = smoothing_m``. On the stored points ``f`` is their noise averaged over
   ``h``; between them it blends the neighbouring tangent planes.
3. **Grid.** ``f`` is tabulated once on a regular grid (``cell_m``) over each object's
   stored points plus ``reach_m``, clipped to ``+-cap_m``; cells whose nearest stored
   point is farther than ``2 h`` hold ``cap_m`` (no stored surface there). A query
   interpolates the grid trilinearly and returns ``|f|``, the distance to the surface
   (``cap_m`` outside the grid).

Measured (12-object library of the recognition study, seed 0, contacts felt along B at
their true poses, maps of 2 loops of A with contacts placed at the true poses): the own
object's field reads a median 2.2-2.3 mm at the Mug, Kettle and Blob (the duck, with 110
stored contacts, 7.3 mm) against 11-17 mm on the nearest other objects; the nearest
stored point is a median 14-16 mm away.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from whisker_io.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, finite_array, validate_fields

__all__ = ["MAX_CELLS", "SurfaceFieldConfig", "SurfaceFields", "grid_cells", "oriented_normals"]

#: Largest grid of one object (cells).
MAX_CELLS = 4_000_000


@dataclass(frozen=True)
class SurfaceFieldConfig(ConfigDataclass):
    """Parameters of the stored surfaces' signed-distance grids (module docstring).

    Parameters
    ----------
    cell_m : float
        Grid spacing, m.
    smoothing_m : float
        Width ``h`` of the Gaussian weights of the IMLS blend, m.
    reach_m : float
        Margin of the grid around the stored points, m.
    cap_m : float
        Largest distance the grid holds (and the distance outside it), m.
    neighbours : int
        Stored points blended per grid cell (>= 1).
    normal_neighbours : int
        Stored points whose principal axes give a stored point's normal (>= 3).
    """

    cell_m: float = checked(0.0075, float, above=0, maximum=10.0)
    smoothing_m: float = checked(0.015, float, above=0, maximum=10.0)
    reach_m: float = checked(0.05, float, above=0, maximum=10.0)
    cap_m: float = checked(0.03, float, above=0, maximum=10.0)
    neighbours: int = checked(16, int, minimum=1, maximum=256)
    normal_neighbours: int = checked(8, int, minimum=3, maximum=256)

    def __post_init__(self) -> None:
        validate_fields(self)


def oriented_normals(points_m: np.ndarray, viewpoints_m: np.ndarray | None, neighbours: int) -> np.ndarray:
    """Unit normals (n, 3) of stored points, all pointing out of the object.

    Parameters
    ----------
    points_m : ndarray (n, 3)
        Stored contact points, m.
    viewpoints_m : ndarray (n, 3) or None
        The end-effector position each point was felt from, m: each normal is turned
        towards its viewpoint. None: the orientation is propagated over the points'
        nearest-neighbour graph (Hoppe et al. 1992), each connected part starting from its
        point farthest from the centroid, turned away from the centroid.
    neighbours : int
        Points of each principal-axes fit (at least 3; fewer points: all of them).

    Returns
    -------
    ndarray (n, 3)
        The least principal axis of each point's nearest points, signed.
    """
    n = len(points_m)
    if n < 3:
        return np.tile([0.0, 0.0, 1.0], (n, 1))
    _, idx = cKDTree(points_m).query(points_m, k=min(neighbours, n))
    nb = points_m[idx]
    d = nb - nb.mean(axis=1, keepdims=True)
    _, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", d, d))
    normals = vec[:, :, 0].copy()
    if viewpoints_m is not None:
        normals[np.einsum("ij,ij->i", normals, viewpoints_m - points_m) < 0] *= -1.0
        return normals
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    graph = csr_matrix((np.ones(idx.size), (np.repeat(np.arange(n), idx.shape[1]), idx.ravel())), shape=(n, n))
    centroid = points_m.mean(axis=0)
    _, labels = connected_components(graph, directed=False)
    for part in np.unique(labels):
        members = np.flatnonzero(labels == part)
        seed = int(members[np.argmax(np.linalg.norm(points_m[members] - centroid, axis=1))])
        if normals[seed] @ (points_m[seed] - centroid) < 0:
            normals[seed] *= -1.0
        order, pred = breadth_first_order(graph, seed, directed=False)
        for i in order[1:]:
            if normals[i] @ normals[pred[i]] < 0:
                normals[i] *= -1.0
    return normals


def _grid_extent(points: np.ndarray, cfg: SurfaceFieldConfig) -> tuple[np.ndarray, np.ndarray]:
    """First cell centre (3,) m and cells per axis (3,) of the grid over ``points`` plus ``reach_m``."""
    lo = points.min(axis=0) - cfg.reach_m
    return lo, np.ceil((points.max(axis=0) + cfg.reach_m - lo) / cfg.cell_m).astype(np.int64) + 1


def grid_cells(points_m: np.ndarray, config: SurfaceFieldConfig = SurfaceFieldConfig()) -> int:
    """Cells of the signed-distance grid over stored points (n, 3), m: their box plus ``reach_m``, at ``cell_m``.

    :class:`SurfaceFields` refuses a surface whose grid exceeds :data:`MAX_CELLS`; a
    caller can ask before mapping, with the box an object's surface may fill.
    """
    pts = finite_array(points_m, (None, 3), "points_m")
    if not len(pts):
        raise InvalidInputError("points_m needs at least one point (n, 3), m")
    return int(np.prod(_grid_extent(pts, config)[1].astype(float)))  # in floats: no int64 overflow on a span in km


def _imls_grid(points: np.ndarray, normals: np.ndarray, cfg: SurfaceFieldConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lo (3,), shape (3,) int, values (prod(shape),)) of one object's clipped signed distance."""
    lo, shape = _grid_extent(points, cfg)
    axes = [lo[i] + cfg.cell_m * np.arange(shape[i]) for i in range(3)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    h = cfg.smoothing_m
    tree = cKDTree(points)
    values = np.full(len(centres), cfg.cap_m)
    near_d, _ = tree.query(centres, k=1, distance_upper_bound=2.0 * h)
    near = np.flatnonzero(np.isfinite(near_d))
    k = min(cfg.neighbours, len(points))
    for chunk in np.array_split(near, max(1, len(near) // 200_000 + 1)):
        x = centres[chunk]
        d, idx = tree.query(x, k=k, distance_upper_bound=3.0 * h)
        d, idx = d.reshape(len(x), k), idx.reshape(len(x), k)
        ok = np.isfinite(d)
        idx = np.where(ok, idx, 0)
        w = np.where(ok, np.exp(-(np.where(ok, d, 0.0) / h) ** 2), 0.0)
        signed = np.einsum("nkj,nkj->nk", x[:, None, :] - points[idx], normals[idx])
        values[chunk] = np.sum(w * signed, axis=1) / np.maximum(np.sum(w, axis=1), 1e-300)
    return lo, shape, np.clip(values, -cfg.cap_m, cfg.cap_m)


class SurfaceFields:
    """The signed-distance grids of several objects' stored contacts, in one flat table.

    Parameters
    ----------
    surfaces_m : sequence of ndarray (n_k, 3)
        Each object's stored points, m (finite, at least 3 each).
    viewpoints_m : sequence of (ndarray (n_k, 3) or None), optional
        Where each point was felt from (normals point there); None for an object (or for
        all): orientation propagated between neighbours (:func:`oriented_normals`).
    config : SurfaceFieldConfig

    Attributes
    ----------
    lo : ndarray (K, 3)
        Each grid's first cell centre, m.
    shape : ndarray (K, 3) int64
    start : ndarray (K,) int64
        Offset of each grid in ``values``.
    values : ndarray (sum of cells,)
        Signed distance at the cell centres (C order per grid), m, in ``[-cap_m, cap_m]``.
    normals : list of ndarray (n_k, 3)
        The stored points' oriented normals.

    Raises
    ------
    InvalidInputError, ShapeError
        Malformed points or viewpoints, fewer than 3 points, a grid over
        :data:`MAX_CELLS` cells (surfaces not in metres).
    """

    def __init__(self, surfaces_m: Sequence[Any], viewpoints_m: Sequence[Any] | None = None,
                 config: SurfaceFieldConfig = SurfaceFieldConfig()) -> None:
        if not isinstance(config, SurfaceFieldConfig):
            raise InvalidInputError(f"config must be a SurfaceFieldConfig, got {type(config).__name__}")
        surfaces = [finite_array(s, (None, 3), f"surface {k}") for k, s in enumerate(surfaces_m)]
        views = list(viewpoints_m) if viewpoints_m is not None else [None] * len(surfaces)
        if len(views) != len(surfaces):
            raise InvalidInputError(f"need one viewpoint array (or None) per surface ({len(surfaces)}), got {len(views)}")
        self.config = config
        lo, shape, start, values, self.normals = [], [], [], [], []
        offset = 0
        for k, (pts, vp) in enumerate(zip(surfaces, views)):
            if len(pts) < 3:
                raise InvalidInputError(f"surface {k} has {len(pts)} stored points (need >= 3): map it with contacts")
            cells = grid_cells(pts, config)
            if cells > MAX_CELLS:
                raise InvalidInputError(f"surface {k} spans {np.ptp(pts, axis=0).round(2).tolist()} m: its grid would need "
                                        f"{cells:.3g} cells (at most {MAX_CELLS:g}); surfaces must be in metres, or use a "
                                        "larger cell_m")
            v = None if vp is None else finite_array(vp, (len(pts), 3), f"viewpoints {k}")
            normals = oriented_normals(pts, v, config.normal_neighbours)
            a, n, f = _imls_grid(pts, normals, config)
            lo.append(a), shape.append(n), start.append(offset), values.append(f), self.normals.append(normals)
            offset += len(f)
        self.lo = np.array(lo, dtype=np.float64).reshape(-1, 3)
        self.shape = np.array(shape, dtype=np.int64).reshape(-1, 3)
        self.start = np.array(start, dtype=np.int64)
        self.values = np.concatenate(values) if values else np.zeros(0)

    @property
    def n_objects(self) -> int:
        """Number of objects."""
        return len(self.start)

    def distance(self, points_m: Any, objects: Any) -> np.ndarray:
        """Distance (m) of each point to its object's stored surface, (n,): ``|f|`` interpolated, ``cap_m`` off the grid.

        Parameters
        ----------
        points_m : array_like (n, 3)
        objects : array_like (n,) int
            The object each point is measured against.
        """
        x = finite_array(points_m, (None, 3), "points_m")
        obj = np.asarray(objects)
        if obj.shape != (len(x),) or not np.issubdtype(obj.dtype, np.integer) or (len(obj) and (obj.min() < 0 or obj.max() >= self.n_objects)):
            raise InvalidInputError(f"objects must be {len(x)} object indices in [0, {self.n_objects})")
        from maps import _surface_numba

        return _surface_numba.field_distance(x, obj.astype(np.int64), self.lo, self.shape, self.start, self.values,
                                             self.config.cell_m, self.config.cap_m)
