"""Region-search strategies of active exploration (thesis Sec 6.1.2; Eq 6.1-6.3).

Every strategy proposes the next end-effector goal (world frame) from a
:class:`SearchContext`; the surface placement controller then adjusts it.

* :class:`DefaultSearch` - visit the faces of a sphere mesh around the object (an
  icosphere scaled to the sphere through the object's bounding-box corners): the seed
  picks the start face, then the closest unvisited face; the array faces the centre
  with its whisker bases on the sphere. With ``semi_axes_m`` the mesh is the icosphere
  scaled to an ellipsoid (the one fitted to the object,
  :func:`whisker_io.sim.trajectories.fit_surface`): the faces over which the object
  maps are built (Sec 6.1.3.1), :meth:`DefaultSearch.tour`. With ``mesh`` (the volume
  the object is believed to occupy, e.g. its bounding box) the array comes in along
  each face direction until the nearest point of its ``footprint_m`` (the whisker
  bases) is ``clearance_m`` before that volume, so no base is put inside it.
* :class:`FollowExperienceHistory` (FEH) - after a re-localisation to experience ``e``
  of object ``k``'s map, target the experience that followed ``e`` in the map's stored
  (mapping) history; map poses (relaxed) are carried into the world through the
  current experience (``T_world_target = T_world_now T_map_current^-1 T_map_target``),
  the motion is flattened to the world horizontal plane and taken in 3-cm steps. A
  target reached (horizontally within one step) hands on to the experience that
  followed it in the history, so the array plays the mapping run back until the next
  re-localisation re-anchors it. With ``along_surface`` (default) the step has no
  part along the array's axis (its horizontal projection): the array moves across
  the surface and the SPC alone sets its distance; otherwise a horizontal step toward
  a target above or round the object drives the array into it.
* :class:`LeastSimilarRegion` (LSR) - the Eq 6.1-6.2 similarity of the current region
  against the regions of every candidate object (non-zero confidence): rows
  ``(chi2, NMSE)`` sorted lexicographically (chi2, then NMSE) in descending order, the
  first row is the least similar region; among that object's experiences holding it,
  the one with the cheapest Dijkstra path (networkx, Eq 6.3 ``w = w_t + w_r + 1/n_l``)
  from the experience of that map most recently re-localised to (the nearest by map
  pose when none). The object maps are not linked to each other. The array follows that
  path experience by experience (3-cm steps toward the next one not yet reached, within
  one step), i.e. along the map round the object, and re-targets at its end; with
  ``along_surface`` (default) a step has no part along the array's axis, as FEH's.

Switching (:func:`active_strategy`): the default search while every confidence is zero
or contact is lost; the chosen strategy once a confidence rises; LSR re-targets when
another identity overtakes the leader.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import trimesh
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation, Slerp

from cansim.errors import ConfigError, InvalidInputError
from cansim.explore.placement import maintain_yaw
from whisker_io.pose import Pose
from whisker_io.validation import config_field, finite_array, finite_vector

__all__ = [
    "STRATEGIES",
    "ObjectView",
    "SearchContext",
    "DefaultSearch",
    "FollowExperienceHistory",
    "LeastSimilarRegion",
    "similarity_rows",
    "cheapest_experience",
    "cheapest_path",
    "active_strategy",
    "make_strategy",
]

STRATEGIES = ("default", "feh", "lsr")

#: largest length :class:`DefaultSearch` takes (radius, standoff, clearance, semi-axes), m: the
#: search surrounds an object within an arm's reach; lengths near 1e154 m overflow the norms
MAX_SEARCH_M = 20.0  # as whisker_io.sim.objects.MAX_SCENE_M: a radius of 1,000 is a believed volume in millimetres
#: smallest ellipsoid semi-axis, m (the face directions divide by the semi-axes)
MIN_SEMI_AXIS_M = 1.0e-6
#: most icosphere subdivisions of :class:`DefaultSearch` (20 * 4**6 = 81,920 faces)
MAX_SUBDIVISIONS = 6


@dataclass
class ObjectView:
    """What a strategy reads of one known object's model.

    Attributes
    ----------
    object_map : maps.object_map.ObjectMap
        The object's map (poses (n, 7) x, y, z, qx, qy, qz, qw; ``graph``; ``view_ids``).
    frontend : cansim.frontends.whisk.WhiskFrontEnd
        Its stored regions (for Eq 6.1-6.2).
    n_built : int
        Experiences of the built map (later ones are the unknown object's own).
    n_built_regions : int
        Regions stored while mapping.
    n_history : int
        Length of the stored (mapping) experience history.
    last_relocalised : int or None
        The built experience most recently re-localised to during exploration.
    """

    object_map: object
    frontend: object
    n_built: int
    n_built_regions: int
    n_history: int
    last_relocalised: int | None = None


@dataclass
class SearchContext:
    """Input of one proposal.

    Attributes
    ----------
    pose : Pose
        Current end-effector pose (world).
    objects : list of ObjectView
    confidence : ndarray (n_objects,)
        Raw confidence per object.
    observation : RegionFeatures or None
        This whisk's region (None: no observation).
    relocalised : list of (int, int)
        ``(object, experience)`` re-localisations of this whisk.
    """

    pose: Pose
    objects: list[ObjectView]
    confidence: np.ndarray
    observation: object | None = None
    relocalised: list[tuple[int, int]] = field(default_factory=list)


def _map_pose(om: object, i: int) -> Pose:
    row = np.asarray(om.poses[i], dtype=float)  # type: ignore[attr-defined]
    return Pose(row[:3], row[3:] / np.linalg.norm(row[3:]))


def _world_of(ctx: SearchContext, k: int, exp: int) -> Pose:
    """World pose of experience ``exp`` of object ``k`` via the current experience."""
    om = ctx.objects[k].object_map
    cur = _map_pose(om, int(om.current_id))  # type: ignore[attr-defined]
    return ctx.pose @ cur.inverse() @ _map_pose(om, exp)


def _offset(pose: Pose, target: Pose, flat: bool, along_surface: bool) -> np.ndarray:
    """The motion from ``pose`` to ``target`` a stepping strategy makes (m, world, (3,)).

    ``flat``: the world horizontal part. ``along_surface``: without the part along the
    array's axis y (its horizontal projection when ``flat``), i.e. no motion toward or
    away from the surface; the SPC (Alg 7) sets that distance.
    """
    d = target.position_m - pose.position_m
    if along_surface:
        y = pose.rotation.as_matrix()[:, 1].copy()
        if flat:
            y[2] = 0.0
        ny = float(np.linalg.norm(y))
        if ny > 1e-9:
            y = y / ny
            d = d - (d @ y) * y
    if flat:
        d = d.copy()
        d[2] = 0.0
    return d


def _step_towards(pose: Pose, target: Pose, step_m: float, flat: bool, along_surface: bool = False) -> Pose:
    d = _offset(pose, target, flat, along_surface)
    if flat:
        n = float(np.linalg.norm(d))
        return pose if n < 1e-12 else Pose.from_rotation(pose.position_m + d * min(1.0, step_m / n), pose.rotation)
    n = float(np.linalg.norm(d))
    f = 1.0 if n <= step_m else step_m / n
    rot = Slerp([0.0, 1.0], Rotation.concatenate([pose.rotation, target.rotation]))([f])[0]
    return Pose.from_rotation(pose.position_m + f * d, rot)


class DefaultSearch:
    """Faces of a sphere mesh around the object (see the module docstring).

    Parameters
    ----------
    centre_m : array_like (3,)
        Sphere centre (world), m.
    radius_m : float
        Sphere radius (through the object's bounding-box corners), m. With
        ``semi_axes_m`` only the start of the rays cast against ``mesh`` (``2 radius_m``
        out).
    standoff_m : float
        End-effector origin to whisker bases along y (the thesis array: 0.2019 m).
    seed : int
        Picks the start face.
    subdivisions : int
        Icosphere subdivisions (1: 80 faces).
    roll_rad : float
        Roll about y after Alg 8 (the trajectories' pi/2).
    mesh : trimesh.Trimesh, optional
        The volume the object is believed to occupy (e.g. its bounding box): the array
        comes in along the face direction until a point of ``footprint_m`` is
        ``clearance_m`` in front of the mesh (a sphere through the bounding-box corners
        leaves up to 12 cm of air before a Box face, beyond the reach of the 60-160 mm
        whiskers). Without it the bases sit on the sphere.
    clearance_m : float
        Gap in front of the mesh, m.
    footprint_m : array_like (k, 3), optional
        Points of the array (end-effector frame, m; e.g. the whisker bases,
        :attr:`whisker_io.array.geometry.WhiskerArray.positions_m`) that must all stay
        ``clearance_m`` in front of ``mesh``: a ray along the array's y-axis from each is
        cast and the nearest hit sets the distance, so no base is put inside the mesh.
        Default the single point ``(0, standoff_m, 0)`` (the ray from the face toward
        the centre).
    semi_axes_m : array_like (3,), optional
        An ellipsoid mesh instead of the sphere: the icosphere's vertices scaled by these
        semi-axes (world x, y, z, m); a face's direction is from the centre through its
        centroid and, without ``mesh``, the bases sit on the ellipsoid along it.

    Raises
    ------
    InvalidInputError, ConfigError
        A length outside (0, :data:`MAX_SEARCH_M`] m (a semi-axis below
        :data:`MIN_SEMI_AXIS_M`), ``subdivisions`` not an integer in
        [0, :data:`MAX_SUBDIVISIONS`], a ``seed`` that is not an integer >= 0 (or None).
    """

    name = "default"

    def __init__(self, centre_m: ArrayLike, radius_m: float, standoff_m: float = 0.2019, *, seed: int = 0,
                 subdivisions: int = 1, roll_rad: float = math.pi / 2, mesh: trimesh.Trimesh | None = None,
                 clearance_m: float = 0.015, semi_axes_m: ArrayLike | None = None,
                 footprint_m: ArrayLike | None = None) -> None:
        c = finite_vector(centre_m, 3, "centre_m")  # the one validator: rejects strings, NaN, wrong shapes
        for name, v in (("radius_m", radius_m), ("standoff_m", standoff_m)):
            config_field(v, name, float, above=0, maximum=MAX_SEARCH_M, hint="give metres (a larger number is millimetres)")
        config_field(clearance_m, "clearance_m", float, minimum=0, maximum=MAX_SEARCH_M, hint="give metres")
        axes = None if semi_axes_m is None else finite_vector(semi_axes_m, 3, "semi_axes_m")
        if axes is not None and not np.all((axes >= MIN_SEMI_AXIS_M) & (axes <= MAX_SEARCH_M)):
            raise InvalidInputError(
                f"semi_axes_m must be 3 numbers of metres in [{MIN_SEMI_AXIS_M:g}, {MAX_SEARCH_M:g}], got {semi_axes_m!r}"
            )
        config_field(subdivisions, "subdivisions", int, minimum=0, maximum=MAX_SUBDIVISIONS,
                     hint=f"an icosphere of {MAX_SUBDIVISIONS} subdivisions has {20 * 4 ** MAX_SUBDIVISIONS} faces")
        config_field(seed, "seed", int, minimum=0, optional=True)
        config_field(roll_rad, "roll_rad", float)
        if mesh is not None and not (isinstance(mesh, trimesh.Trimesh) and len(mesh.faces)):
            raise InvalidInputError(f"mesh must be a trimesh.Trimesh with faces (the believed volume), or None; got "
                                    f"{type(mesh).__name__}")
        sphere = trimesh.creation.icosphere(subdivisions=int(subdivisions))
        d = sphere.triangles_center if axes is None else (sphere.vertices * axes)[sphere.faces].mean(axis=1)
        self.directions = d / np.linalg.norm(d, axis=1, keepdims=True)
        self.centre_m, self.radius_m, self.standoff_m, self.roll_rad = c, float(radius_m), float(standoff_m), float(roll_rad)
        self.visited = np.zeros(len(self.directions), dtype=bool)
        self.current = int(np.random.default_rng(seed).integers(len(self.directions)))
        self._started = False
        if axes is None:
            self.distance_m = np.full(len(self.directions), self.radius_m)
        else:  # the ellipsoid's radius along each direction u: 1 / |u / a|
            self.distance_m = 1.0 / np.linalg.norm(self.directions / axes, axis=1)
        if footprint_m is None:
            foot = np.array([[0.0, self.standoff_m, 0.0]])
        else:
            foot = finite_array(footprint_m, (None, 3), "footprint_m (k points of the end-effector frame, m)")
            if len(foot) < 1 or np.abs(foot).max() > MAX_SEARCH_M:
                raise InvalidInputError(f"footprint_m must hold 1 or more points within {MAX_SEARCH_M:g} m, got shape {foot.shape}")
        if mesh is not None:
            self._clear(mesh, foot, float(clearance_m))

    def _clear(self, mesh: trimesh.Trimesh, foot: np.ndarray, clearance_m: float) -> None:
        """Bring each face's array in until a footprint point is ``clearance_m`` before ``mesh``."""
        far = 2.0 * self.radius_m
        k = len(foot)
        origins, dirs = [], []
        for f, u in enumerate(self.directions):
            p = self._pose_at(f, far)
            origins.append(p.apply(foot))
            dirs.append(np.repeat(-u[None], k, axis=0))
        o, d = np.concatenate(origins), np.concatenate(dirs)
        locs, rays, _ = mesh.ray.intersects_location(o, d, multiple_hits=False)
        advance = np.full(len(self.directions), np.inf)
        for loc, r in zip(locs, rays):
            f = int(r) // k
            advance[f] = min(advance[f], float(np.linalg.norm(loc - o[r])))
        hit = np.isfinite(advance)
        self.distance_m[hit] = far - advance[hit] + clearance_m

    def _pose_at(self, face: int, distance_m: float) -> Pose:
        u = self.directions[face]
        rot = maintain_yaw(-u) * Rotation.from_rotvec([0.0, self.roll_rad, 0.0])
        return Pose.from_rotation(self.centre_m + (distance_m + self.standoff_m) * u, rot)

    def face_pose(self, face: int) -> Pose:
        """End-effector pose facing the centre from face ``face``."""
        return self._pose_at(face, float(self.distance_m[face]))

    def next_face(self) -> int:
        """Mark the current face visited and return the closest unvisited one (all visited: start over)."""
        if not self._started:
            self._started = True
            return self.current
        self.visited[self.current] = True
        if self.visited.all():
            self.visited[:] = False
            self.visited[self.current] = True
        free = np.flatnonzero(~self.visited)
        dist = np.linalg.norm(self.directions[free] - self.directions[self.current], axis=1)
        self.current = int(free[np.argmin(dist)])
        return self.current

    def propose(self, ctx: SearchContext | None = None) -> Pose:
        """The pose of the next face."""
        return self.face_pose(self.next_face())

    def refused(self) -> None:
        """The last proposal was refused: it counts as visited."""
        self.visited[self.current] = True

    def tour(self, n_loops: int, accept: Callable[[Pose], bool] | None = None) -> list[Pose]:
        """The face poses of ``n_loops`` loops, each visiting every face once, closest unvisited first.

        The mapping run of Sec 6.1.3.1 over the ellipsoid's faces (the SPC then adjusts
        at each, :func:`cansim.explore.explorer.build_object_model`). Consecutive loops
        share the face where one ends and the next begins (as :meth:`next_face` does), so
        the tour is :meth:`next_face` ``n_faces + (n_loops - 1) (n_faces - 1)`` times;
        it advances this search.

        Parameters
        ----------
        n_loops : int
            Loops (>= 1).
        accept : callable, optional
            ``accept(pose) -> bool``; a face whose pose it rejects (e.g. outside the arm's
            safety envelope, under the table) is skipped.
        """
        if isinstance(n_loops, bool) or not isinstance(n_loops, (int, np.integer)) or n_loops < 1:
            raise InvalidInputError(f"n_loops must be an integer >= 1, got {n_loops!r}")
        n = len(self.directions)
        poses = [self.face_pose(self.next_face()) for _ in range(n + (int(n_loops) - 1) * (n - 1))]
        return [p for p in poses if accept is None or accept(p)]


def _step_and_reach(step_m: float, reach_m: float | None) -> tuple[float, float]:
    """Validated ``(step_m, reach_m)`` of a stepping strategy (``reach_m`` None: one step)."""
    reach = step_m if reach_m is None else reach_m
    for name, v in (("step_m", step_m), ("reach_m", reach)):
        config_field(v, name, float, above=0, hint="give metres")
    return float(step_m), float(reach)


class FollowExperienceHistory:
    """FEH (see the module docstring).

    Parameters
    ----------
    step_m : float
        Largest horizontal step (3 cm).
    reach_m : float
        A target is reached when the horizontal distance to it is below this (default
        one step: the SPC's own corrections between two steps move the array by up to
        about as much); the history is then played on: the next target is the experience
        that followed the reached one in the stored history. Without this the array
        stands at a reached target, whisking the same place, until a re-localisation
        (measured on the Box: 52 of 122 proposals within 5 mm of one target).
    along_surface : bool
        Drop the part of each step (and of the distance to a target) along the array's
        axis, projected on the horizontal (default True; module docstring). Without it
        the array met the mapped object with a whisker base inside it in 39-47 % of the
        FEH whisks (Box and Box-Stack, ``examples/ch6_active_exploration.py``).
    """

    name = "feh"

    def __init__(self, step_m: float = 0.03, reach_m: float | None = None, along_surface: bool = True) -> None:
        self.step_m, self.reach_m = _step_and_reach(step_m, reach_m)
        self.along_surface = bool(config_field(along_surface, "along_surface", bool))
        self.target: tuple[int, int] | None = None
        self._index: int | None = None  # history index of the target's visit being played back

    @staticmethod
    def following(history: np.ndarray, index: int) -> tuple[int, int] | None:
        """``(experience, index)`` of the first entry after ``index`` that differs from ``history[index]`` (None at the end)."""
        h = np.asarray(history)
        after = np.flatnonzero((h[index + 1:] != h[index]) & (h[index + 1:] >= 0))
        if not after.size:
            return None
        j = index + 1 + int(after[0])
        return int(h[j]), j

    @staticmethod
    def next_in_history(history: np.ndarray, exp: int) -> int | None:
        """The experience following the first visit of ``exp`` in ``history`` (None at its end)."""
        idx = np.flatnonzero(np.asarray(history) == exp)
        nxt = FollowExperienceHistory.following(history, int(idx[0])) if idx.size else None
        return None if nxt is None else nxt[0]

    def propose(self, ctx: SearchContext) -> Pose | None:
        """A 3-cm horizontal step toward the target; None when there is none."""
        if ctx.relocalised:
            k, e = max(ctx.relocalised, key=lambda ke: (ctx.confidence[ke[0]], -ke[0]))
            h = ctx.objects[k].object_map.history[: ctx.objects[k].n_history]  # type: ignore[attr-defined]
            idx = np.flatnonzero(h == e)
            nxt = self.following(h, int(idx[0])) if idx.size else None
            if nxt is not None:
                self.target, self._index = (k, nxt[0]), nxt[1]
        if self.target is None:
            return None
        k, e = self.target
        goal = _world_of(ctx, k, e)
        if float(np.linalg.norm(_offset(ctx.pose, goal, True, self.along_surface))) < self.reach_m:  # reached: play on
            h = ctx.objects[k].object_map.history[: ctx.objects[k].n_history]  # type: ignore[attr-defined]
            nxt = self.following(h, int(self._index)) if self._index is not None else None
            if nxt is None:
                self.target = self._index = None
                return None
            self.target, self._index = (k, nxt[0]), nxt[1]
            goal = _world_of(ctx, k, nxt[0])
        return _step_towards(ctx.pose, goal, self.step_m, flat=True, along_surface=self.along_surface)

    def refused(self) -> None:
        """Drop the target after a refused command."""
        self.target = self._index = None


def similarity_rows(ctx: SearchContext, candidates: list[int]) -> np.ndarray:
    """Eq 6.1-6.2 rows ``(object, region, chi2, nmse)`` of the current region, least similar first.

    Sorted lexicographically by chi2 then NMSE, descending; regions of the built maps only.
    """
    rows = []
    for k in candidates:
        ov = ctx.objects[k]
        fe = ov.frontend
        f, s, m = fe.parse(ctx.observation)  # type: ignore[attr-defined]
        sc = fe.scores(f, s, m)  # type: ignore[attr-defined]
        n = min(ov.n_built_regions, len(sc.chi2))
        for r in range(n):
            rows.append((k, r, float(sc.chi2[r]), float(sc.nmse[r])))
    if not rows:
        return np.zeros((0, 4))
    a = np.array(rows, dtype=float)
    order = np.lexsort((a[:, 3], a[:, 2]))[::-1]
    return a[order]


def cheapest_path(graph: object, source: int, targets: list[int]) -> tuple[int, float, list[int]] | None:
    """The target with the cheapest Dijkstra path from ``source`` (Eq 6.3 ``weight``): ``(target, cost, path)``.

    ``path`` runs from ``source`` to the target, both included; None when no target is reachable.
    """
    import networkx as nx

    dist, paths = nx.single_source_dijkstra(graph, source, weight="weight")
    reach = [(float(dist[t]), t) for t in targets if t in dist]
    if not reach:
        return None
    cost, t = min(reach)
    return int(t), cost, [int(n) for n in paths[t]]


def cheapest_experience(graph: object, source: int, targets: list[int]) -> tuple[int, float] | None:
    """The target with the cheapest Dijkstra path from ``source`` (Eq 6.3 ``weight``), with its cost."""
    best = cheapest_path(graph, source, targets)
    return None if best is None else best[:2]


class LeastSimilarRegion:
    """LSR (see the module docstring).

    Parameters
    ----------
    step_m : float
        Largest step toward the next experience of the path (3 cm).
    reach_m : float
        An experience of the path is reached within this distance (default one step,
        as :class:`FollowExperienceHistory`); the array then heads for the next one.
        The array follows the Dijkstra path experience by experience (the path of
        the map, round the object) rather than the straight line to the target,
        which runs through the object: measured on the Box, straight-line targets lay
        0.4-0.6 m away, on the far side, and none was reached in 300 whisks, the SPC
        holding the array against the near face.
    along_surface : bool
        Drop the part of each step (and of the distance to an experience) along the
        array's axis (default True; as :class:`FollowExperienceHistory`).
    """

    name = "lsr"

    def __init__(self, step_m: float = 0.03, reach_m: float | None = None, along_surface: bool = True) -> None:
        self.step_m, self.reach_m = _step_and_reach(step_m, reach_m)
        self.along_surface = bool(config_field(along_surface, "along_surface", bool))
        self.target: tuple[int, int] | None = None
        self.path: list[int] = []  # experiences still to visit on the way to the target (target last)
        self.leader: int | None = None
        self.last_cost: float | None = None

    def choose_target(self, ctx: SearchContext) -> tuple[int, int] | None:
        """(object, experience) of the least similar region's cheapest experience; sets :attr:`path`."""
        cand = [k for k in range(len(ctx.objects)) if ctx.confidence[k] > 0]
        if ctx.observation is None or not cand:
            return None
        rows = similarity_rows(ctx, cand)
        for k_f, r_f, _, _ in rows:
            k, r = int(k_f), int(r_f)
            ov = ctx.objects[k]
            om = ov.object_map
            vids = np.asarray(om.view_ids)[: ov.n_built]  # type: ignore[attr-defined]
            exps = [int(i) for i in np.flatnonzero(vids == r)]
            if not exps:
                continue
            src = ov.last_relocalised
            if src is None:
                here = np.asarray(om.poses[int(om.current_id)])[:3]  # type: ignore[attr-defined]
                src = int(np.argmin(np.linalg.norm(np.asarray(om.poses)[: ov.n_built, :3] - here, axis=1)))  # type: ignore[attr-defined]
            best = cheapest_path(om.graph, src, exps)  # type: ignore[attr-defined]
            if best is None:
                continue
            self.last_cost = best[1]
            self.path = best[2][1:] or [best[0]]
            return k, best[0]
        return None

    def propose(self, ctx: SearchContext) -> Pose | None:
        """A step toward the next experience of the path; re-targets at the target, when none, or when the leader changes."""
        leader = int(np.argmax(ctx.confidence)) if np.any(ctx.confidence > 0) else None
        if self.target is not None:
            k = self.target[0]
            while self.path and float(np.linalg.norm(
                    _offset(ctx.pose, _world_of(ctx, k, self.path[0]), False, self.along_surface))) < self.reach_m:
                self.path.pop(0)
        if self.target is None or not self.path or leader != self.leader:
            new = self.choose_target(ctx)
            if new is not None:
                self.target = new
        self.leader = leader
        if self.target is None:
            return None
        if not self.path:
            self.path = [self.target[1]]
        return _step_towards(ctx.pose, _world_of(ctx, self.target[0], self.path[0]), self.step_m, flat=False,
                             along_surface=self.along_surface)

    def refused(self) -> None:
        """Drop the target after a refused command."""
        self.target = None
        self.path = []


def active_strategy(chosen: str, confidence: np.ndarray, contact: bool) -> str:
    """Switching rule: ``"default"`` while every confidence is zero or contact is lost, else ``chosen``."""
    if chosen not in STRATEGIES:
        raise ConfigError(f"unknown strategy {chosen!r}; use one of {STRATEGIES}")
    c = np.asarray(confidence, dtype=float)
    if not contact or not np.any(c > 0):
        return "default"
    return chosen


def make_strategy(name: str, **kw: object) -> FollowExperienceHistory | LeastSimilarRegion | None:
    """The FEH or LSR strategy by name (None for ``"default"``, which the explorer always holds)."""
    if name == "feh":
        return FollowExperienceHistory(**kw)  # type: ignore[arg-type]
    if name == "lsr":
        return LeastSimilarRegion(**kw)  # type: ignore[arg-type]
    if name == "default":
        return None
    raise ConfigError(f"unknown strategy {name!r}; use one of {STRATEGIES}")
