"""The experience map: one graph core for the 3-DoF experience map and the 6-DoF object map.

An *experience* (Eq 2.23) is the triple (pose-cell coordinates ``P``, local-view
id ``V``, map pose ``p``). The core below is geometry-free: growable node and link
arrays, the view -> experiences index, OpenRatSLAM's decision rule
(``PosecellNetwork::get_action``), the duplicate-link rule, the relaxation
scheduler with its budget and cursor, persistence, and a networkx graph kept in step
with the map. A *geometry* plug-in supplies the poses and their arithmetic:

* :class:`maps.se2.SE2Geometry` - ``(x, y, theta)``; OpenRatSLAM's arithmetic bit for bit
  (the default, for RatSLAM);
* :class:`maps.se3.SE3Geometry` - position + unit quaternion (scalar-last) for
  WhiskerRatSLAM's object map (Alg 6).

Decision rule (:meth:`ExperienceMap.update`), once the pose cells and the local view
have both updated:

* the current view has no experience yet -> create one (``CREATE_NODE``);
* the packet moved more than ``match_distance_cells`` (wrapped Euclidean distance in
  pose cells, Eq 2.22) from the current experience, or the view changed -> search that
  view's *other* experiences for the smallest distance; below the threshold -> link
  to it and make it current (``CREATE_EDGE``, a re-localisation / loop closure), else
  create one;
* otherwise nothing happens.

On ``offset_axes`` (OpenRatSLAM: theta) the packet is first corrected by the view
offset of the last injection and wrapped once, as the C++ does.

A link stores the odometry accumulated since its source experience (geometry
columns) and the elapsed time. With ``MapConfig(link_update="average")`` a repeated
traversal of a link (in either direction) replaces it by the running mean of its
traversals (:mod:`maps.link_average`); by default it is skipped, as in OpenRatSLAM. After every action the map relaxes (Eq 2.25) in
OpenRatSLAM's order (experiences by id, then each experience's outgoing links in
creation order).

C++ quirks (decisions)
----------------------
* ``on_create_link``'s duplicate check walks the *current* experience's links for as
  many entries as the *source* has. Every link starts at the current experience, so
  the check always means "a link exists in either direction", which is what is
  implemented.
* Setting the experience that is already current changes nothing, so after the first
  experience the dead-reckoning accumulators are not reset (as in C++).
* OpenRatSLAM never resets its link timer; ``link_time_since_start=True`` reproduces
  that, the default stores the time since the link's source.

Bounded relaxation (decision)
-----------------------------
OpenRatSLAM relaxes every link ``relax_passes`` times per action, O(links) per step.
Here each :meth:`ExperienceMap.iterate` performs at most ``relax_budget`` single-link
updates. While ``relax_passes * n_links <= relax_budget`` this *is* OpenRatSLAM's
relaxation, bit for bit. Beyond that the map continues a round-robin sweep from where
the previous step stopped (the cursor is saved state), so every link is still visited
and the per-step cost is constant. ``relax_budget=None`` restores the unbounded
behaviour.

Path search (Eq 6.3)
--------------------
:attr:`ExperienceMap.graph` is a :class:`networkx.DiGraph` updated incrementally (no
rebuild per query): nodes are experience ids (``view_id``, ``pc_cells``), every link
appears in both directions with ``weight = w_t + w_r + 1 / n_l`` (translation m,
rotation rad, ``n_l`` the number of links of the edge's target), ready for
``networkx.dijkstra_path(map.graph, a, b)``.

Persistence and export
----------------------
:meth:`ExperienceMap.save` / :meth:`~ExperienceMap.load` (``.npz``, no pickle; a round trip
is bit identical and a resumed run equals an uninterrupted one),
:meth:`~ExperienceMap.to_arrays` / :meth:`~ExperienceMap.from_arrays` (the same fields,
prefixed, inside a saved SLAM model) and :meth:`~ExperienceMap.to_networkx` delegate to
:mod:`maps.experience_map_io`, whose docstring gives the file format.
"""

from __future__ import annotations

import bisect
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any, Sequence, Union

import numpy as np

