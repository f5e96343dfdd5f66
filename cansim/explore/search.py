"""Region-search strategies of active exploration (thesis Sec 6.1.2; Eq 6.1-6.3).

Every strategy proposes the next end-effector goal (world frame) from a
:class:`SearchContext`; the surface placement controller then adjusts it.

* :class:`DefaultSearch` - visit the faces of a sphere mesh around the object (an
  icosphere scaled to the sphere through the object's bounding-box corners): the seed
  picks the start face, then the closest unvisited face; the array faces the centre
  with its whisker bases on the sphere.
* :class:`FollowExperienceHistory` (FEH) - after a re-localisation to experience ``e``
  of object ``k``'s map, target the experience that followed ``e`` in the map's stored
  (mapping) history; map poses (relaxed) are carried into the world through the
  current experience (``T_world_target = T_world_now T_map_current^-1 T_map_target``),
  the motion is flattened to the world horizontal plane and taken in 3-cm steps.
* :class:`LeastSimilarRegion` (LSR) - the Eq 6.1-6.2 similarity of the current region
  against the regions of every candidate object (non-zero confidence): rows
  ``(chi2, NMSE)`` sorted lexicographically (chi2, then NMSE) in descending order, the
  first row is the least similar region; among that object's experiences holding it,
  the one with the cheapest Dijkstra path (networkx, Eq 6.3 ``w = w_t + w_r + 1/n_l``)
  from the experience of that map most recently re-localised to (the nearest by map
  pose when none). The object maps are not linked to each other.

Switching (:func:`active_strategy`): the default search while every confidence is zero
or contact is lost; the chosen strategy once a confidence rises; LSR re-targets when
another identity overtakes the leader.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation, Slerp

from cansim.errors import ConfigError, InvalidInputError
from cansim.explore.placement import maintain_yaw
from whisker_io.pose import Pose
from whisker_io.validation import finite_vector

__all__ = [
    "STRATEGIES",
    "ObjectView",
    "SearchContext",
    "DefaultSearch",
    "FollowExperienceHistory",
    "LeastSimilarRegion",
    "similarity_rows",
    "cheapest_experience",
    "active_strategy",
    "make_strategy",
]

STRATEGIES = ("default", "feh", "lsr")


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


def _step_towards(pose: Pose, target: Pose, step_m: float, flat: bool) -> Pose:
    d = target.position_m - pose.position_m
    if flat:
        d = d.copy()
        d[2] = 0.0
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
        Sphere radius (through the object's bounding-box corners), m.
    standoff_m : float
        End-effector origin to whisker bases along y (the thesis array: 0.2019 m).
    seed : int
        Picks the start face.
    subdivisions : int
        Icosphere subdivisions (1: 80 faces).
    roll_rad : float
        Roll about y after Alg 8 (the trajectories' pi/2).
    mesh : trimesh.Trimesh, optional
        In simulation: the ray from the face toward the centre is cast against the mesh
        and the whisker bases are put ``clearance_m`` in front of the hit (a sphere
        through the bounding-box corners leaves up to 12 cm of air before a Box face,
        beyond the 60-160 mm whiskers). Without it the bases sit on the sphere.
    clearance_m : float
        Gap in front of the hit, m.
    """

    name = "default"

    def __init__(self, centre_m: ArrayLike, radius_m: float, standoff_m: float = 0.2019, *, seed: int = 0,
                 subdivisions: int = 1, roll_rad: float = math.pi / 2, mesh: trimesh.Trimesh | None = None,
                 clearance_m: float = 0.015) -> None:
        c = finite_vector(centre_m, 3, "centre_m")  # the one validator: rejects strings, NaN, wrong shapes
        for name, v in (("radius_m", radius_m), ("standoff_m", standoff_m)):
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InvalidInputError(f"{name} must be a positive number of metres, got {v!r}")
        sphere = trimesh.creation.icosphere(subdivisions=int(subdivisions))
        d = sphere.triangles_center
        self.directions = d / np.linalg.norm(d, axis=1, keepdims=True)
        self.centre_m, self.radius_m, self.standoff_m, self.roll_rad = c, float(radius_m), float(standoff_m), float(roll_rad)
        self.visited = np.zeros(len(self.directions), dtype=bool)
        self.current = int(np.random.default_rng(seed).integers(len(self.directions)))
        self._started = False
        self.distance_m = np.full(len(self.directions), self.radius_m)
        if mesh is not None:
            origins = c + 2.0 * self.radius_m * self.directions
            locs, rays, _ = mesh.ray.intersects_location(origins, -self.directions, multiple_hits=False)
            for loc, r in zip(locs, rays):
                self.distance_m[r] = min(self.radius_m, float((loc - c) @ self.directions[r]) + float(clearance_m))

    def face_pose(self, face: int) -> Pose:
        """End-effector pose facing the centre from face ``face``."""
        u = self.directions[face]
        rot = maintain_yaw(-u) * Rotation.from_rotvec([0.0, self.roll_rad, 0.0])
        return Pose.from_rotation(self.centre_m + (self.distance_m[face] + self.standoff_m) * u, rot)

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


