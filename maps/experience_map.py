"""RatSLAM experience map (3-DoF) with OpenRatSLAM semantics (Eq 2.23-2.25 of the thesis).

An *experience* (Eq 2.23) is the triple (pose-cell coordinates ``P``, local-view
id ``V``, map pose ``p = (x, y, theta)``). Between experiences the map
dead-reckons the odometry (``facing += omega dt`` first, then
``x, y += v dt (cos, sin)(facing)``, as OpenRatSLAM's ``on_odo``). Whenever the
pose cells and the local view both updated, :meth:`ExperienceMap.update`
decides, exactly as OpenRatSLAM's ``PosecellNetwork::get_action``:

* the current view has no experience yet -> create one (``CREATE_NODE``);
* the packet moved more than ``exp_delta_pc_threshold`` cells (wrapped
  Euclidean distance in (x, y, theta) cells) from the current experience, or
  the view changed -> search that view's *other* experiences for the smallest
  distance; below the threshold -> link to it and make it current
  (``CREATE_EDGE``, a re-localisation / loop closure), else create one;
* otherwise nothing happens.

A link stores the odometry accumulated since its source experience: distance
``d``, heading relative to the source's facing, relative facing and elapsed
time. After every action the map is relaxed (Eq 2.25): for each link the
target position predicted by the link, ``l = p_from + d (cos, sin)(th_from +
heading)``, pulls both ends, ``p_from += c (p_to - l)``, ``p_to -= c (p_to -
l)``, and the facings likewise, with ``c = exp_correction`` (0.5), Gauss-Seidel
in OpenRatSLAM's order (experiences by id, then each experience's outgoing
links in creation order), ``exp_loops`` passes.

C++ quirks (decisions)
----------------------
* ``on_create_link``'s duplicate check walks the *current* experience's links
  for as many entries as the *source* has. Every link OpenRatSLAM creates starts
  at the current experience: ``get_action``'s source is the pose cells'
  current experience, which the map has just been set to. So the check always
  means "a link exists in either direction", and that is what is tested here.
  The two can only differ for a link from a non-current experience, which
  neither OpenRatSLAM nor :meth:`ExperienceMap.update` creates, so there is no
  switch for it.
* Setting the experience that is already current changes nothing, so after the
  first experience the dead-reckoning accumulators are not reset (as in C++).
* OpenRatSLAM never resets its link timer; ``link_time_since_start=True``
  reproduces that (the parity presets do), the default stores the time since
  the link's source.

Bounded relaxation (decision)
-----------------------------
OpenRatSLAM relaxes every link ``exp_loops`` times per action, so one step
costs O(links) and a long run slows down without bound. Here each
:meth:`ExperienceMap.iterate` performs at most ``relax_budget`` single-link
updates. While ``exp_loops * n_links <= relax_budget`` this *is* OpenRatSLAM's
relaxation, bit for bit (same order, same arithmetic). Beyond that the map
continues a round-robin sweep in the same order from where the previous step
stopped (the cursor is part of the saved state), so every link is still
visited, the per-step cost is constant and the map converges over a few
steps instead of within one. ``relax_budget=None`` restores the unbounded
OpenRatSLAM behaviour (:meth:`ExperienceMapConfig.openratslam`).

Data layout
-----------
Experiences and links live in growable numpy arrays (the relaxation runs in a
numba kernel over them); :meth:`ExperienceMap.to_networkx` returns a
:class:`networkx.DiGraph` view with typed attributes (:class:`ExperienceAttrs`,
:class:`LinkAttrs`) for path search and plotting.

Saved file format (``.npz``, no pickle)
----------------------------------------
``ExperienceMap.save(path)`` writes a numpy ``.npz`` archive (read back with
``allow_pickle=False``) holding:

* ``format`` - int64 scalar, :data:`FORMAT_VERSION`;
* ``config`` - 0-d unicode string, JSON of :class:`ExperienceMapConfig`;
* ``exp_pc`` float64 (n, 3) pose-cell (x, y, th) coordinates, ``exp_vt`` int64 (n,)
  view ids, ``exp_pose`` float64 (n, 3) map pose (x m, y m, theta rad);
* ``link_ends`` int64 (m, 2) (from, to) ids, ``link_data`` float64 (m, 4)
  (d m, heading rad, facing rad, dt s);
* ``state_f`` float64 (6,) = accum dx, accum dy, accum facing, accum time,
  relative_rad, vt_delta_pc_th; ``state_i`` int64 (3,) = current id, previous id,
  relaxation cursor.

Floats are stored as raw IEEE-754 doubles, so a save/load round trip is bit
identical and a resumed run equals an uninterrupted one.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from enum import IntEnum
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from whisker_io.errors import CorruptFileError, InvalidInputError

if TYPE_CHECKING:  # pragma: no cover
    import networkx as nx

__all__ = [
    "FORMAT_VERSION",
    "Action",
    "ExperienceAttrs",
    "ExperienceMap",
    "ExperienceMapConfig",
    "ExperienceUpdate",
    "LinkAttrs",
    "clip_rad_180",
    "signed_delta_rad",
]

FORMAT_VERSION = 1
_TWO_PI = 2.0 * math.pi


def clip_rad_180(angle: float) -> float:
    """Wrap an angle to (-pi, pi] radians exactly as OpenRatSLAM's ``clip_rad_180``."""
    while angle > math.pi:
        angle -= _TWO_PI
    while angle <= -math.pi:
        angle += _TWO_PI
    return angle