from maps.experience_map_io import (  # noqa: F401 (FORMAT_VERSION: this module's name for it since 0.1)
    FORMAT_VERSION,
    MapArrays,
    map_to_networkx,
    read_map_body,
    read_map_header,
    write_map_arrays,
)
from maps.link_average import LINK_UPDATES, average_se2_link, invert_se2_link
from whisker_io.persistence import naming_file, read_npz, write_npz
from maps.se2 import SE2Geometry, clip_rad_180, signed_delta_rad
from maps.se3 import SE3Geometry
from whisker_io.errors import ConfigError, CorruptFileError, InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, config_field, validate_fields

__all__ = [
    "FORMAT_VERSION",
    "Action",
    "ExperienceMap",
    "ExperienceUpdate",
    "Geometry",
    "MapConfig",
    "clip_rad_180",
    "signed_delta_rad",
]

Geometry = Union[SE2Geometry, SE3Geometry]


class Action(IntEnum):
    """Topological action of one update (OpenRatSLAM's ``PosecellAction``)."""

    NO_ACTION = 0
    CREATE_NODE = 1
    CREATE_EDGE = 2
    SET_NODE = 3


def _sequence(value: Any, name: str) -> tuple[Any, ...]:
    if isinstance(value, (str, bytes)):
        raise ConfigError(f"{name} must be a tuple of integers, got {value!r}")
    try:
        return tuple(value)
    except TypeError:
        raise ConfigError(f"{name} must be a tuple of integers, got {value!r}") from None


@dataclass(frozen=True)
class MapConfig(ConfigDataclass):
    """Parameters of the experience-map core.

    Parameters
    ----------
    correction : float
        Relaxation rate alpha of Eq 2.25, in (0, 1] (OpenRatSLAM ``exp_correction``, 0.5).
    relax_passes : int
        Relaxation passes over all links per action (``exp_loops``, 10).
    match_distance_cells : float
        Wrapped pose-cell distance (cells) below which an experience of the current view
        is re-used (``exp_delta_pc_threshold``; OpenRatSLAM 2, thesis Table 3.1: 1).
    pc_shape : tuple of int
        Pose-cell grid shape, to wrap distances (Eq 2.22).
    offset_axes : tuple of int
        Axes on which the packet is corrected by the view offset and wrapped once
        (OpenRatSLAM: the theta axis, ``(2,)``).
    relax_budget : int or None
        Maximum single-link updates per :meth:`ExperienceMap.iterate` (2,000 ~ 50 us);
        None = OpenRatSLAM's unbounded relaxation.
    link_time_since_start : bool
        True: every link's time is the time since the first odometry (OpenRatSLAM's
        never-reset timer); False (default): the time since the link's source.
    keep_first_accumulator : bool
        True (OpenRatSLAM): creating the very first experience does not reset the
        dead-reckoning accumulator (the C++ sets experience 0 while 0 is already
        current, a no-op), so the motion before it is counted again in the next link.
        False: every creation resets it (the object map, thesis Alg 6).
    link_update : {"first", "average"}
        What a repeated traversal of a link does (a re-localisation from one of its ends
        to the other, in either direction). ``"first"`` (default, OpenRatSLAM): nothing,
        the link keeps the odometry of its first traversal. ``"average"``: the link
        becomes the running mean of its traversals - displacement in the source's frame
        (m, averaged in Cartesian form), relative facing (rad, circular mean) and elapsed
        time (s) - see :mod:`maps.link_average`; Eq 2.25's relaxation is unchanged.
        SE(2) maps only.
    """

    correction: float = checked(0.5, float, above=0, maximum=1, hint="alpha of Eq 2.25")
    relax_passes: int = checked(10, int, minimum=0)
    match_distance_cells: float = checked(2.0, float, minimum=0, hint="a distance in cells")
    pc_shape: tuple[int, ...] = (21, 21, 36)
    offset_axes: tuple[int, ...] = (2,)
    relax_budget: int | None = checked(2_000, int, minimum=1, optional=True, hint="None relaxes every link")
    link_time_since_start: bool = checked(False, bool)
    keep_first_accumulator: bool = checked(True, bool)
    link_update: str = checked("first", str, choices=LINK_UPDATES)

    def __post_init__(self) -> None:
        validate_fields(self)  # the declared fields; numpy scalars -> Python numbers (saved as JSON with the map)
        shape, axes = _sequence(self.pc_shape, "pc_shape"), _sequence(self.offset_axes, "offset_axes")
        if not shape:
            raise ConfigError("pc_shape must have at least one axis")
        for n in shape:
            config_field(n, "pc_shape entries", int, minimum=1)
        for a in axes:
            config_field(a, "offset_axes entries", int, minimum=0, maximum=len(shape) - 1, hint=f"axes of pc_shape {shape}")
        object.__setattr__(self, "pc_shape", tuple(int(n) for n in shape))
        object.__setattr__(self, "offset_axes", tuple(int(a) for a in axes))


