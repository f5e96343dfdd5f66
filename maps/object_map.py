"""WhiskerRatSLAM's object map: the experience map on SE(3) plus the experience history (thesis Sec 5.1.2.4).

An object map is an :class:`~maps.experience_map.ExperienceMap` with the
:class:`~maps.se3.SE3Geometry` (positions and scalar-last unit quaternions, first
experience at the identity; Alg 6): complex experiences hold the pose-cell location,
the region (local-view id, whose PFH and SDA the whisk front end stores) and the map
pose; links hold the relative translation and rotation. On top of the core it keeps
the *experience history*, the current experience at every iteration, which Ch.5's
recognition (leaky integration of re-localisations) and Ch.6's follow-experience-history
search read. The history is saved with the map; the iteration at which each experience
was created (its first entry in the history, :attr:`ObjectMap.creation_iterations`) is
derived from it.

What was felt is kept too (for identification from new viewpoints,
:mod:`maps.surface_match`): :meth:`ObjectMap.record_contacts` attaches a whisk's contact
points (end-effector frame, metres) to the current experience, as felt from that
experience's pose. They are stored in that experience's frame, so the map-frame surface
(:meth:`ObjectMap.surface_points`) follows the experience poses when the map relaxes,
and are saved with the map and appended with it (:mod:`maps.object_library`).

Three queries serve the model's pose-consistent region matching (WhiskerRatSLAM's pose
gate): :meth:`ObjectMap.predicted_pose` (the dead-reckoned pose after one more
odometry sample, the map unchanged), :meth:`ObjectMap.pose_distances` (position and
rotation distance of every experience to a pose, Sec 5.2.2.1's error measures) and
:meth:`ObjectMap.gated_views` (the views with an experience inside a per-experience gate
around a pose, and their smallest normalised distance).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from maps.experience_map import ExperienceMap, MapConfig
from maps.odometry import SpatialOdometry
from maps.se3 import SE3Geometry
from whisker_io.errors import CorruptFileError, InvalidInputError, ShapeError

__all__ = ["ObjectMap"]


class ObjectMap(ExperienceMap):
    """An SE(3) experience map with its experience history.

    Parameters
    ----------
    config : MapConfig
        Core parameters (``pc_shape`` of the 6-D pose cells, ``offset_axes=()``).
    geometry : SE3Geometry, optional
    """

    def __init__(self, config: MapConfig | None = None, geometry: SE3Geometry | None = None) -> None:
        config = config if config is not None else MapConfig(
            pc_shape=(5,) * 6, offset_axes=(), match_distance_cells=1.0, keep_first_accumulator=False
        )
        super().__init__(config, geometry if geometry is not None else SE3Geometry())
        if not isinstance(self.geometry, SE3Geometry):
            raise InvalidInputError("an ObjectMap needs the SE3Geometry")
        self._history = np.zeros(64, dtype=np.int64)
        self._n_hist = 0
        self._born = np.zeros(16, dtype=np.int64)  # history index at which each experience was created
        self._n_born = 0
        self._last_reloc = -1  # history index of the last re-localisation
        self._contact_pts = np.zeros((64, 3))  # contact points in their experience's frame, m
        self._contact_exp = np.zeros(64, dtype=np.int64)  # the experience each contact belongs to
        self._n_contacts = 0

    @property
    def history(self) -> np.ndarray:
        """Current experience per recorded iteration, (n_iterations,) int64 (-1 before the first); a copy."""
        return self._history[: self._n_hist].copy()

    @property
    def n_recorded(self) -> int:
        """Number of recorded iterations (the length of :attr:`history`)."""
        return self._n_hist

    @property
    def last_relocalisation(self) -> int:
        """History index of the last recorded re-localisation (a switch to an experience created
        earlier), -1 if none."""
        return self._last_reloc

    @property
    def creation_iterations(self) -> np.ndarray:
        """History index (iteration) at which each experience was created, (n_experiences,) int64; a copy.

        An experience that never appeared in the history (a map built without
        :meth:`record`) has -1.
        """
        self._sync_born()
        return self._born[: self._n_born].copy()

    def _sync_born(self) -> None:
        """Experiences created since the last :meth:`record` were created in the iteration being recorded."""
        n = self.n_experiences
        if n > len(self._born):
            self._born = np.concatenate([self._born, np.zeros(max(n, len(self._born)), dtype=np.int64)])
        self._born[self._n_born:n] = self._n_hist
        self._n_born = n

    def record(self) -> None:
        """Append the current experience (or -1 while empty) to the history (one call per iteration)."""
        self._sync_born()
        if self._n_hist == len(self._history):
            self._history = np.concatenate([self._history, np.zeros(len(self._history), dtype=np.int64)])
        cur = self.current_id if self.n_experiences else -1
        t = self._n_hist
        if t and cur >= 0 and cur != self._history[t - 1] and self._born[cur] < t:
            self._last_reloc = t
        self._history[t] = cur
        self._n_hist = t + 1

    @property
    def n_contacts(self) -> int:
        """Number of stored contact points (:meth:`record_contacts`)."""
        return self._n_contacts

    @property
    def contact_points_m(self) -> np.ndarray:
        """Stored contact points, each in the frame of its experience (the end-effector frame
        at that experience's pose), (n_contacts, 3) m; a copy."""
        return self._contact_pts[: self._n_contacts].copy()

    @property
    def contact_experiences(self) -> np.ndarray:
        """Experience of each stored contact point, (n_contacts,) int64; a copy."""
        return self._contact_exp[: self._n_contacts].copy()

    def record_contacts(self, contact_points_m: Any) -> int:
        """Keep a whisk's contact points with the current experience (what was felt, and from where).

        Call after the whisk's iteration was processed: the whisk was made at the
        dead-reckoned pose (:meth:`dead_reckoned_pose`: the current experience's pose
        composed with the odometry since it; the experience's own pose right after a
        re-localisation or a new experience). The points are stored in the current
        experience's frame, ``R_e^T (p + R x - p_e)`` for the dead-reckoned pose
        ``(p, R)`` and the experience pose ``(p_e, R_e)``, so the map-frame surface
        (:meth:`surface_points`) follows the experience when the map relaxes.

        Parameters
        ----------
        contact_points_m : array_like (k, 3)
            The whisk's contact points in the end-effector frame, m (k may be 0).

        Returns
        -------
        int
            The experience the points were attached to.

        Raises
        ------
        ShapeError
            Not a (k, 3) array.
        InvalidInputError
            Non-finite points, or no experience yet (explore with an observation first).
        """
        from whisker_io.validation import finite_array

        pts = finite_array(contact_points_m, (None, 3), "contact_points_m")
        if self.n_experiences == 0:
            raise InvalidInputError("the map has no experience to attach contact points to; step the model with an observation first")
        k, n = len(pts), self._n_contacts
        if n + k > len(self._contact_pts):
            grow = max(n + k, 2 * len(self._contact_pts))
            self._contact_pts = np.concatenate([self._contact_pts[:n], np.zeros((grow - n, 3))])
            self._contact_exp = np.concatenate([self._contact_exp[:n], np.zeros(grow - n, dtype=np.int64)])
        cur = int(self.current_id)
        if k:  # felt from the dead-reckoned pose (the current experience and the odometry since): into its frame
            from scipy.spatial.transform import Rotation

            dr = np.asarray(self.dead_reckoned_pose())
            exp = self._a.pose[cur]
            pts = Rotation.from_quat(exp[3:7]).inv().apply(dr[:3] + Rotation.from_quat(dr[3:7]).apply(pts) - exp[:3])
        self._contact_pts[n:n + k] = pts
        self._contact_exp[n:n + k] = cur
        self._n_contacts = n + k
        return cur

    def surface_points(self) -> np.ndarray:
        """The stored contact points in the map frame, (n_contacts, 3) m.

        Each point is placed by the current pose of its experience (``p_e + R(q_e) x``),
        so the surface follows the map's relaxation.
        """
        from scipy.spatial.transform import Rotation

        n = self._n_contacts
        if n == 0:
            return np.zeros((0, 3))
        poses = self._a.pose[: self.n_experiences]
        e = self._contact_exp[:n]
        return poses[e, :3] + Rotation.from_quat(poses[e, 3:7]).apply(self._contact_pts[:n])

    def contact_viewpoints(self) -> np.ndarray:
        """Where each stored contact was felt from, (n_contacts, 3) m in the map frame.

        The position of the contact's experience (the end-effector pose it is stored
        in), in the order of :meth:`surface_points`: the arm was outside the object there,
        which orients the stored surface's normals (:mod:`maps.surface_field`).
        """
        n = self._n_contacts
        if n == 0:
            return np.zeros((0, 3))
        return self._a.pose[: self.n_experiences][self._contact_exp[:n], :3].copy()

    def predicted_pose(self, *odometry: Any) -> np.ndarray:
        """The dead-reckoned pose after one more odometry sample; the map is unchanged.

        Parameters
        ----------
        *odometry : SpatialOdometry, or its fields ``v (3,) m/s, omega (3,) rad/s, dt s``
            Body-frame motion since the last :meth:`on_odo` (Eq 5.7).

        Returns
        -------
        ndarray (7,)
            ``(x, y, z m, qx, qy, qz, qw)``: the current experience's pose composed with the
            accumulated odometry and this sample (Alg 6, Eq 5.13); relative to the identity
            while the map is empty.

        Raises
        ------
        InvalidInputError, ShapeError
            Malformed odometry.
        """
        g = self.geometry
        if not (len(odometry) == 3 or (len(odometry) == 1 and isinstance(odometry[0], SpatialOdometry))):
            raise InvalidInputError("predicted_pose takes a SpatialOdometry or its fields (v (3,), omega (3,), dt)")
        odo = g.odometry(*odometry)
        pose = list(self.dead_reckoned_pose())  # one more body-frame step from the absolute pose (Alg 6, Eq 5.13)
        g.accumulate(pose, odo)
        return np.array(pose, dtype=np.float64)

    def pose_distances(self, pose: Any) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and rotation (rad) distance of every experience to ``pose``.

        Parameters
        ----------
        pose : array_like (7,)
            ``(x, y, z m, qx, qy, qz, qw)``, a unit quaternion scalar-last.

        Returns
        -------
        (position_m, rotation_rad) : ndarray (n_experiences,) each
            Euclidean distance and the angle ``2 acos |<q_e, q>|`` in [0, pi] (Sec 5.2.2.1).

        Raises
        ------
        ShapeError, InvalidInputError
            Not 7 finite numbers, or a quaternion that is not unit length.
        """
        from maps._se3_numba import pose_distances_se3

        p = self._checked_pose(pose)
        n = self.n_experiences
        dist, angle = np.empty(n), np.empty(n)
        pose_distances_se3(self._a.pose, n, p, dist, angle)
        return dist, angle

    @staticmethod
    def _checked_pose(pose: Any) -> np.ndarray:
        """A pose argument as a contiguous float64 (7,) array with a unit quaternion, else the typed error."""
        try:
            p = np.ascontiguousarray(pose, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidInputError(f"pose must be 7 numbers (x, y, z, qx, qy, qz, qw), got {pose!r}") from None
        if p.shape != (7,):
            raise ShapeError(f"pose must be (x, y, z, qx, qy, qz, qw), 7 numbers; got shape {p.shape}")
        vals = p.tolist()
        if not all(math.isfinite(v) for v in vals) or abs(math.sqrt(sum(v * v for v in vals[3:])) - 1.0) > 1e-6:
            raise InvalidInputError("pose must be finite with a unit quaternion (scalar-last)")
        return p

    def gated_views(self, pose: Any, gate_m: np.ndarray, gate_rad: np.ndarray, n_views: int) -> tuple[np.ndarray, np.ndarray]:
        """Views with an experience inside its gate around ``pose``, and their smallest normalised distance.

        Parameters
        ----------
        pose : array_like (7,)
            As :meth:`pose_distances`.
        gate_m, gate_rad : ndarray (n_experiences,)
            Position (m) and rotation (rad) gate of each experience.
        n_views : int
            Number of views (local-view ids are below it).

        Returns
        -------
        (consistent, cost) : ndarray (n_views,) bool and float64
            ``consistent[v]``: some experience ``e`` of view ``v`` has ``d_e <= gate_m[e]`` and
            ``angle_e <= gate_rad[e]`` (the distances of :meth:`pose_distances`); ``cost[v]``:
            the smallest ``d_e / gate_m[e] + angle_e / gate_rad[e]`` among them, 0 where not
            consistent. One compiled pass (:func:`maps._se3_numba.gate_views_se3`); the angle is
            computed only for experiences inside the position gate.

        Raises
        ------
        ShapeError, InvalidInputError
            A bad pose, gates that are not (n_experiences,) arrays of numbers >= 0, a bad
            ``n_views`` or a view id >= ``n_views``.
        """
        from maps._se3_numba import gate_views_se3

        p = self._checked_pose(pose)
        n = self.n_experiences
        try:
            gm = np.ascontiguousarray(gate_m, dtype=np.float64)
            gr = np.ascontiguousarray(gate_rad, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidInputError("gate_m and gate_rad must be arrays of numbers (m, rad)") from None
        if gm.shape != (n,) or gr.shape != (n,):
            raise ShapeError(f"gate_m and gate_rad must be ({n},) arrays (one gate per experience), got {gm.shape} and {gr.shape}")
        if isinstance(n_views, (bool, np.bool_)) or not isinstance(n_views, (int, np.integer)) or n_views < 0:
            raise InvalidInputError(f"n_views must be an integer >= 0, got {n_views!r}")
        nv = int(n_views)
        consistent = np.zeros(nv, dtype=bool)
        best = np.full(nv, np.inf)
        status = gate_views_se3(self._a.pose, n, p, gm, gr, self._a.vt, consistent, best)
        if status == 1:
            raise InvalidInputError("gates must be >= 0 (m, rad), not NaN")
        if status == 2:
            raise InvalidInputError(f"the map holds view {int(self._a.vt[:n].max())}, beyond n_views={nv}")
        best[~consistent] = 0.0
        return consistent, best

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The map's arrays plus ``history``."""
        arrays = super().to_arrays(prefix)
        arrays[prefix + "history"] = self.history
        arrays[prefix + "contact_points_m"] = self.contact_points_m
        arrays[prefix + "contact_exp"] = self.contact_experiences
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> "ObjectMap":
        """Rebuild from :meth:`to_arrays` output (raises CorruptFileError naming a bad field)."""
        om = super().from_arrays(arrays, prefix)
        key = prefix + "history"
        if key not in arrays:
            raise CorruptFileError("missing", field=key)
        h = np.asarray(arrays[key])
        if h.ndim != 1 or h.dtype.kind != "i" or (len(h) and (h.min() < -1 or h.max() >= om.n_experiences)):
            raise CorruptFileError(f"expected experience ids in [-1, {om.n_experiences}), got {h.dtype} {h.shape}", field=key)
        om._history = np.concatenate([h.astype(np.int64), np.zeros(64, dtype=np.int64)])
        om._n_hist = len(h)
        born = np.full(max(om.n_experiences, 16), -1, dtype=np.int64)
        ids, first = np.unique(h[h >= 0], return_index=True)
        born[ids] = np.flatnonzero(h >= 0)[first]
        om._born, om._n_born = born, om.n_experiences
        t = np.arange(1, len(h))
        switch = (h[1:] >= 0) & (h[1:] != h[:-1]) & (born[np.maximum(h[1:], 0)] < t)
        om._last_reloc = int(t[switch][-1]) if switch.any() else -1
        kp, ke = prefix + "contact_points_m", prefix + "contact_exp"
        if (kp in arrays) != (ke in arrays):
            raise CorruptFileError("missing (contact points and their experiences are saved together)",
                                   field=ke if kp in arrays else kp)
        if kp in arrays:  # maps saved before contacts were kept have neither: no stored surface
            pts, ex = np.asarray(arrays[kp]), np.asarray(arrays[ke])
            if pts.ndim != 2 or pts.shape[1] != 3 or pts.dtype.kind != "f" or not np.isfinite(pts).all():
                raise CorruptFileError(f"expected finite (n, 3) floats, got {pts.dtype} {pts.shape}", field=kp)
            if ex.shape != (len(pts),) or ex.dtype.kind != "i" or (len(ex) and (ex.min() < 0 or ex.max() >= om.n_experiences)):
                raise CorruptFileError(f"expected {len(pts)} experience ids in [0, {om.n_experiences}), got {ex.dtype} {ex.shape}",
                                       field=ke)
            om._contact_pts = np.concatenate([pts.astype(np.float64), np.zeros((64, 3))])
            om._contact_exp = np.concatenate([ex.astype(np.int64), np.zeros(64, dtype=np.int64)])
            om._n_contacts = len(pts)
        return om