def _clip_rad_360(angle: float) -> float:
    while angle < 0:
        angle += _TWO_PI
    while angle >= _TWO_PI:
        angle -= _TWO_PI
    return angle


def signed_delta_rad(angle1: float, angle2: float) -> float:
    """Signed smallest rotation from ``angle1`` to ``angle2`` (rad), as OpenRatSLAM's ``get_signed_delta_rad``."""
    direction = clip_rad_180(angle2 - angle1)
    delta = abs(_clip_rad_360(angle1) - _clip_rad_360(angle2))
    if delta < _TWO_PI - delta:
        return delta if direction > 0 else -delta
    return _TWO_PI - delta if direction > 0 else -(_TWO_PI - delta)


class Action(IntEnum):
    """Topological action of one update (OpenRatSLAM's ``PosecellAction``)."""

    NO_ACTION = 0
    CREATE_NODE = 1
    CREATE_EDGE = 2
    SET_NODE = 3


class ExperienceAttrs(TypedDict):
    """Node attributes of :meth:`ExperienceMap.to_networkx` (units in the names)."""

    x_pc: float
    y_pc: float
    th_pc: float
    vt_id: int
    x_m: float
    y_m: float
    th_rad: float


class LinkAttrs(TypedDict):
    """Edge attributes of :meth:`ExperienceMap.to_networkx`."""

    link_id: int
    d_m: float
    heading_rad: float
    facing_rad: float
    dt_s: float