class FollowExperienceHistory:
    """FEH (see the module docstring). ``step_m``: largest horizontal step (3 cm)."""

    name = "feh"

    def __init__(self, step_m: float = 0.03) -> None:
        if not (isinstance(step_m, (int, float)) and math.isfinite(step_m) and step_m > 0):
            raise InvalidInputError(f"step_m must be a positive number of metres, got {step_m!r}")
        self.step_m = float(step_m)
        self.target: tuple[int, int] | None = None

    @staticmethod
    def next_in_history(history: np.ndarray, exp: int) -> int | None:
        """The experience following the first visit of ``exp`` in ``history`` (None at its end)."""
        h = np.asarray(history)
        idx = np.flatnonzero(h == exp)
        if not idx.size:
            return None
        after = h[idx[0] + 1:]
        after = after[(after != exp) & (after >= 0)]
        return int(after[0]) if after.size else None

    def propose(self, ctx: SearchContext) -> Pose | None:
        """A 3-cm horizontal step toward the target; None when there is none."""
        if ctx.relocalised:
            k, e = max(ctx.relocalised, key=lambda ke: (ctx.confidence[ke[0]], -ke[0]))
            ov = ctx.objects[k]
            nxt = self.next_in_history(ov.object_map.history[: ov.n_history], e)  # type: ignore[attr-defined]
            if nxt is not None:
                self.target = (k, nxt)
        if self.target is None:
            return None
        k, e = self.target
        goal = _world_of(ctx, k, e)
        return _step_towards(ctx.pose, goal, self.step_m, flat=True)

    def refused(self) -> None:
        """Drop the target after a refused command."""
        self.target = None


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


def cheapest_experience(graph: object, source: int, targets: list[int]) -> tuple[int, float] | None:
    """The target with the cheapest Dijkstra path from ``source`` (Eq 6.3 ``weight``), with its cost."""
    import networkx as nx

    dist = nx.single_source_dijkstra_path_length(graph, source, weight="weight")
    reach = [(float(dist[t]), t) for t in targets if t in dist]
    if not reach:
        return None
    cost, t = min(reach)
    return int(t), cost


class LeastSimilarRegion:
    """LSR (see the module docstring). ``step_m``: largest step toward the target (3 cm)."""

    name = "lsr"

    def __init__(self, step_m: float = 0.03, reach_m: float = 0.01) -> None:
        if not (isinstance(step_m, (int, float)) and math.isfinite(step_m) and step_m > 0):
            raise InvalidInputError(f"step_m must be a positive number of metres, got {step_m!r}")
        self.step_m, self.reach_m = float(step_m), float(reach_m)
        self.target: tuple[int, int] | None = None
        self.leader: int | None = None
        self.last_cost: float | None = None

    def choose_target(self, ctx: SearchContext) -> tuple[int, int] | None:
        """(object, experience) of the least similar region's cheapest experience."""
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
            best = cheapest_experience(om.graph, src, exps)  # type: ignore[attr-defined]
            if best is None:
                continue
            self.last_cost = best[1]
            return k, best[0]
        return None

    def propose(self, ctx: SearchContext) -> Pose | None:
        """A step toward the target; re-targets when reached, when none, or when the leader changes."""
        leader = int(np.argmax(ctx.confidence)) if np.any(ctx.confidence > 0) else None
        reached = False
        if self.target is not None:
            goal = _world_of(ctx, *self.target)
            reached = float(np.linalg.norm(goal.position_m - ctx.pose.position_m)) < self.reach_m
        if self.target is None or reached or leader != self.leader:
            new = self.choose_target(ctx)
            if new is not None:
                self.target = new
        self.leader = leader
        if self.target is None:
            return None
        return _step_towards(ctx.pose, _world_of(ctx, *self.target), self.step_m, flat=False)

    def refused(self) -> None:
        """Drop the target after a refused command."""
        self.target = None


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