@dataclass(frozen=True)
class ExperienceUpdate:
    """Outcome of :meth:`ExperienceMap.update`.

    Attributes
    ----------
    action : Action
        ``NO_ACTION``, ``CREATE_NODE`` or ``CREATE_EDGE``.
    exp_id : int
        Current experience after the update.
    src_id : int
        Current experience before the update (-1 while the map was empty).
    relocalised : bool
        The current experience switched to an existing, different one (a loop closure).
    new_link : bool
        A link was added (False for a repeated link, which OpenRatSLAM skips).
    """

    action: Action
    exp_id: int
    src_id: int
    relocalised: bool
    new_link: bool


def _grow(arr: np.ndarray, needed: int) -> np.ndarray:
    """``arr`` with capacity for ``needed`` rows (doubling growth)."""
    if needed <= arr.shape[0]:
        return arr
    new = np.zeros((max(needed, 2 * arr.shape[0], 16),) + arr.shape[1:], dtype=arr.dtype)
    new[: arr.shape[0]] = arr
    return new


@dataclass
class _Arrays:
    pc: np.ndarray
    vt: np.ndarray
    pose: np.ndarray
    ends: np.ndarray
    links: np.ndarray
    # the first n_links entries: link ids in relaxation order
    order: np.ndarray = field(default_factory=lambda: np.zeros(16, dtype=np.int64))
    # per experience, the next experience of the same view (-1: none)
    next_same: np.ndarray = field(default_factory=lambda: np.full(16, -1, dtype=np.int64))