@dataclass(frozen=True)
class ExperienceMapConfig:
    """Parameters of the experience map (OpenRatSLAM names and defaults).

    Parameters
    ----------
    exp_correction : float
        Relaxation rate ``alpha`` of Eq 2.25 (OpenRatSLAM default 0.5), in (0, 1].
    exp_loops : int
        Relaxation passes per action (default 10).
    exp_initial_em_deg : float
        Facing (deg) of the dead reckoning before the first experience
        (OpenRatSLAM default 90; Table 3.1 of the thesis uses 180).
    exp_delta_pc_threshold : float
        Wrapped pose-cell distance (cells) below which an experience of the
        current view is re-used (OpenRatSLAM default 2; Table 3.1: 1).
    pc_dim_xy, pc_dim_th : int
        Pose-cell grid size, used to wrap pose-cell distances.
    relax_budget : int or None
        Maximum single-link updates per :meth:`ExperienceMap.iterate` (see the
        module docstring); default 2,000 (~50 us; OpenRatSLAM's exact relaxation
        for maps of up to 2,000 / exp_loops = 200 links). ``None`` = OpenRatSLAM's
        unbounded relaxation.
    link_time_since_start : bool
        OpenRatSLAM never resets its link timer (``accum_delta_time_s``), so each
        link's ``delta_time_s`` - Dijkstra's cost - is the time since the first
        odometry. True reproduces that; False (default) stores the time since the
        link's source experience, as the thesis' model means.
    """

    exp_correction: float = 0.5
    exp_loops: int = 10
    exp_initial_em_deg: float = 90.0
    exp_delta_pc_threshold: float = 2.0
    pc_dim_xy: int = 21
    pc_dim_th: int = 36
    relax_budget: int | None = 2_000
    link_time_since_start: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.exp_correction) and 0.0 < self.exp_correction <= 1.0):
            raise InvalidInputError(f"exp_correction must be in (0, 1], got {self.exp_correction!r}")
        for name in ("exp_loops", "pc_dim_xy", "pc_dim_th"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < (0 if name == "exp_loops" else 1):
                raise InvalidInputError(f"{name} must be a non-negative integer (>= 1 for dimensions), got {value!r}")
        if not math.isfinite(self.exp_initial_em_deg):
            raise InvalidInputError(f"exp_initial_em_deg must be finite, got {self.exp_initial_em_deg!r}")
        if not (math.isfinite(self.exp_delta_pc_threshold) and self.exp_delta_pc_threshold >= 0):
            raise InvalidInputError(
                f"exp_delta_pc_threshold must be a finite number >= 0 (cells), got {self.exp_delta_pc_threshold!r}"
            )
        if self.relax_budget is not None and (
            isinstance(self.relax_budget, bool) or not isinstance(self.relax_budget, (int, np.integer)) or self.relax_budget < 1
        ):
            raise InvalidInputError(f"relax_budget must be a positive integer or None, got {self.relax_budget!r}")
        if not isinstance(self.link_time_since_start, (bool, np.bool_)):
            raise InvalidInputError(f"link_time_since_start must be a boolean, got {self.link_time_since_start!r}")

    @classmethod
    def openratslam(cls, **overrides: Any) -> "ExperienceMapConfig":
        """OpenRatSLAM's defaults with its unbounded (O(links) per step) relaxation and link timer."""
        params: dict[str, Any] = {"relax_budget": None, "link_time_since_start": True}
        params.update(overrides)
        return cls(**params)


@dataclass(frozen=True)
class ExperienceUpdate:
    """Outcome of :meth:`ExperienceMap.update`.

    Attributes
    ----------
    action : Action
        What happened (``NO_ACTION``, ``CREATE_NODE`` or ``CREATE_EDGE``).
    exp_id : int
        Current experience after the update (-1 while the map is empty).
    src_id : int
        Current experience before the update.
    relocalised : bool
        True when the current experience switched to an existing, different
        experience (a loop closure / re-localisation).
    new_link : bool
        True when a link was added (False for a repeated link OpenRatSLAM skips).
    """

    action: Action
    exp_id: int
    src_id: int
    relocalised: bool
    new_link: bool


def _relax_kernel() -> Any:
    """Return the numba Gauss-Seidel relaxation kernel (numba is imported on first use)."""
    from maps._relax_numba import relax_links

    return relax_links


def _grow(arr: np.ndarray, needed: int) -> np.ndarray:
    """Return ``arr`` with capacity for ``needed`` rows (doubling growth)."""
    if needed <= arr.shape[0]:
        return arr
    new = np.zeros((max(needed, 2 * arr.shape[0], 16),) + arr.shape[1:], dtype=arr.dtype)
    new[: arr.shape[0]] = arr
    return new


class ExperienceMap:
    """Experience map of RatSLAM with OpenRatSLAM's semantics (Eq 2.23-2.25).

    Parameters
    ----------
    config : ExperienceMapConfig, optional
        Parameters; OpenRatSLAM's defaults with bounded relaxation when omitted.

    Notes
    -----
    One RatSLAM iteration calls :meth:`on_odo` with the odometry and, when both
    the pose cells and the view updated, :meth:`update` with the decoded packet
    (which also relaxes the map). Experience ids are consecutive integers from 0.

    OpenRatSLAM's ``on_create_link`` checks for an existing link by indexing the
    *current* experience's links instead of ``exp_id_from``'s; links are only
    ever created from the current experience, so the faithful and the intended
    check coincide and this class implements the intended one.
    """

    def __init__(self, config: ExperienceMapConfig | None = None) -> None:
        self.config = config if config is not None else ExperienceMapConfig()
        self._n_exp = 0
        self._n_link = 0
        self._exp_pc = np.zeros((16, 3))
        self._exp_vt = np.zeros(16, dtype=np.int64)
        self._exp_pose = np.zeros((16, 3))
        self._link_ends = np.zeros((16, 2), dtype=np.int64)
        self._link_data = np.zeros((16, 4))
        # links sorted by (from id, link id): OpenRatSLAM's relaxation order
        self._order = np.zeros(0, dtype=np.int64)
        self._order_key = np.zeros(0, dtype=np.int64)
        self._vt_exps: dict[int, list[int]] = {}
        self._out: dict[int, set[int]] = {}
        self.current_id = 0
        self.prev_id = 0
        self.accum_dx = 0.0
        self.accum_dy = 0.0
        self.accum_facing = math.radians(self.config.exp_initial_em_deg)
        self.accum_time_s = 0.0
        self.relative_rad = 0.0
        self.vt_delta_pc_th = 0.0
        self._cursor = 0
        #: single-link relaxation updates done by the last :meth:`iterate` call
        self.last_relax_updates = 0

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
        """Map poses, shape (n, 3): x (m), y (m), theta (rad, in (-pi, pi]); a copy."""
        return self._exp_pose[: self._n_exp].copy()

    @property
    def pc_coords(self) -> np.ndarray:
        """Pose-cell coordinates (x, y, th) in cells, shape (n, 3); a copy."""
        return self._exp_pc[: self._n_exp].copy()

    @property
    def view_ids(self) -> np.ndarray:
        """Local-view (template) id of each experience, shape (n,); a copy."""
        return self._exp_vt[: self._n_exp].copy()

    @property
    def links(self) -> tuple[np.ndarray, np.ndarray]:
        """``(ends, data)``: int64 (m, 2) from/to ids and float64 (m, 4) d (m), heading, facing (rad), dt (s)."""
        return self._link_ends[: self._n_link].copy(), self._link_data[: self._n_link].copy()

    def current_pose(self) -> tuple[float, float, float]:
        """Map pose (x m, y m, theta rad) of the current experience ((nan,)*3 while empty)."""
        if self._n_exp == 0:
            return (math.nan, math.nan, math.nan)
        p = self._exp_pose[self.current_id]
        return (float(p[0]), float(p[1]), float(p[2]))

    def dead_reckoned_pose(self) -> tuple[float, float, float]:
        """Current experience's map pose plus the odometry accumulated since it (x m, y m, theta rad)."""
        x0, y0 = (0.0, 0.0) if self._n_exp == 0 else (float(self._exp_pose[self.current_id, 0]), float(self._exp_pose[self.current_id, 1]))
        return (x0 + self.accum_dx, y0 + self.accum_dy, clip_rad_180(self.accum_facing))

    def experiences_of_view(self, vt_id: int) -> list[int]:
        """Ids of the experiences created with view ``vt_id``, in creation order."""
        return list(self._vt_exps.get(int(vt_id), []))

    # ------------------------------------------------------------- odometry
    def on_odo(self, vtrans: float, vrot: float, dt: float) -> None:
        """Dead-reckon one odometry reading: rotate first, then translate (OpenRatSLAM ``on_odo``).

        Parameters
        ----------
        vtrans : float
            Forward speed, m/s.
        vrot : float
            Yaw rate, rad/s.
        dt : float
            Duration of the reading, s (>= 0).
        """
        vtrans, vrot, dt = float(vtrans), float(vrot), float(dt)
        for name, value in (("vtrans", vtrans), ("vrot", vrot), ("dt", dt)):
            if not math.isfinite(value):
                raise InvalidInputError(f"{name} must be finite, got {value!r}; drop or repair the odometry sample")
        if dt < 0:
            raise InvalidInputError(f"dt must be >= 0 s, got {dt!r}")
        dist = vtrans * dt
        self.accum_facing = clip_rad_180(self.accum_facing + vrot * dt)
        self.accum_dx = self.accum_dx + dist * math.cos(self.accum_facing)
        self.accum_dy = self.accum_dy + dist * math.sin(self.accum_facing)
        self.accum_time_s += dt

    # ------------------------------------------------------- action (get_action)
    def _delta_pc(self, best: tuple[float, float, float], ids: np.ndarray) -> np.ndarray:
        """Wrapped pose-cell distances (cells) between the packet and experiences ``ids``."""
        nxy, nth = float(self.config.pc_dim_xy), float(self.config.pc_dim_th)
        th_corr = best[2] - self.vt_delta_pc_th
        if th_corr < 0:
            th_corr = nth + th_corr
        if th_corr >= nth:
            th_corr = th_corr - nth
        pc = self._exp_pc[ids]
        d = np.abs(np.array((best[0], best[1], th_corr)) - pc)  # (k, 3): |dx|, |dy|, |dth|
        d = np.minimum(d, np.array((nxy, nxy, nth)) - d)  # wrapped, Eq 2.22
        d *= d
        return np.sqrt(d[:, 0] + d[:, 1] + d[:, 2])

    def update(
        self,
        best_pc: tuple[float, float, float],
        vt_id: int,
        prev_vt_id: int,
        *,
        relative_rad: float = 0.0,
        vt_delta_pc_th: float | None = None,
    ) -> ExperienceUpdate:
        """Choose the experience for the decoded packet and view, then relax (OpenRatSLAM ``get_action``).

        Parameters
        ----------
        best_pc : (float, float, float)
            Decoded packet (x, y, th) in pose cells (OpenRatSLAM ``find_best``).
        vt_id : int
            Current view (template) id, >= 0.
        prev_vt_id : int
            View id of the previous view update.
        relative_rad : float
            Relative view rotation (rad) of a panoramic match (0 otherwise); stored
            in a new link's facing and in the dead-reckoned facing after a switch.
        vt_delta_pc_th : float, optional
            Theta offset (cells) of the last injection (OpenRatSLAM ``vt_delta_pc_th``);
            unchanged when omitted.

        Returns
        -------
        ExperienceUpdate
        """
        bx, by, bth = (float(v) for v in best_pc)
        if not all(math.isfinite(v) for v in (bx, by, bth)):
            raise InvalidInputError(f"best_pc must be finite pose-cell coordinates, got {best_pc!r}")
        vt_id, prev_vt_id = int(vt_id), int(prev_vt_id)
        if vt_id < 0:
            raise InvalidInputError(f"vt_id must be >= 0, got {vt_id}")
        if not math.isfinite(relative_rad):
            raise InvalidInputError(f"relative_rad must be finite, got {relative_rad!r}")
        if vt_delta_pc_th is not None:
            self.vt_delta_pc_th = float(vt_delta_pc_th)
        best = (bx, by, bth)
        src = self.current_id if self._n_exp else -1
        thr = self.config.exp_delta_pc_threshold
        exps = self._vt_exps.get(vt_id)
        if self._n_exp == 0 or not exps:
            self._create(best, vt_id)
            result = ExperienceUpdate(Action.CREATE_NODE, self.current_id, src, False, self._n_exp > 1)
        else:
            delta = float(self._delta_pc(best, np.array([self.current_id]))[0])
            if not (delta > thr or vt_id != prev_vt_id):
                return ExperienceUpdate(Action.NO_ACTION, self.current_id, src, False, False)
            ids = np.array([e for e in exps if e != self.current_id], dtype=np.int64)
            matched = -1
            if ids.size:
                deltas = self._delta_pc(best, ids)
                k = int(np.argmin(deltas))
                if deltas[k] < thr:
                    matched = int(ids[k])
            if matched == -1:
                self._create(best, vt_id)
                result = ExperienceUpdate(Action.CREATE_NODE, self.current_id, src, False, True)
            else:
                added = self._add_link(self.current_id, matched, relative_rad)
                self._set_current(matched, relative_rad)
                result = ExperienceUpdate(Action.CREATE_EDGE, matched, src, True, added)
        self.iterate()
        return result

    def _create(self, best: tuple[float, float, float], vt_id: int) -> None:
        """OpenRatSLAM ``create_experience`` + ``on_create_experience`` + ``on_set_experience(new, 0)``."""
        n = self._n_exp
        self._exp_pc = _grow(self._exp_pc, n + 1)
        self._exp_vt = _grow(self._exp_vt, n + 1)
        self._exp_pose = _grow(self._exp_pose, n + 1)
        base = self._exp_pose[self.current_id] if n else np.zeros(3)
        self._exp_pose[n] = (base[0] + self.accum_dx, base[1] + self.accum_dy, clip_rad_180(self.accum_facing))
        self._exp_pc[n] = best
        self._exp_vt[n] = vt_id
        self._n_exp = n + 1
        self._vt_exps.setdefault(vt_id, []).append(n)
        if n:
            self._add_link(self.current_id, n, 0.0)
        self._set_current(n, 0.0)

    def _add_link(self, id_from: int, id_to: int, rel_rad: float) -> bool:
        """OpenRatSLAM ``on_create_link``: add a link unless one exists in either direction."""
        if id_to in self._out.get(id_from, ()) or id_from in self._out.get(id_to, ()):
            return False
        m = self._n_link
        self._link_ends = _grow(self._link_ends, m + 1)
        self._link_data = _grow(self._link_data, m + 1)
        th_from = float(self._exp_pose[id_from, 2])
        self._link_ends[m] = (id_from, id_to)
        self._link_data[m] = (
            math.sqrt(self.accum_dx * self.accum_dx + self.accum_dy * self.accum_dy),
            signed_delta_rad(th_from, math.atan2(self.accum_dy, self.accum_dx)),
            signed_delta_rad(th_from, clip_rad_180(self.accum_facing + rel_rad)),
            self.accum_time_s,
        )
        self._n_link = m + 1
        self._out.setdefault(id_from, set()).add(id_to)
        key = id_from * (1 << 32) + m
        pos = int(np.searchsorted(self._order_key, key))
        self._order_key = np.insert(self._order_key, pos, key)
        self._order = np.insert(self._order, pos, m)
        return True

    def _set_current(self, new_id: int, rel_rad: float) -> None:
        """OpenRatSLAM ``on_set_experience``.

        Faithful quirk: setting the experience that is already current changes
        nothing, so after the very first experience (id 0 == initial current id)
        the dead-reckoning accumulators are *not* reset.
        """
        if new_id == self.current_id:
            return
        self.prev_id = self.current_id
        self.current_id = new_id
        self.accum_dx = 0.0
        self.accum_dy = 0.0
        self.accum_facing = clip_rad_180(float(self._exp_pose[new_id, 2]) + rel_rad)
        if not self.config.link_time_since_start:
            self.accum_time_s = 0.0
        self.relative_rad = rel_rad

    # ------------------------------------------------------------ relaxation
    def iterate(self, n_updates: int | None = None) -> int:
        """Relax the map (Eq 2.25, OpenRatSLAM ``iterate``); returns the number of link updates done.

        Parameters
        ----------
        n_updates : int, optional
            Single-link updates to perform. Default: ``exp_loops * n_links``
            capped at ``relax_budget`` (see the module docstring).
        """
        m = self._n_link
        self.last_relax_updates = 0
        if m == 0:
            return 0
        full = self.config.exp_loops * m
        if n_updates is None:
            budget = self.config.relax_budget
            if budget is None or full <= budget:
                n_updates, start = full, 0
            else:
                n_updates, start = budget, self._cursor % m
        else:
            start = self._cursor % m
        if n_updates <= 0:
            return 0
        end = _relax_kernel()(
            self._order, self._link_ends, self._link_data, self._exp_pose, float(self.config.exp_correction), int(n_updates), int(start)
        )
        self._cursor = int(end)
        self.last_relax_updates = int(n_updates)
        return int(n_updates)

    # --------------------------------------------------------------- export
    def to_networkx(self) -> "nx.DiGraph":
        """The map as a :class:`networkx.DiGraph` (a snapshot).

        Nodes are experience ids with :class:`ExperienceAttrs`; edges are links
        (from -> to) with :class:`LinkAttrs`. Graph attribute ``current_id``.
        """
        import networkx as nx

        g = nx.DiGraph(current_id=int(self.current_id) if self._n_exp else -1)
        for i in range(self._n_exp):
            pc, pose = self._exp_pc[i], self._exp_pose[i]
            attrs: ExperienceAttrs = {
                "x_pc": float(pc[0]), "y_pc": float(pc[1]), "th_pc": float(pc[2]), "vt_id": int(self._exp_vt[i]),
                "x_m": float(pose[0]), "y_m": float(pose[1]), "th_rad": float(pose[2]),
            }
            g.add_node(i, **attrs)
        for k in range(self._n_link):
            ld = self._link_data[k]
            link: LinkAttrs = {
                "link_id": k, "d_m": float(ld[0]), "heading_rad": float(ld[1]), "facing_rad": float(ld[2]), "dt_s": float(ld[3]),
            }
            g.add_edge(int(self._link_ends[k, 0]), int(self._link_ends[k, 1]), **link)
        return g

    # ----------------------------------------------------------- save / load
    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The whole map as named arrays (the ``.npz`` fields of the module docstring, names prefixed)."""
        arrays = {
            "format": np.int64(FORMAT_VERSION),
            "config": np.array(json.dumps(asdict(self.config))),
            "exp_pc": self._exp_pc[: self._n_exp].copy(),
            "exp_vt": self._exp_vt[: self._n_exp].copy(),
            "exp_pose": self._exp_pose[: self._n_exp].copy(),
            "link_ends": self._link_ends[: self._n_link].copy(),
            "link_data": self._link_data[: self._n_link].copy(),
            "state_f": np.array([self.accum_dx, self.accum_dy, self.accum_facing, self.accum_time_s, self.relative_rad, self.vt_delta_pc_th]),
            "state_i": np.array([self.current_id, self.prev_id, self._cursor], dtype=np.int64),
        }
        return {prefix + k: np.asarray(v) for k, v in arrays.items()}

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the map to ``path`` (``.npz``, format in the module docstring); bit-exact round trip."""
        np.savez(path, **self.to_arrays())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "ExperienceMap":
        """Read a map written by :meth:`save`.

        Raises
        ------
        CorruptFileError
            When the file is unreadable or a field is missing or has the wrong type,
            shape or value (named in the error).
        """
        try:
            archive = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise CorruptFileError(f"cannot be read as an .npz archive ({exc})", path=path) from exc
        if not hasattr(archive, "files"):
            raise CorruptFileError("holds a single array, not an .npz archive", path=path)
        with archive:
            return cls.from_arrays(archive)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> "ExperienceMap":
        """Rebuild a map from :meth:`to_arrays` output (e.g. an open ``.npz`` archive).

        Raises
        ------
        CorruptFileError
            A field is missing or has the wrong type, shape or value (named in the error).
        """

        def field(name: str, kind: str, shape: tuple[int | None, ...]) -> np.ndarray:
            key = prefix + name
            if key not in arrays:
                raise CorruptFileError("missing", field=key)
            try:
                arr = np.asarray(arrays[key])
            except Exception as exc:  # zip/CRC/header errors of a damaged member
                raise CorruptFileError(f"unreadable ({exc})", field=key) from exc
            if arr.dtype.kind != kind:
                raise CorruptFileError(f"dtype {arr.dtype} where kind {kind!r} is required", field=key)
            if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
                raise CorruptFileError(f"shape {arr.shape} where {shape} is required (None = any)", field=key)
            if kind == "f" and not np.all(np.isfinite(arr)):
                raise CorruptFileError("holds NaN or infinite values", field=key)
            return arr

        version = int(field("format", "i", ()))
        if version != FORMAT_VERSION:
            raise CorruptFileError(f"version {version}, this library reads version {FORMAT_VERSION}", field=prefix + "format")
        try:
            config = ExperienceMapConfig(**json.loads(str(field("config", "U", ()))))
        except (json.JSONDecodeError, TypeError, InvalidInputError) as exc:
            raise CorruptFileError(f"not a valid ExperienceMapConfig JSON ({exc})", field=prefix + "config") from exc
        exp_pc = field("exp_pc", "f", (None, 3))
        n = exp_pc.shape[0]
        exp_vt = field("exp_vt", "i", (n,))
        exp_pose = field("exp_pose", "f", (n, 3))
        link_ends = field("link_ends", "i", (None, 2))
        m = link_ends.shape[0]
        link_data = field("link_data", "f", (m, 4))
        state_f = field("state_f", "f", (6,))
        state_i = field("state_i", "i", (3,))
        if np.any(exp_vt < 0):
            raise CorruptFileError("negative view id", field=prefix + "exp_vt")
        if m and (link_ends.min() < 0 or link_ends.max() >= n):
            raise CorruptFileError(f"link end outside the {n} experiences", field=prefix + "link_ends")
        if n and not (0 <= state_i[0] < n and 0 <= state_i[1] < n):
            raise CorruptFileError(f"current/previous id {state_i[:2].tolist()} outside the {n} experiences", field=prefix + "state_i")
        if state_i[2] < 0:
            raise CorruptFileError("negative relaxation cursor", field=prefix + "state_i")
        em = cls(config)
        em._n_exp, em._n_link = n, m
        em._exp_pc = _grow(np.array(exp_pc, dtype=np.float64), n)
        em._exp_vt = _grow(np.array(exp_vt, dtype=np.int64), n)
        em._exp_pose = _grow(np.array(exp_pose, dtype=np.float64), n)
        em._link_ends = _grow(np.array(link_ends, dtype=np.int64), m)
        em._link_data = _grow(np.array(link_data, dtype=np.float64), m)
        for i, v in enumerate(exp_vt.tolist()):
            em._vt_exps.setdefault(v, []).append(i)
        for k, (f, t) in enumerate(link_ends.tolist()):
            if t in em._out.get(f, ()) or f in em._out.get(t, ()):
                raise CorruptFileError(f"duplicate link {f}->{t} at row {k}", field=prefix + "link_ends")
            em._out.setdefault(f, set()).add(t)
        keys = link_ends[:, 0].astype(np.int64) * (1 << 32) + np.arange(m, dtype=np.int64)
        em._order = np.argsort(keys, kind="stable").astype(np.int64)
        em._order_key = keys[em._order]
        (em.accum_dx, em.accum_dy, em.accum_facing, em.accum_time_s, em.relative_rad, em.vt_delta_pc_th) = (
            float(v) for v in state_f
        )
        em.current_id, em.prev_id, em._cursor = (int(v) for v in state_i)
        return em