class ExperienceMap:
    """Experience map on a geometry plug-in (see the module docstring).

    Parameters
    ----------
    config : MapConfig, optional
        Core parameters (defaults: OpenRatSLAM's, bounded relaxation).
    geometry : SE2Geometry or SE3Geometry, optional
        Pose arithmetic; default :class:`~maps.se2.SE2Geometry` (3-DoF RatSLAM).

    Notes
    -----
    One iteration calls :meth:`on_odo` with the odometry and, when the pose cells and
    the view both updated, :meth:`update` with the decoded packet (which relaxes the
    map). Experience ids are consecutive integers from 0.
    """

    def __init__(self, config: MapConfig | None = None, geometry: Geometry | None = None) -> None:
        self.config = config if config is not None else MapConfig()
        self.geometry: Geometry = geometry if geometry is not None else SE2Geometry(heading_cells=self.config.pc_shape[-1])
        g, nd = self.geometry, len(self.config.pc_shape)
        if self.config.link_update == "average" and not isinstance(g, SE2Geometry):
            raise ConfigError(f"link_update='average' needs an SE2Geometry map, got {type(g).__name__}; use link_update='first'")
        self._n_exp = 0
        self._n_link = 0
        self._a = _Arrays(
            pc=np.zeros((16, nd)), vt=np.zeros(16, dtype=np.int64), pose=np.zeros((16, g.pose_width)),
            ends=np.zeros((16, 2), dtype=np.int64), links=np.zeros((16, g.link_width + 1)),
        )
        self._vt_exps: dict[int, list[int]] = {}
        self._order_keys: list[int] = []  # relaxation order's sort keys (from id * 2**32 + link id), ascending
        self._shape_f = np.array(self.config.pc_shape, dtype=np.float64)
        self._nearest: Any = None  # maps.experience_map_numba.nearest_of_view, imported at the first search
        self._out: dict[int, set[int]] = {}
        self._n_links_of: dict[int, int] = {}
        self._link_of: dict[tuple[int, int], int] = {}  # (from, to) -> link index
        self._traversals = np.zeros(16, dtype=np.int64)  # traversals averaged into each link
        self.current_id = 0
        self.prev_id = 0
        self._acc = g.initial_accumulator()
        self.accum_time_s = 0.0
        self._offset = np.zeros(nd)
        self._cursor = 0
        #: single-link relaxation updates done by the last :meth:`iterate` call
        self.last_relax_updates = 0
        self._graph: Any = None

    # ------------------------------------------------------------------ views
    @property
    def n_experiences(self) -> int:
        """Number of experiences."""
        return self._n_exp

    @property
    def n_links(self) -> int:
        """Number of links."""
        return self._n_link

    @property
    def poses(self) -> np.ndarray:
        """Map poses, shape (n, pose width): SE(2) ``(x m, y m, theta rad)``, SE(3)
        ``(x, y, z m, qx, qy, qz, qw)``; a copy."""
        return self._a.pose[: self._n_exp].copy()

    @property
    def pc_coords(self) -> np.ndarray:
        """Pose-cell coordinates of every experience, cells, shape (n, ndim); a copy."""
        return self._a.pc[: self._n_exp].copy()

    @property
    def view_ids(self) -> np.ndarray:
        """Local-view id of each experience, shape (n,); a copy."""
        return self._a.vt[: self._n_exp].copy()

    @property
    def links(self) -> tuple[np.ndarray, np.ndarray]:
        """``(ends, data)``: int64 (m, 2) from/to ids and float64 (m, link width + 1) -
        the geometry's link columns (SE(2): d m, heading rad, facing rad) then dt s."""
        return self._a.ends[: self._n_link].copy(), self._a.links[: self._n_link].copy()

    @property
    def link_traversals(self) -> np.ndarray:
        """Traversals averaged into each link, int64 (m,); all 1 unless ``link_update="average"``; a copy."""
        return self._traversals[: self._n_link].copy()

    @property
    def accumulator(self) -> tuple[float, ...]:
        """Odometry accumulated since the current experience (SE(2): dx m, dy m, facing rad;
        SE(3): d (3) m in the experience's frame and the relative quaternion xyzw)."""
        return tuple(self._acc)

    @property
    def view_offset_cells(self) -> np.ndarray:
        """The view offset (cells, per axis) of the last injection (OpenRatSLAM ``vt_delta_pc_th``)."""
        return self._offset.copy()

    def current_pose(self) -> tuple[float, ...]:
        """Map pose of the current experience (all NaN while the map is empty)."""
        if self._n_exp == 0:
            return (math.nan,) * self.geometry.pose_width
        return tuple(self._a.pose[self.current_id].tolist())  # Python floats, as float(v) of each

    def dead_reckoned_pose(self) -> tuple[float, ...]:
        """The current experience's map pose plus the odometry accumulated since it."""
        base = self._a.pose[self.current_id] if self._n_exp else None
        return tuple(float(v) for v in self.geometry.dead_reckoned(base, self._acc))

    def experiences_of_view(self, view_id: int) -> list[int]:
        """Ids of the experiences created with view ``view_id``, in creation order."""
        return list(self._vt_exps.get(int(view_id), []))

    # ------------------------------------------------------------- odometry
    def on_odo(self, *odometry: Any) -> None:
        """Dead-reckon one odometry sample.

        Parameters
        ----------
        *odometry
            A :class:`~maps.odometry.PlanarOdometry` / :class:`~maps.odometry.SpatialOdometry`
            (as the geometry needs), or its fields: SE(2) ``(v m/s, omega rad/s, dt s)``,
            SE(3) ``(v (3,) m/s, omega (3,) rad/s, dt s)`` in the body frame.

        Raises
        ------
        InvalidInputError, ShapeError
            Malformed odometry; the map is unchanged.
        """
        odo = self.geometry.odometry(*odometry)
        self.geometry.accumulate(self._acc, odo)
        self.accum_time_s += odo.dt

    # ------------------------------------------------------- action (get_action)
    def _corrected(self, best: Sequence[float]) -> list[float]:
        """The packet corrected by the view offset on ``offset_axes`` and wrapped once (as the C++ does)."""
        shape = self.config.pc_shape
        corr = list(best)
        for ax in self.config.offset_axes:
            n = float(shape[ax])
            c = corr[ax] - float(self._offset[ax])
            if c < 0:
                c = n + c
            if c >= n:
                c = c - n
            corr[ax] = c
        return corr

    def _check_update(self, best_pc: Sequence[float], view_id: int, offset_cells: Any) -> tuple[list[float], int, np.ndarray | None]:
        nd = len(self.config.pc_shape)
        try:
            # a float64 vector (the SLAM loop's packet): tolist gives float(v) of each, faster
            best = best_pc.tolist() if type(best_pc) is np.ndarray and best_pc.dtype == np.float64 and best_pc.ndim == 1 \
                else [float(v) for v in best_pc]
        except (TypeError, ValueError):
            raise InvalidInputError(f"best_pc must be {nd} real pose-cell coordinates, got {best_pc!r}") from None
        if len(best) != nd or not all(math.isfinite(v) for v in best):
            raise InvalidInputError(f"best_pc must be {nd} finite pose-cell coordinates, got {best_pc!r}")
        if isinstance(view_id, (bool, np.bool_)) or not isinstance(view_id, (int, np.integer)) or not 0 <= view_id < 2**62:
            raise InvalidInputError(f"view_id must be an integer in [0, 2**62), got {view_id!r}")
        off = None
        if offset_cells is not None:
            off = np.array(offset_cells, dtype=np.float64).reshape(-1)
            if off.shape != (nd,) or not all(math.isfinite(v) for v in off.tolist()):
                raise InvalidInputError(f"offset_cells must be {nd} finite values (cells), got {offset_cells!r}")
        return best, int(view_id), off

    def update(self, best_pc: Sequence[float], view_id: int, prev_view_id: int, *, offset_cells: Any = None) -> ExperienceUpdate:
        """Choose the experience for the decoded packet and view, then relax (OpenRatSLAM ``get_action``).

        Parameters
        ----------
        best_pc : sequence of float, shape (ndim,)
            Decoded packet, fractional pose cells.
        view_id : int
            Current view id, >= 0.
        prev_view_id : int
            View id of the previous view update.
        offset_cells : array_like (ndim,), optional
            View offset (cells) of the last injection (OpenRatSLAM ``vt_delta_pc_th`` on
            theta); kept from the previous call when omitted. On ``offset_axes`` it
            corrects the packet; the geometry turns it into a link / facing rotation.

        Returns
        -------
        ExperienceUpdate

        Raises
        ------
        InvalidInputError
            Non-finite or wrong-length coordinates, a bad view id or offset; the map is unchanged.
        """
        best, vt_id, off = self._check_update(best_pc, view_id, offset_cells)
        if off is not None:
            self._offset = off
        rotation = self.geometry.offset_rotation(self._offset)
        src = self.current_id if self._n_exp else -1
        thr = self.config.match_distance_cells
        exps = self._vt_exps.get(vt_id)
        if self._n_exp == 0 or not exps:
            self._create(best, vt_id)
            result = ExperienceUpdate(Action.CREATE_NODE, self.current_id, src, False, self._n_exp > 1)
        else:
            # the distance to the current experience and the nearest other experience of the
            # view in one compiled pass (Eq 2.22; on ties the lowest id)
            nearest = self._nearest
            if nearest is None:
                from maps.experience_map_numba import nearest_of_view as nearest

                self._nearest = nearest
            delta, matched, d_matched = nearest(self._a.pc, self._a.next_same, exps[0], self.current_id,
                                                np.array(self._corrected(best)), self._shape_f)
            if not (delta > thr or vt_id != int(prev_view_id)):
                return ExperienceUpdate(Action.NO_ACTION, self.current_id, src, False, False)
            if not d_matched < thr:  # none closer than the threshold (or no other experience: -1, inf)
                matched = -1
            if matched == -1:
                self._create(best, vt_id)
                result = ExperienceUpdate(Action.CREATE_NODE, self.current_id, src, False, True)
            else:
                added = self._add_link(self.current_id, matched, rotation)
                self._set_current(matched, rotation)
                result = ExperienceUpdate(Action.CREATE_EDGE, matched, src, True, added)
        self.iterate()
        return result

    def _index_view(self, vt_id: int, exp_id: int) -> None:
        """Append experience ``exp_id`` (the newest) to view ``vt_id``'s list and to its chain (``next_same``)."""
        a = self._a
        a.next_same[exp_id] = -1
        same = self._vt_exps.setdefault(vt_id, [])
        if same:
            a.next_same[same[-1]] = exp_id
        same.append(exp_id)

    def _create(self, best: list[float], vt_id: int) -> None:
        """OpenRatSLAM ``create_experience`` + ``on_create_experience`` + ``on_set_experience(new, 0)``."""
        n, a = self._n_exp, self._a
        a.pc, a.vt, a.pose = _grow(a.pc, n + 1), _grow(a.vt, n + 1), _grow(a.pose, n + 1)
        a.next_same = _grow(a.next_same, n + 1)
        a.pose[n] = self.geometry.new_pose(a.pose[self.current_id] if n else None, self._acc)
        a.pc[n] = best
        a.vt[n] = vt_id
        self._n_exp = n + 1
        self._index_view(vt_id, n)
        if self._graph is not None:
            self._graph.add_node(n, view_id=vt_id, pc_cells=tuple(best))
        if n:
            self._add_link(self.current_id, n, 0.0)
        elif not self.config.keep_first_accumulator:
            self.geometry.reset_accumulator(self._acc, a.pose[0], 0.0)
            if not self.config.link_time_since_start:
                self.accum_time_s = 0.0
        self._set_current(n, 0.0)

    def _add_link(self, id_from: int, id_to: int, rotation: float) -> bool:
        """OpenRatSLAM ``on_create_link``: add a link unless one exists in either direction
        (then, with ``link_update="average"``, average this traversal into it)."""
        if id_to in self._out.get(id_from, ()) or id_from in self._out.get(id_to, ()):
            if self.config.link_update == "average":
                self._average_link(id_from, id_to, rotation)
            return False
        m, a = self._n_link, self._a
        a.ends, a.links = _grow(a.ends, m + 1), _grow(a.links, m + 1)
        self._traversals = _grow(self._traversals, m + 1)
        a.ends[m] = (id_from, id_to)
        a.links[m, :-1] = self.geometry.link(a.pose[id_from], self._acc, rotation)
        a.links[m, -1] = self.accum_time_s
        self._traversals[m] = 1
        self._n_link = m + 1
        self._out.setdefault(id_from, set()).add(id_to)
        self._link_of[(id_from, id_to)] = m
        for e in (id_from, id_to):
            self._n_links_of[e] = self._n_links_of.get(e, 0) + 1
        key = id_from * (1 << 32) + m  # relaxation order: by source, then creation
        keys = self._order_keys
        pos = bisect.bisect_left(keys, key)
        keys.insert(pos, key)
        a.order = order = _grow(a.order, m + 1)
        if pos < m:
            order[pos + 1 : m + 1] = order[pos:m]  # overlapping copy: numpy buffers it
        order[pos] = m
        if self._graph is not None:
            self._graph_link(m)
        return True

    def _average_link(self, id_from: int, id_to: int, rotation: float) -> None:
        """Fold the odometry since ``id_from`` (a traversal to ``id_to``) into their link's running mean."""
        a = self._a
        observed = (*self.geometry.link(a.pose[id_from], self._acc, rotation), self.accum_time_s)
        k = self._link_of.get((id_from, id_to))
        if k is None:  # the link runs id_to -> id_from: express the traversal in its direction
            k = self._link_of[(id_to, id_from)]
            observed = invert_se2_link(observed)
        n = int(self._traversals[k])
        a.links[k] = average_se2_link(a.links[k].tolist(), observed, n)
        self._traversals[k] = n + 1
        if self._graph is not None:
            self._graph_link(k)

    def _set_current(self, new_id: int, rotation: float) -> None:
        """OpenRatSLAM ``on_set_experience`` (setting the current experience again changes nothing)."""
        if new_id == self.current_id:
            return
        self.prev_id = self.current_id
        self.current_id = new_id
        self.geometry.reset_accumulator(self._acc, self._a.pose[new_id], rotation)
        if not self.config.link_time_since_start:
            self.accum_time_s = 0.0

    # ------------------------------------------------------------ relaxation
    def iterate(self, n_updates: int | None = None) -> int:
        """Relax the map (Eq 2.25, OpenRatSLAM ``iterate``); returns the number of link updates done.

        Parameters
        ----------
        n_updates : int, optional
            Single-link updates to perform. Default: ``relax_passes * n_links`` capped at
            ``relax_budget`` (see the module docstring).
        """
        m = self._n_link
        self.last_relax_updates = 0
        if m == 0:
            return 0
        full = self.config.relax_passes * m
        if n_updates is None:
            budget = self.config.relax_budget
            if budget is None or full <= budget:
                n_updates, start = full, 0
            else:
                n_updates, start = budget, self._cursor % m
        else:
            if isinstance(n_updates, bool) or not isinstance(n_updates, (int, np.integer)) or n_updates < 0:
                raise InvalidInputError(f"n_updates must be an integer >= 0, got {n_updates!r}")
            start = self._cursor % m
        if n_updates <= 0:
            return 0
        a = self._a
        self._cursor = self.geometry.relax(a.order[:m], a.ends, a.links, a.pose, float(self.config.correction), int(n_updates),
                                           int(start))
        self.last_relax_updates = int(n_updates)
        return int(n_updates)

    # ---------------------------------------------------------------- graph
    def _graph_link(self, k: int) -> None:
        f, t = (int(v) for v in self._a.ends[k])
        w_t, w_r = self.geometry.link_cost(self._a.links[k])
        g = self._graph
        g.add_edge(f, t, link_id=k, w_t=w_t, w_r=w_r)
        g.add_edge(t, f, link_id=k, w_t=w_t, w_r=w_r)
        for node in (f, t):  # Eq 6.3: 1 / n_l of the edge's target changed for both ends
            inv = 1.0 / self._n_links_of[node]
            for u in g.predecessors(node):
                e = g.edges[u, node]
                e["weight"] = e["w_t"] + e["w_r"] + inv

    @property
    def graph(self) -> Any:
        """The live :class:`networkx.DiGraph` of the map (see "Path search" in the module docstring).

        Built on first access, then updated with every new experience and link. Treat it
        as read-only; map poses are in :attr:`poses` (they move with relaxation).
        """
        if self._graph is None:
            import networkx as nx

            self._graph = nx.DiGraph()
            for i in range(self._n_exp):
                self._graph.add_node(i, view_id=int(self._a.vt[i]), pc_cells=tuple(float(v) for v in self._a.pc[i]))
            for k in range(self._n_link):
                self._graph_link(k)
        return self._graph

    def to_networkx(self) -> Any:
        """A snapshot :class:`networkx.DiGraph` with the current map poses (:func:`maps.experience_map_io.map_to_networkx`).

        Nodes: ``view_id``, ``pc_cells`` and the geometry's pose fields (SE(2): ``x_m``,
        ``y_m``, ``th_rad``); edges (from -> to, one per link): ``link_id``, the geometry's
        link fields (SE(2): ``d_m``, ``heading_rad``, ``facing_rad``) and ``dt_s``. Graph
        attribute ``current_id``.
        """
        return map_to_networkx(self)

    # ----------------------------------------------------------- save / load
    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The whole map as named arrays (the ``.npz`` fields of :mod:`maps.experience_map_io`, names prefixed).

        A subclass that saves more state extends this (``super().to_arrays(prefix)`` plus
        its own prefixed fields) and :meth:`from_arrays`; :meth:`save` and :meth:`load` call both.
        """
        a, n, m = self._a, self._n_exp, self._n_link
        saved = MapArrays(
            self.config, self.geometry, a.pc[:n].copy(), a.vt[:n].copy(), a.pose[:n].copy(), a.ends[:m].copy(),
            a.links[:m].copy(), np.array([*self._acc, self.accum_time_s, *self._offset.tolist()]),
            np.array([self.current_id, self.prev_id, self._cursor], dtype=np.int64),
            self._traversals[:m].copy() if self.config.link_update == "average" else None,
        )
        return write_map_arrays(saved, prefix)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the map to ``path`` (``.npz``, format in :mod:`maps.experience_map_io`); bit-exact round trip.

        As :func:`numpy.savez`, ``.npz`` is added to a name without it; written whole, then renamed into place
        (:func:`whisker_io.persistence.write_npz`)."""
        write_npz(path, self.to_arrays())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "ExperienceMap":
        """Read a map written by :meth:`save`.

        Raises
        ------
        CorruptFileError
            The file is unreadable, or a field is missing or has the wrong type, shape or value.
        """
        arrays = read_npz(path)
        with naming_file(path):  # a fault met while rebuilding names the file
            return cls.from_arrays(arrays)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> "ExperienceMap":
        """Rebuild a map from :meth:`to_arrays` output (e.g. an open ``.npz`` archive).

        The map is built as ``cls(config, geometry)``, so a subclass's ``from_arrays`` can
        call ``super().from_arrays(arrays, prefix)`` and restore its own fields on the result.

        Raises
        ------
        CorruptFileError
            A field is missing or has the wrong type, shape or value (named in the error).
        """
        if f"{prefix}format" not in arrays and f"em_{prefix}format" in arrays and "model" in arrays:
            raise CorruptFileError("this file holds a whole model (RatSLAM.save or WhiskerRatSLAM.save), not an "
                                   "experience map alone: load it with that class's load(); its map is .experience_map")
        config, geometry = read_map_header(arrays, prefix, MapConfig)
        em = cls(config, geometry)
        em._restore(read_map_body(arrays, prefix, config, geometry))
        return em

    def _restore(self, saved: MapArrays) -> None:
        """Take the experiences, links and state of a validated :class:`~maps.experience_map_io.MapArrays`."""
        exp_vt, link_ends = saved.exp_vt, saved.link_ends
        n, m = len(exp_vt), len(link_ends)
        a = self._a
        self._n_exp, self._n_link = n, m
        a.pc, a.vt = _grow(np.array(saved.exp_pc, dtype=np.float64), n), _grow(np.array(exp_vt, dtype=np.int64), n)
        a.pose = _grow(np.array(saved.exp_pose, dtype=np.float64), n)
        a.ends, a.links = _grow(np.array(link_ends, dtype=np.int64), m), _grow(np.array(saved.link_data, dtype=np.float64), m)
        a.next_same = np.full(max(n, 16), -1, dtype=np.int64)
        for i, v in enumerate(exp_vt.tolist()):
            self._index_view(v, i)
        self._traversals = _grow(np.ones(m, dtype=np.int64) if saved.link_traversals is None
                                 else np.array(saved.link_traversals, dtype=np.int64), m)
        for k, (f, t) in enumerate(link_ends.tolist()):  # no duplicates: read_map_body refused them
            self._out.setdefault(f, set()).add(t)
            self._link_of[(f, t)] = k
            for e in (f, t):
                self._n_links_of[e] = self._n_links_of.get(e, 0) + 1
        keys = link_ends[:, 0].astype(np.int64) * (1 << 32) + np.arange(m, dtype=np.int64)
        order = np.argsort(keys, kind="stable").astype(np.int64)
        a.order = _grow(order, m)
        self._order_keys = keys[order].tolist()
        w = self.geometry.accum_width
        state_f = saved.state_f
        self._acc = [float(v) for v in state_f[:w]]
        self.accum_time_s = float(state_f[w])
        self._offset = np.array(state_f[w + 1:], dtype=np.float64)
        self.current_id, self.prev_id, self._cursor = (int(v) for v in saved.state_i)
