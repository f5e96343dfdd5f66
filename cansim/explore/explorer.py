"""The active-exploration loop (thesis Ch.6, Sec 6.1): whisk, recognise, search, place, move.

One iteration = one whisk:

1. read the end-effector pose from the :class:`~whisker_io.hw.arm.Arm` (a
   :class:`~whisker_io.hw.arm.SimArm` in simulation, a :class:`~whisker_io.hw.arm.URArm`
   on hardware) and whisk there (a ``sensor(pose) -> RegionFeatures`` callable: the
   simulated :class:`~whisker_io.sim.whisk_chain.WhiskChain` or the USB array through
   :class:`~whisker_io.sim.whisk_chain.RecordedChain`);
2. odometry from the previous pose (``odometry(prev, now) -> (v, omega, dt)``: Eq 6.4-6.11
   noise in simulation, exact on the arm) into one WhiskerRatSLAM per known object,
   each holding that object's map (:meth:`KnownObject.exploring_model`; the object maps
   are not linked);
3. a re-localisation of model ``k`` to an experience of its built map is an impulse into
   ``k``'s leaky integrator (:class:`maps.recognition.LeakyIntegrator`); the integrated
   confidence (IC) decides the identity;
4. the goal: contact seeking's when it is on (:mod:`cansim.explore.contact_seeking`, opt-in: back
   off when the contacts lie nearer than the SPC band, advance along the array's axis
   after a whisk without contact, turn toward fewer than ``mu`` contacts, and keep every
   goal clear of the whisk's contacts), else the
   surface placement controller's correction while it has one (at most
   ``max_adjustments`` per region, back-offs and turns included), else the active
   strategy's proposal (:func:`cansim.explore.search.active_strategy`); the default
   search's next face comes in to the range where contact was last held;
5. ``arm.move_linear(goal)``: every command passes the arm's
   :class:`~whisker_io.hw.safety.SafetyEnvelope`; a refused command is logged and counted,
   the strategy drops its target and the explorer re-plans with the default search (at
   most ``max_replans`` times per iteration), never bypassing the envelope.

The run stops when an IC reaches ``stop_threshold``, after ``max_iterations`` or after
``time_limit_s`` of wall-clock time. :meth:`Explorer.replay` runs steps 2-3 of the same
code over recorded ``(pose, features)`` cycles (:func:`whisker_io.hw.recorder.replay_session`
with a ``RecordedChain``).

Object maps (:func:`build_object_model`): two loops over the faces of the ellipsoid fitted
to the object (:meth:`cansim.explore.search.DefaultSearch.tour`), the SPC at every face
until its conditions are met (at most 10 adjustments), pose-consistent matching (one
object mapped in one frame, :meth:`cansim.models.whisker_ratslam.WhiskerRatSLAMConfig.mapping`).

Decisions for recognition (the thesis is silent; measured in
``examples/ch6_active_exploration.py``, whose docstring gives the figures):

* **One model per map**, not one model holding the appended history (Fig 5.16,
  :meth:`WhiskerRatSLAM.library` of all maps, one region match per whisk across every
  object): each map keeps its own current experience, the frame through which FEH and
  LSR carry their targets into the world. In a trial both gave the correct identity
  first at IC 300 in 7 of 8 runs (default search, noise 0.3, seeds 0-3, 1000 whisks;
  the final exploring copy below then gave 8 of 8).
* **The exploring copy** (:meth:`KnownObject.exploring_model`): the array meets an
  object in an unknown frame, so the copy has no pose prior and its pose cells start
  at the initial packet (:meth:`WhiskerRatSLAM.library` of the map alone), and a
  whisk that matches a stored region (Eq 5.5) re-localises to that region's experience
  nearest the packet whatever the pose-cell distance (``match_distance_cells`` =
  :func:`any_distance_cells`). With the map's 1-cell rule the packet is rarely within a
  cell of the stored location (the pose cells do not hold a pose consistent with the
  map's frame, :mod:`cansim.models.whisker_ratslam`): of 186 matches to the right object's
  stored regions 27 re-localised, the rest made new experiences (11 matches to the other
  object's; 400 whisks, seeds 0-1), and no IC reached 100 in 1000 whisks (8 runs).
"""

from __future__ import annotations

import io
import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from cansim.errors import ConfigError, CorruptFileError, InvalidInputError
from cansim.explore.contact_seeking import (
    ContactSeekingParams, clear_of_contacts, contact_range_m, held_face_pose, seek_contact,
)
from cansim.explore.placement import PlacementParams, place
from cansim.explore.search import (
    STRATEGIES, DefaultSearch, ObjectView, SearchContext, active_strategy, make_strategy,
)
from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig
from maps.odometry import SpatialOdometry
from maps.recognition import MATCHERS, LeakyIntegrator, first_crossing, leaky_step
from maps.surface_match import SurfaceLibrary, SurfaceMatchConfig, SurfaceMatcher
from whisker_io.errors import SafetyViolationError
from whisker_io.features.region import MIN_OBSERVATION_CONTACTS
from whisker_io.persistence import naming_file, read_npz, write_npz
from whisker_io.pose import Pose
from whisker_io.validation import config_field, finite_array, scale_factor

__all__ = ["KnownObject", "any_distance_cells", "build_object_model", "Explorer", "ExplorationResult", "ic_metrics", "ICMetrics"]

_LOG = logging.getLogger(__name__)

Sensor = Callable[[Pose], object]
Odometry = Callable[[Pose, Pose], tuple[np.ndarray, np.ndarray, float]]


@dataclass
class KnownObject:
    """A mapped object: its model after mapping and the sizes of what mapping stored.

    Attributes
    ----------
    name : str
    model : WhiskerRatSLAM
    n_built, n_built_regions, n_history : int
        Experiences, regions and history length after mapping.
    poses : list of Pose
        The true whisk poses of the mapping run (world).
    mapping_log : dict or None
        What :func:`build_object_model` recorded of each mapping whisk (``odometry``,
        ``exp_ids``, ``relocalised``, ``contacts``): the input of :meth:`stored_surface`.
    odometry_scale : float
        The mapping odometry's noise as a multiple of Eq 6.4-6.11's (default 1): the odometry
        edges of :meth:`stored_surface`'s pose graph
        (:meth:`maps.pose_graph.WhiskGraphConfig.for_odometry_scale`).

    :meth:`save` writes all of it to one ``.npz`` file and :meth:`load` reads it back (or
    a bare model file, without poses and log).
    """

    name: str
    model: WhiskerRatSLAM
    n_built: int
    n_built_regions: int
    n_history: int
    poses: list[Pose] = field(default_factory=list)
    mapping_log: dict[str, list] | None = field(default=None, repr=False)
    odometry_scale: float = 1.0
    _snapshot: dict[str, np.ndarray] | None = field(default=None, repr=False)
    _surface: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        scale_factor(self.odometry_scale, f"{self.name}: odometry_scale", " (a multiple of Eq 6.4-6.11's odometry noise)")

    def stored_surface(self) -> tuple[np.ndarray, np.ndarray]:
        """What mapping felt, in the world frame: contact points and where each was felt from, (n, 3) m each.

        The mapping whisks' poses are optimised as a pose graph from their odometry and the
        map's own re-localisations (:func:`maps.pose_graph.whisk_surface`) and anchored at
        the first mapping pose (the arm's pose when mapping began). Computed once.

        Raises
        ------
        ConfigError
            The object was not mapped by :func:`build_object_model` (no mapping log).
        """
        if self._surface is None:
            from maps.pose_graph import WhiskGraphConfig, whisk_surface

            log = self.mapping_log
            if log is None or not self.poses:
                raise ConfigError(f"{self.name}: no mapping log to place a stored surface by; map it with build_object_model")
            graph = WhiskGraphConfig().for_odometry_scale(self.odometry_scale)
            self._surface = whisk_surface(log["odometry"], log["exp_ids"], log["relocalised"], log["contacts"], graph,
                                          with_viewpoints=True, anchor=self.poses[0])
        return self._surface

    def mapping_observations(self) -> tuple[int, int] | None:
        """``(whisks that observed a region, mapping whisks)`` of the mapping run, or None without a mapping log.

        A whisk observes a region with 3 contacts or more (Eq 5.5,
        :data:`whisker_io.features.region.MIN_OBSERVATION_CONTACTS`); a map whose whisks
        seldom did (:meth:`seldom_observed`) is sparse and seldom re-localised, so its stored surface
        is only as good as the mapping odometry.
        """
        if self.mapping_log is None:
            return None
        contacts = self.mapping_log["contacts"]
        return sum(c is not None and len(c) >= MIN_OBSERVATION_CONTACTS for c in contacts), len(contacts)

    def seldom_observed(self) -> bool:
        """Whether under :data:`SELDOM_OBSERVED_SHARE` of the mapping whisks observed a region (False without a log)."""
        seen = self.mapping_observations()
        return seen is not None and seen[0] < SELDOM_OBSERVED_SHARE * seen[1]

    def _model_arrays(self) -> dict[str, np.ndarray]:
        """The model's ``.npz`` members as mapping left it (taken once)."""
        if self._snapshot is None:
            buf = io.BytesIO()
            self.model.save(buf)  # type: ignore[arg-type]
            buf.seek(0)
            with np.load(buf, allow_pickle=False) as z:
                self._snapshot = {k: z[k] for k in z.files}
        return self._snapshot

    def fresh_model(self) -> WhiskerRatSLAM:
        """An independent copy of the model as mapping left it (through its ``.npz`` save format)."""
        return WhiskerRatSLAM.from_arrays(self._model_arrays())  # type: ignore[return-value]

    def save(self, path: str | os.PathLike[str]) -> None:
        """Save the mapped object - its model, mapping poses and mapping log - to one ``.npz`` file.

        The file is a :meth:`WhiskerRatSLAM.save` file (``WhiskerRatSLAM.load`` reads its
        model) with the object's own members beside the model's (prefix ``known_``):
        ``known_name``, ``known_sizes`` (``n_built``, ``n_built_regions``, ``n_history``),
        ``known_poses`` (n, 7: position m, quaternion x, y, z, w), ``known_odometry_scale`` (a
        file without it is read as 1), and, when the object
        was mapped by :func:`build_object_model`, its mapping log: ``known_odometry``
        (n, 7: v m/s, omega rad/s, dt s), ``known_exp_ids`` (n,), ``known_relocalised``
        (n,), ``known_contact_counts`` (n,; -1 for a whisk without a contact array) and
        ``known_contacts`` (sum of the counts, 3; m, end-effector frame). :meth:`load`
        gives back an object whose :meth:`stored_surface` and :meth:`fresh_model` are
        those of this one. Written to a temporary name and renamed (no half-written file); as
        :func:`numpy.savez`, ``.npz`` is added to a name without it.
        No pickle.

        Raises
        ------
        InvalidInputError, ShapeError
            Sizes that are not counts, poses that are not Pose objects, a mapping log that
            is not one entry per mapping pose, odometry that is not SpatialOdometry,
            malformed contact points (nothing is written).
        """
        sizes = (self.n_built, self.n_built_regions, self.n_history)
        self.__post_init__()  # the fields may have been set after construction
        if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 0 for v in sizes):
            raise InvalidInputError(f"{self.name}: n_built, n_built_regions and n_history must be counts >= 0, got {sizes}")
        if not all(isinstance(p, Pose) for p in self.poses):
            raise InvalidInputError(f"{self.name}: poses must be Pose objects")
        log = self.mapping_log
        contacts: list[np.ndarray | None] = []
        if log is not None:  # checked before anything is written: a file that could not be loaded back is never made
            try:
                lengths = {key: len(log[key]) for key in ("odometry", "exp_ids", "relocalised", "contacts")}
            except (KeyError, TypeError) as exc:
                raise InvalidInputError(f"{self.name}: mapping_log needs odometry, exp_ids, relocalised and contacts lists ({exc})") from None
            if set(lengths.values()) != {len(self.poses)}:
                raise InvalidInputError(f"{self.name}: the mapping log needs one entry per mapping pose ({len(self.poses)}), "
                                        f"got {lengths}")
            if not all(isinstance(o, SpatialOdometry) for o in log["odometry"]):
                raise InvalidInputError(f"{self.name}: mapping_log['odometry'] must hold SpatialOdometry samples")
            contacts = [None if c is None else finite_array(c, (None, 3), f"mapping_log['contacts'][{k}]")
                        for k, c in enumerate(log["contacts"])]
        arrays: dict[str, np.ndarray] = dict(self._model_arrays())
        arrays["known_format"] = np.int64(_KNOWN_FORMAT)
        arrays["known_name"] = np.array(str(self.name))
        arrays["known_sizes"] = np.array(sizes, dtype=np.int64)
        arrays["known_odometry_scale"] = np.float64(self.odometry_scale)
        arrays["known_poses"] = np.array([np.r_[p.position_m, p.quaternion_xyzw] for p in self.poses],
                                         dtype=np.float64).reshape(-1, 7)
        if log is not None:
            odo = [np.r_[o.v, o.omega, o.dt] for o in log["odometry"]]
            arrays["known_odometry"] = np.array(odo, dtype=np.float64).reshape(-1, 7)
            arrays["known_exp_ids"] = np.asarray(log["exp_ids"], dtype=np.int64).reshape(-1)
            arrays["known_relocalised"] = np.asarray(log["relocalised"], dtype=bool).reshape(-1)
            arrays["known_contact_counts"] = np.array([-1 if c is None else len(c) for c in contacts], dtype=np.int64)
            arrays["known_contacts"] = np.concatenate([np.zeros((0, 3))] + [c for c in contacts if c is not None])
        write_npz(path, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str], name: str | None = None) -> "KnownObject":
        """A mapped object from :meth:`save`'s file, or from a bare :meth:`WhiskerRatSLAM.save` file.

        Parameters
        ----------
        path : path
        name : str, optional
            The object's name (default: the saved one; required for a bare model file).

        Returns
        -------
        KnownObject
            From a bare model file: no mapping poses and no mapping log (:meth:`stored_surface`
            then raises ConfigError; ``matcher="surface"`` needs a file written by :meth:`save`).

        Raises
        ------
        CorruptFileError
            Unreadable file, a missing or malformed member (named in the error).
        InvalidInputError
            A bare model file without ``name``.
        """
        arrays = read_npz(path)
        with naming_file(path):  # a fault met while rebuilding names the file
            model = WhiskerRatSLAM.from_arrays(arrays)
        if not isinstance(model, WhiskerRatSLAM):
            raise CorruptFileError(f"holds a {type(model).__name__}, not a WhiskerRatSLAM", path=path, field="model")
        om = model.object_map
        if not any(k.startswith("known_") for k in arrays):
            if name is None:
                raise InvalidInputError(f"{path}: a bare model file; give the object's name (load(path, name=...))")
            return cls(str(name), model, om.n_experiences, len(model.frontend), len(om.history))
        fields = _known_fields(arrays, path)
        obj = cls(str(fields["name"]) if name is None else str(name), model, *fields["sizes"], fields["poses"],
                  fields["log"], fields["odometry_scale"])
        obj._snapshot = {k: v for k, v in arrays.items() if not k.startswith("known_")}
        return obj

    def exploring_model(self) -> WhiskerRatSLAM:
        """The model that recognises this object while an unknown object is explored (module docstring).

        :meth:`WhiskerRatSLAM.library` of a :meth:`fresh_model` alone: the pose cells at
        the initial packet, every region's decay at the floor, no pose prior (the array
        is brought to an object in an unknown frame), and the map re-localising to the
        matched region's experience nearest the packet at any pose-cell distance
        (``match_distance_cells`` beyond the grid's largest wrapped distance,
        :func:`any_distance_cells`). Experience and region ids are the map's own.

        Raises
        ------
        InvalidInputError
            The map holds no experience (no mapping whisk observed a region).
        """
        m = self.fresh_model()
        if m.object_map.n_experiences == 0:
            raise InvalidInputError(
                f"the map of {self.name!r} holds no experience: none of its {len(self.poses)} mapping whisks observed a "
                "region (3 contacts or more), so nothing can be recognised as it. Map it along a path that touches it "
                "(a flat or thin object passes between the array's rows of whiskers; a mesh in millimetres or lying on "
                "its side is out of reach: check its units and up axis) or leave it out")
        cfg = replace(m.config, match_distance_cells=any_distance_cells(m.config.shape))
        return WhiskerRatSLAM.library([m], [self.name], cfg)[0]


#: Share of its mapping whisks that observed a region under which a map is called seldom observed
#: (:meth:`KnownObject.seldom_observed`; the studies' seldom-touched rule, more often than not).
SELDOM_OBSERVED_SHARE = 0.5
#: Layout version of the ``known_`` members of :meth:`KnownObject.save`.
_KNOWN_FORMAT = 1
#: The members of a saved mapping log (:meth:`KnownObject.save`).
_LOG_MEMBERS = ("known_odometry", "known_exp_ids", "known_relocalised", "known_contact_counts", "known_contacts")


def _known_fields(arrays: dict[str, np.ndarray], path: Any) -> dict[str, Any]:
    """The ``known_`` members of a :meth:`KnownObject.save` file, checked (CorruptFileError naming the member)."""

    def need(key: str) -> np.ndarray:
        if key not in arrays:
            raise CorruptFileError("missing", path=path, field=key)
        return np.asarray(arrays[key])

    fmt = need("known_format")
    if fmt.shape != () or fmt.dtype.kind != "i" or int(fmt) != _KNOWN_FORMAT:
        raise CorruptFileError(f"layout {fmt.tolist()!r}, this version reads {_KNOWN_FORMAT}", path=path, field="known_format")
    name = need("known_name")
    if name.shape != () or name.dtype.kind != "U":
        raise CorruptFileError("expected one string", path=path, field="known_name")
    sizes = need("known_sizes")
    if sizes.shape != (3,) or sizes.dtype.kind != "i" or sizes.min() < 0:
        raise CorruptFileError("expected 3 counts >= 0", path=path, field="known_sizes")
    raw = need("known_poses")
    if raw.ndim != 2 or raw.shape[1] != 7 or raw.dtype.kind != "f":
        raise CorruptFileError(f"expected (n, 7) floats, got {raw.shape} {raw.dtype}", path=path, field="known_poses")
    try:
        poses = [Pose(r[:3], r[3:]) for r in raw]
    except (InvalidInputError, ValueError) as exc:
        raise CorruptFileError(str(exc), path=path, field="known_poses") from exc
    log = None
    if any(k in arrays for k in _LOG_MEMBERS):  # a log is all of its members or none
        n = len(poses)
        odo = need("known_odometry")
        if odo.shape != (n, 7) or odo.dtype.kind != "f":
            raise CorruptFileError(f"expected ({n}, 7) floats (one per mapping pose), got {odo.shape}", path=path,
                                   field="known_odometry")
        try:
            odometry = [SpatialOdometry(r[:3], r[3:6], float(r[6])) for r in odo]
        except (InvalidInputError, ValueError) as exc:
            raise CorruptFileError(str(exc), path=path, field="known_odometry") from exc
        ids, rel, counts = need("known_exp_ids"), need("known_relocalised"), need("known_contact_counts")
        for key, a, kind in (("known_exp_ids", ids, "i"), ("known_relocalised", rel, "b"), ("known_contact_counts", counts, "i")):
            if a.shape != (n,) or a.dtype.kind != kind:
                raise CorruptFileError(f"expected {n} values of kind {kind!r}, got {a.shape} {a.dtype}", path=path, field=key)
        pts = need("known_contacts")
        if counts.size and counts.min() < -1:
            raise CorruptFileError("counts must be >= -1 (-1: no contact array)", path=path, field="known_contact_counts")
        total = int(np.sum(np.maximum(counts, 0)))
        if pts.shape != (total, 3) or pts.dtype.kind != "f" or not np.isfinite(pts).all():
            raise CorruptFileError(f"expected ({total}, 3) finite floats (the counts' sum), got {pts.shape}", path=path,
                                   field="known_contacts")
        contacts: list[np.ndarray | None] = []
        at = 0
        for c in counts.tolist():
            contacts.append(None if c < 0 else pts[at:at + c].copy())
            at += max(c, 0)
        log = {"odometry": odometry, "exp_ids": [int(v) for v in ids], "relocalised": [bool(v) for v in rel],
               "contacts": contacts}
    scale = np.asarray(arrays.get("known_odometry_scale", np.float64(1.0)))  # files before it: Eq 6.4-6.11's noise
    if scale.shape != () or scale.dtype.kind != "f" or not np.isfinite(scale) or float(scale) < 0:
        raise CorruptFileError("expected one finite float >= 0", path=path, field="known_odometry_scale")
    return {"name": str(name), "sizes": [int(v) for v in sizes], "poses": poses, "log": log,
            "odometry_scale": float(scale)}


def any_distance_cells(shape: Sequence[int]) -> float:
    """A match distance (cells) above every wrapped distance on a grid of ``shape``: ``|shape / 2| + 1``.

    Raises
    ------
    InvalidInputError
        ``shape`` is not a non-empty sequence of positive integers.
    """
    try:
        dims = [int(n) for n in shape if not isinstance(n, bool) and math.isfinite(n) and int(n) == n and n > 0]
    except (TypeError, ValueError, OverflowError):
        dims = []
    if not dims or len(dims) != len(shape):
        raise InvalidInputError(f"shape must be positive integers (cells per axis), got {shape!r}")
    return float(math.hypot(*(n / 2.0 for n in dims))) + 1.0


def build_object_model(
    name: str,
    trajectory: Sequence[Pose],
    sensor: Sensor,
    odometry: Odometry,
    *,
    placement: PlacementParams | None = PlacementParams(roll_rad=math.pi / 2),
    adjustments_per_pose: int = 10,
    model: WhiskerRatSLAM | None = None,
    odometry_scale: float = 1.0,
) -> KnownObject:
    """Map an object along ``trajectory`` (two loops over the faces of its fitted ellipsoid), with the SPC.

    Every whisk (the face poses and the SPC's adjustments) is one WhiskerRatSLAM step.

    Parameters
    ----------
    name : str
    trajectory : sequence of Pose
        Whisk poses (world): the thesis' mapping run (Sec 6.1.3.1) is
        ``DefaultSearch(c, r, mesh=mesh, semi_axes_m=fit_surface(mesh).semi_axes_m,
        footprint_m=array.positions_m).tour(2, accept=...)`` (every whisker base 15 mm or more before the
        object; ``accept`` drops the faces the arm cannot take, e.g. under the table, as
        :func:`cansim.studies.ch6_active_exploration.mapping_tour` does with the safety envelope).
    sensor : callable
        ``sensor(pose) -> RegionFeatures``.
    odometry : callable
        ``odometry(prev, now) -> (v, omega, dt)`` in the end-effector frame.
    placement : PlacementParams or None
        SPC parameters (None: SPC off).
    adjustments_per_pose : int
        SPC corrections (extra whisks) at each pose, until its goal is the current pose
        (the SPC's conditions are met) or this many were made (default 10: the physical
        runs' limit, Sec 6.1.4; in simulation the array "moved on to the closest
        unvisited face" once the conditions were met, Sec 6.1.3.1).
    model : WhiskerRatSLAM, optional
        Default ``WhiskerRatSLAM(WhiskerRatSLAMConfig.mapping(cell_size_m=0.03))``: one object
        mapped in one frame (pose-consistent matching, see :mod:`cansim.models.whisker_ratslam`).
    odometry_scale : float
        How noisy ``odometry`` is, as a multiple of Eq 6.4-6.11's (default 1; 0: exact): kept as
        :attr:`KnownObject.odometry_scale` for the stored surface's pose graph.

    Notes
    -----
    A map is only as good as its loop closures: the experience poses are the odometry
    corrected at re-localisations. A mapping run in which no whisk re-localised is dead
    reckoning (a warning says so); under Eq 6.4-6.11's noise its stored surface
    (:meth:`KnownObject.stored_surface`) lies centimetres to decimetres from the object,
    and the surface matcher then matches it poorly.
    """
    if not isinstance(name, str) or not name.strip():
        raise InvalidInputError(f"name must be a non-empty string (the object's name), got {name!r}")
    if not isinstance(trajectory, Sequence) or not all(isinstance(p, Pose) for p in trajectory):
        raise InvalidInputError(f"trajectory must be a sequence of Pose (e.g. object_trajectory(...)), got "
                                f"{type(trajectory).__name__}")
    if len(trajectory) < 2:
        raise InvalidInputError("a mapping trajectory needs at least 2 poses")
    config_field(adjustments_per_pose, "adjustments_per_pose", int, minimum=0)
    config_field(odometry_scale, "odometry_scale", float, minimum=0.0, hint="a multiple of Eq 6.4-6.11's odometry noise")
    if not callable(sensor) or not callable(odometry):
        raise InvalidInputError("sensor and odometry must be callables: sensor(pose) -> RegionFeatures, "
                                "odometry(prev, now) -> (v, omega, dt)")
    slam = model if model is not None else WhiskerRatSLAM(WhiskerRatSLAMConfig.mapping(cell_size_m=0.03))
    prev: Pose | None = None
    visited: list[Pose] = []
    log: dict[str, list] = {"odometry": [], "exp_ids": [], "relocalised": [], "contacts": []}

    def whisk(pose: Pose) -> object:
        nonlocal prev
        obs = sensor(pose)
        odo = SpatialOdometry(np.zeros(3), np.zeros(3), 1.0) if prev is None else _odometry_of(odometry, prev, pose)
        st = slam.step(odo, obs)
        log["odometry"].append(odo)
        log["exp_ids"].append(int(st.exp_id))
        log["relocalised"].append(bool(st.relocalised))
        log["contacts"].append(_contacts(obs))
        prev = pose
        visited.append(pose)
        return obs

    for pose in trajectory:
        obs = whisk(pose)
        for _ in range(adjustments_per_pose if placement is not None else 0):
            if not getattr(obs, "is_observation", False):
                break
            goal = place(pose, obs.contact_points_m, placement)  # type: ignore[attr-defined]
            if goal == pose:
                break
            pose = goal
            obs = whisk(pose)
    om = slam.object_map
    known = KnownObject(name, slam, om.n_experiences, len(slam.frontend), len(om.history), visited, log,
                        float(odometry_scale))
    observed, whisks = known.mapping_observations() or (0, len(visited))
    seldom = known.seldom_observed()
    if seldom:
        _LOG.warning("only %d of the %d mapping whisks of %r observed a region (3 contacts or more): its map is sparse "
                     "and seldom re-localises, so its stored surface is only as good as the odometry; bring the "
                     "trajectory within the whiskers' reach (placements nearer the surface, contact seeking), and for a "
                     "flat or thin object try another roll of the array", observed, whisks, name)
    if om.n_experiences and not any(log["relocalised"]):
        _LOG.warning("the map of %r closed no loop: none of its %d mapping whisks re-localised, so its poses are dead "
                     "reckoning (under the thesis' odometry noise, centimetres off after a loop) and its stored surface "
                     "is as far off; %s", name, len(visited),
                     "touch it more often (above)" if seldom else
                     "map along a path that comes back to what it felt, at the same poses (two loops or more)")
    return known


def _odometry_of(odometry: Odometry, prev: Pose, now: Pose) -> SpatialOdometry:
    """``odometry(prev, now)`` as a :class:`SpatialOdometry`; a typed error if it is not ``(v, omega, dt)``."""
    if odometry is None:
        raise ConfigError("no odometry to move by: give odometry(prev, now) -> (v, omega, dt)")
    value = odometry(prev, now)
    if isinstance(value, SpatialOdometry):
        return value
    try:
        v, omega, dt = value
        return SpatialOdometry(v, omega, dt)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"odometry(prev, now) must return (v (3,) m/s, omega (3,) rad/s, dt s) in the "
                                f"end-effector frame, got {type(value).__name__}: {exc}") from None


def _touched(obs: object) -> bool:
    """Whether a whisk touched anything: contact points, or an observation of another kind (a test double's)."""
    return _contacts(obs) is not None or (obs is not None and not hasattr(obs, "contact_points_m"))


def _contacts(obs: object) -> np.ndarray | None:
    """A whisk's contact points in the end-effector frame, (k, 3) m (also below a region's ``mu``), or None."""
    pts = getattr(obs, "contact_points_m", None)
    if pts is None:
        return None
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    return pts if len(pts) else None


@dataclass(frozen=True)
class ICMetrics:
    """Ch.6 metrics of one IC trace at one threshold (Sec 6.2).

    Attributes
    ----------
    identity : int or None
        First object whose IC reached the threshold (ties: the larger IC, then the lower index).
    im : float
        Identity Margin ``t(first incorrect IC >= thr) - t(correct IC >= thr)``, censored
        at the run's end (``n dt``) for a crossing that never happened.
    srt : float
        Successful Recognition Time ``t(correct IC >= thr)``, censored likewise.
    correct_first : bool
        The correct identity crossed, and before every other.
    """

    identity: int | None
    im: float
    srt: float
    correct_first: bool


def ic_metrics(ic: np.ndarray, correct: int, threshold: float, dt: float = 1.0) -> ICMetrics:
    """IM, SRT and the decision from an IC trace (n, n_objects); see :class:`ICMetrics`."""
    a = np.asarray(ic, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] < 1:
        raise InvalidInputError(f"ic must be (n, n_objects), got {a.shape}")
    if not np.isfinite(a).all():
        raise InvalidInputError("ic must be finite")
    if isinstance(correct, bool) or not isinstance(correct, (int, np.integer)) or not 0 <= correct < a.shape[1]:
        raise InvalidInputError(f"correct must be an object index in [0, {a.shape[1]}), got {correct!r}")
    if not (math.isfinite(threshold) and threshold > 0 and math.isfinite(dt) and dt > 0):
        raise InvalidInputError(f"threshold and dt must be finite and > 0, got {threshold!r}, {dt!r}")
    n = len(a)
    times = [first_crossing(a[:, k], threshold) for k in range(a.shape[1])]
    end = n * dt
    t_ok = times[correct]
    bad = [t for k, t in enumerate(times) if k != correct and t is not None]
    t_bad = min(bad) if bad else None
    srt = end if t_ok is None else t_ok * dt
    im = (end if t_bad is None else t_bad * dt) - srt
    hits = [(t, -a[t, k], k) for k, t in enumerate(times) if t is not None]
    identity = min(hits)[2] if hits else None
    return ICMetrics(identity, float(im), float(srt), bool(t_ok is not None and (t_bad is None or t_ok < t_bad)))


@dataclass
class ExplorationResult:
    """One exploration run.

    Attributes
    ----------
    confidence, ic : ndarray (n, n_objects)
        Raw and integrated confidence per iteration.
    impulses : ndarray (n, n_objects) bool
        Re-localisations to each object's built map (``matcher="surface"``: the surface
        matcher's impulses).
    poses : list of Pose
        End-effector pose of every whisk.
    strategies : list of str
        The source of each goal (``spc``, ``default``, ``feh``, ``lsr``, ``none``; with
        contact seeking also ``advance``, ``back_off`` and ``turn``,
        :func:`cansim.explore.contact_seeking.seek_contact`).
    refused_commands : int
    stop_reason : str
        ``threshold``, ``iterations`` or ``time``.
    """

    confidence: np.ndarray
    ic: np.ndarray
    impulses: np.ndarray
    poses: list[Pose]
    strategies: list[str]
    refused_commands: int
    stop_reason: str

    def metrics(self, correct: int, threshold: float, dt: float = 1.0) -> ICMetrics:
        """:func:`ic_metrics` of this run."""
        return ic_metrics(self.ic, correct, threshold, dt)


class Explorer:
    """Active exploration (see the module docstring).

    Parameters
    ----------
    known : sequence of KnownObject
        Mapped objects; each is recognised by its own copy (:meth:`KnownObject.exploring_model`),
        so one set of maps serves many runs.
    sensor : callable
        ``sensor(pose) -> RegionFeatures`` (contact points in the end-effector frame).
    arm : whisker_io.hw.arm.Arm
        Moves pass its safety envelope.
    odometry : callable
        ``odometry(prev, now) -> (v, omega, dt)``.
    default_search : DefaultSearch
    strategy : {"default", "feh", "lsr"}
    placement : PlacementParams or None
        SPC (None: off).
    integrator : LeakyIntegrator
    stop_threshold : float
        Stop when an IC reaches it (inf: never).
    max_iterations : int
    time_limit_s : float
        Wall-clock limit (inf: none).
    max_adjustments : int
        SPC corrections per region before the strategy moves on (10, the physical runs).
    max_replans : int
        Re-plans after refused commands per iteration.
    strategy_options : mapping, optional
        Keyword arguments of the FEH or LSR strategy
        (:class:`cansim.explore.search.FollowExperienceHistory`,
        :class:`cansim.explore.search.LeastSimilarRegion`), e.g. ``{"along_surface": True}``; the
        default search takes none (options given with it raise :class:`ConfigError`).
    contact_seeking : ContactSeekingParams or None
        Contact seeking (:mod:`cansim.explore.contact_seeking`; opt-in, default None): back off
        when the contacts lie nearer than the SPC band, advance along the array's axis
        after a whisk without contact, turn toward fewer than ``mu`` contacts, and
        place the default search's next face at the range where contact was last held.
        None (the default): the thesis' behaviour (Alg 7 alone; the search's faces before
        its believed volume), which reaches no surface of an object that does not fill
        that volume. Contact seeking extends the SPC: with ``placement`` None it is off
        too. It is not the default: it puts a whisker base inside the object in 5-15 % of
        the whisks (a placement no arm can make; the thesis' placement puts none), because
        no whisker of the thesis array sweeps the space straight ahead of its front bases,
        and where the believed volume is the object's exact box (the Ch.6 study) it delays
        the IC 300 decision (:mod:`cansim.explore.contact_seeking` for the measurements).
        Every goal it plans, whatever proposed it, is kept clear of the whisk's contacts
        (:func:`cansim.explore.contact_seeking.clear_of_contacts`).
    matcher : {"thesis", "surface"}
        Where the impulses into the leaky integrators come from. ``"thesis"`` (default): a
        re-localisation of object ``k``'s model to an experience of its built map (step 3
        above, Eq 5.5's region match). ``"surface"``: a
        :class:`maps.surface_match.SurfaceMatcher` on the known objects' stored surfaces
        (:meth:`KnownObject.stored_surface`), started at the arm's pose of the first whisk
        and moved by the same odometry: it compares each whisk's contacts with the surface
        the map felt at every pose hypothesis, so a path the map never took can name the
        object (issue 22). The models still step: FEH and LSR take their targets from them.
    surface_config : SurfaceMatchConfig, optional
        The surface matcher's parameters (``matcher="surface"``; default
        ``SurfaceMatchConfig()`` with its motion model for the known objects' odometry noise,
        :meth:`~maps.surface_match.SurfaceMatchConfig.for_odometry_scale` of their
        :attr:`KnownObject.odometry_scale` when they share one, else Eq 6.4-6.11's).

    Notes
    -----
    With ``matcher="surface"`` the matcher may rule every known object out (each fits the
    window's contacts worse than ``prune_residual_ratio`` times the impulse tolerance, or lies
    ``prune_margin`` behind one that did): no impulse comes for the rest of the run, and the
    explorer says so once, at INFO, with the whisk. That is what a novel object does, but in
    exploration it happens on known objects too, where the whisks touch what their map never
    felt: in the Ch.6 study's surface-matcher runs (freeform pairs and Box / Box-Stack, seeds
    0-3, 1000 whisks) in 11 of 24, mostly after the decision (the upright torus at whisks 34
    and 99, never named). Putting every object back in question 20 whisks later named no
    more of them and turned those two torus runs into decisions for the snowman
    (:mod:`maps.surface_match`, Status): it is not done, and ruling everything out is not
    reported as "unknown object".
    """

    def __init__(
        self,
        known: Sequence[KnownObject],
        sensor: Sensor,
        arm: object,
        odometry: Odometry,
        default_search: DefaultSearch,
        *,
        strategy: str = "default",
        placement: PlacementParams | None = PlacementParams(roll_rad=math.pi / 2),
        integrator: LeakyIntegrator = LeakyIntegrator(),
        stop_threshold: float = 300.0,
        max_iterations: int = 1000,
        time_limit_s: float = math.inf,
        max_adjustments: int = 10,
        max_replans: int = 3,
        strategy_options: dict[str, object] | None = None,
        contact_seeking: ContactSeekingParams | None = None,
        matcher: str = "thesis",
        surface_config: SurfaceMatchConfig | None = None,
    ) -> None:
        if matcher not in MATCHERS:
            raise ConfigError(f"unknown matcher {matcher!r}; use one of {MATCHERS}")
        if surface_config is not None and not isinstance(surface_config, SurfaceMatchConfig):
            raise ConfigError(f"surface_config must be a SurfaceMatchConfig or None, got {type(surface_config).__name__}")
        if strategy not in STRATEGIES:
            raise ConfigError(f"unknown strategy {strategy!r}; use one of {STRATEGIES}")
        if contact_seeking is not None and not isinstance(contact_seeking, ContactSeekingParams):
            raise ConfigError(f"contact_seeking must be a ContactSeekingParams or None, got {type(contact_seeking).__name__}")
        if placement is not None and not isinstance(placement, PlacementParams):
            raise ConfigError(f"placement must be a PlacementParams or None, got {type(placement).__name__}")
        if isinstance(known, KnownObject) or not isinstance(known, Sequence) or not known \
                or not all(isinstance(k, KnownObject) for k in known):
            raise InvalidInputError("known must be a non-empty list of KnownObject (build_object_model or "
                                    f"KnownObject.load), got {type(known).__name__}")
        if len({k.name for k in known}) != len(known):
            raise InvalidInputError(f"the known objects need distinct names, got {[k.name for k in known]}")
        if not isinstance(default_search, DefaultSearch):
            raise InvalidInputError(f"default_search must be a DefaultSearch, got {type(default_search).__name__}")
        if any(f is not None and not callable(f) for f in (odometry, sensor)):
            raise InvalidInputError("odometry must be a callable odometry(prev, now) -> (v, omega, dt), and sensor a "
                                    "callable sensor(pose) -> RegionFeatures (either None: given later, not used)")
        config_field(max_iterations, "max_iterations", int, minimum=1)
        for name, v in (("max_adjustments", max_adjustments), ("max_replans", max_replans)):
            config_field(v, name, int, minimum=0)
        for name, v in (("stop_threshold", stop_threshold), ("time_limit_s", time_limit_s)):
            if v != math.inf:  # inf: no such limit
                config_field(v, name, float, above=0, hint="or math.inf for no limit")
        self.models = [k.exploring_model() for k in known]
        self.matcher = matcher
        self._surfaces: SurfaceLibrary | None = None
        scales = {float(k.odometry_scale) for k in known}  # the arm that mapped them explores: its odometry's noise
        self._surface_config = surface_config if surface_config is not None else \
            SurfaceMatchConfig().for_odometry_scale(scales.pop() if len(scales) == 1 else 1.0)
        self._surface_matcher: SurfaceMatcher | None = None
        self._ruled_out = False  # the surface matcher holds no object in question (logged once)
        if matcher == "surface":
            stored = [k.stored_surface() for k in known]
            self._surfaces = SurfaceLibrary([pts for pts, _ in stored], [k.name for k in known], [seen for _, seen in stored])
        self.views = [ObjectView(m.object_map, m.frontend, k.n_built, k.n_built_regions, k.n_history)
                      for m, k in zip(self.models, known)]
        self.sensor, self.arm, self.odometry = sensor, arm, odometry
        self.default = default_search
        self.strategy_name = strategy
        if strategy_options is not None and not isinstance(strategy_options, dict):
            raise ConfigError(f"strategy_options must be a dict of keyword arguments, got {type(strategy_options).__name__}")
        if strategy == "default" and strategy_options:  # they were ignored, a typo and all
            raise ConfigError(f"strategy_options {sorted(strategy_options)} apply to the 'feh' and 'lsr' strategies; the "
                              "default search takes none")
        try:
            self.strategy = make_strategy(strategy, **(strategy_options or {}) if strategy != "default" else {})
        except TypeError as exc:
            raise ConfigError(f"bad strategy_options for {strategy!r}: {exc}") from None
        self.placement, self.integrator = placement, integrator
        self.seeking = contact_seeking
        self._advance = 0.0
        self._held: tuple[float, np.ndarray] | None = None  # (range, direction) of the last contact held
        self._backed_off = False  # a back-off since the last move that was not contact seeking's
        self.stop_threshold, self.max_iterations, self.time_limit_s = float(stop_threshold), int(max_iterations), float(time_limit_s)
        self.max_adjustments, self.max_replans = int(max_adjustments), int(max_replans)
        n = len(self.models)
        self._level = np.zeros(n)
        self._ic = np.zeros(n)
        self._prev: Pose | None = None
        self.refused_commands = 0
        self._c: list[np.ndarray] = []
        self._icl: list[np.ndarray] = []
        self._imp: list[np.ndarray] = []
        self._poses: list[Pose] = []
        self._strats: list[str] = []
        self._adjust = 0

    # ------------------------------------------------------------ perception
    def observe(self, pose: Pose, observation: object) -> list[tuple[int, int]]:
        """Steps 2-3 of one iteration (also the replay path): returns the re-localisations."""
        if self._prev is None:
            odo = SpatialOdometry(np.zeros(3), np.zeros(3), 1.0)
        else:
            odo = _odometry_of(self.odometry, self._prev, pose)
        reloc: list[tuple[int, int]] = []
        imp = np.zeros(len(self.models), dtype=bool)
        for k, (m, v) in enumerate(zip(self.models, self.views)):
            st = m.step(odo, observation)
            if st.relocalised and 0 <= st.exp_id < v.n_built:
                reloc.append((k, int(st.exp_id)))
                v.last_relocalised = int(st.exp_id)
                imp[k] = True
        if self._surfaces is not None:
            if self._surface_matcher is None:  # the first whisk: the hypotheses start at the arm's pose
                self._surface_matcher = SurfaceMatcher(self._surfaces, np.r_[pose.position_m, pose.quaternion_xyzw],
                                                       self._surface_config)
                imp = self._surface_matcher.step(None, _contacts(observation))
            else:
                imp = self._surface_matcher.step(odo, _contacts(observation))
            if not self._ruled_out and not self._surface_matcher.active.any():
                self._ruled_out = True
                _LOG.info("surface matcher: no known object fits the contacts felt (whisk %d, %d contacts in the "
                          "evidence window): every object ruled out, no further impulses this run",
                          len(self._poses) + 1, self._surface_matcher.window_contacts)
        self._level = leaky_step(self._level, imp, self.integrator)
        self._ic = self._ic + self._level * self.integrator.dt
        self._c.append(self._level.copy())
        self._icl.append(self._ic.copy())
        self._imp.append(imp)
        self._poses.append(pose)
        self._prev = pose
        return reloc

    # -------------------------------------------------------------- planning
    def _seek(self, pose: Pose, obs: object) -> tuple[Pose, str] | None:
        """Contact seeking's goal (:func:`seek_contact`), or None; keeps the held range and the advance."""
        assert self.seeking is not None
        pts = np.asarray(getattr(obs, "contact_points_m", np.zeros((0, 3))), dtype=float).reshape(-1, 3)
        spc = self.placement
        assert spc is not None
        centre = self.default.centre_m
        if len(pts):
            self._advance = 0.0
            if len(pts) >= spc.mu:
                self._held = contact_range_m(pose, centre, self.seeking.front_m)
            if self._adjust >= self.max_adjustments:
                return None
        if not len(pts) and self._backed_off:
            return None  # backed off from a surface the whiskers then lost: no blind advance back into it
        step = seek_contact(pose, pts, params=self.seeking, placement=spc, advance_m=self._advance, centre_m=centre)
        if step is None:
            if not len(pts):
                self._held = None  # nothing at this range here: the next face starts before the believed volume
            return None
        if step.action == "advance":
            self._advance = step.advance_m
        else:
            self._adjust += 1
        return step.goal, step.action

    def _default_goal(self) -> Pose:
        """The default search's next face, at the held range when contact was held nearby (contact seeking)."""
        goal = self.default.propose()
        self._advance = 0.0
        if self.seeking is None or self.placement is None or self._held is None:
            return goal
        rng, u = self._held
        face_u = self.default.directions[self.default.current]
        if math.acos(float(np.clip(face_u @ u, -1.0, 1.0))) > self.seeking.hold_max_turn_rad:
            self._held = None
            return goal
        return held_face_pose(goal, self.default.centre_m, self.seeking.front_m, rng, self.seeking.hold_margin_m)

    def _plan(self, pose: Pose, obs: object, reloc: list[tuple[int, int]]) -> tuple[Pose, str]:
        goal, source = self._plan_goal(pose, obs, reloc)
        if self.seeking is not None and self.placement is not None and self.seeking.clear_ahead_m > 0:
            pts = np.asarray(getattr(obs, "contact_points_m", np.zeros((0, 3))), dtype=float).reshape(-1, 3)
            if len(pts):  # the whisk's contacts must stay clear of the array at the goal (clear_of_contacts)
                goal = clear_of_contacts(goal, pose.apply(pts), ahead_m=self.seeking.clear_ahead_m,
                                         radius_m=self.seeking.clear_radius_m)
        return goal, source

    def _plan_goal(self, pose: Pose, obs: object, reloc: list[tuple[int, int]]) -> tuple[Pose, str]:
        contact = bool(getattr(obs, "is_observation", False))
        if self.seeking is not None and self.placement is not None:
            sought = self._seek(pose, obs)
            if sought is not None:
                return sought
        if self.placement is not None and contact and self._adjust < self.max_adjustments:
            goal = place(pose, obs.contact_points_m, self.placement)  # type: ignore[attr-defined]
            if goal != pose:
                self._adjust += 1
                return goal, "spc"
        self._adjust = 0
        active = active_strategy(self.strategy_name, self._level, contact)
        if active != "default" and self.strategy is not None:
            ctx = SearchContext(pose, self.views, self._level.copy(), obs if contact else None, reloc)
            goal = self.strategy.propose(ctx)
            if goal is not None:
                return goal, active
        return self._default_goal(), "default"

    def _move(self, goal: Pose, source: str) -> str:
        for attempt in range(self.max_replans + 1):
            try:
                self.arm.move_linear(goal)  # type: ignore[attr-defined]
                if source == "back_off":
                    self._backed_off = True
                elif source != "advance":
                    self._backed_off = False
                return source
            except SafetyViolationError as exc:
                self.refused_commands += 1
                _LOG.debug("arm command refused by the safety envelope (%s): %s; re-planning", source, exc)
                if source == "default":
                    self.default.refused()
                elif source in ("feh", "lsr") and self.strategy is not None:
                    self.strategy.refused()
                self._adjust = self.max_adjustments if source in ("spc", "back_off", "turn") else self._adjust
                goal, source = self._default_goal(), "default"
        return "none"

    # ------------------------------------------------------------------ runs
    def run(self) -> ExplorationResult:
        """Explore until the stop threshold, the iteration limit or the time limit."""
        if self.sensor is None or self.arm is None:
            raise ConfigError("run() needs a sensor and an arm (this explorer was made with None: replay() its "
                              "recorded cycles instead, or give both)")
        t0 = time.monotonic()
        reason = "iterations"
        refused = self.refused_commands
        whisks, touched, moves, stuck = 0, 0, 0, 0
        for _ in range(self.max_iterations):
            pose = self.arm.pose()  # type: ignore[attr-defined]
            obs = self.sensor(pose)
            whisks += 1
            touched += _touched(obs)
            # (an observation without contact points - a (pfh, sda) pair - counts as touching: no false warning)
            reloc = self.observe(pose, obs)
            if self._ic.max() >= self.stop_threshold:
                self._strats.append("none")
                reason = "threshold"
                break
            goal, source = self._plan(pose, obs, reloc)
            self._strats.append(self._move(goal, source))
            moves += 1
            stuck += self._strats[-1] == "none"  # every attempt refused: the arm stayed
            if time.monotonic() - t0 > self.time_limit_s:
                reason = "time"
                break
        n_refused = self.refused_commands - refused
        if n_refused:  # one line a run; each refusal is logged at DEBUG
            many = n_refused >= whisks  # a refusal a whisk or more: the envelope, not the object, shapes the run
            _LOG.log(logging.WARNING if many else logging.INFO,
                     "%d arm commands refused by the safety envelope in %d whisks, each re-planned "
                     "(ExplorationResult.refused_commands)%s", n_refused, whisks,
                     "; most planned moves lie outside it: check the envelope against the search's placements "
                     "(centre, radius, tool tilt)" if many else "")
        if moves and stuck == moves:
            _LOG.warning("the arm did not move in this run: all %d of its commands were refused by the safety "
                         "envelope; check the envelope against the search's placements (centre, radius, tool tilt)",
                         moves)
        if whisks and not touched:
            _LOG.warning("none of the %d whisks of this run touched anything: the search's placements do not reach the "
                         "object (is the search centred on it, with a radius in metres?); contact seeking "
                         "(contact_seeking=ContactSeekingParams()) moves the array until whiskers touch", whisks)
        return self.result(reason)

    def replay(self, cycles: Sequence[tuple[Pose, object]], stop_at_threshold: bool = False) -> ExplorationResult:
        """Perception and recognition over recorded ``(pose, features)`` cycles (no arm).

        Parameters
        ----------
        cycles : sequence of (Pose, observation)
            The recorded whisks, in order.
        stop_at_threshold : bool
            Stop after the whisk at which an IC reaches ``stop_threshold``, as :meth:`run`
            does (stop reason ``"threshold"``); default False: every cycle.

        Returns
        -------
        ExplorationResult
            The traces of every whisk replayed so far (this call's and any earlier ones').
        """
        if not isinstance(stop_at_threshold, (bool, np.bool_)):
            raise InvalidInputError(f"stop_at_threshold must be True or False, got {stop_at_threshold!r}")
        whisks = touched = 0
        reason = "iterations"
        for pose, obs in cycles:
            self.observe(pose, obs)
            self._strats.append("none")
            whisks += 1
            touched += _touched(obs)
            if stop_at_threshold and self._ic.max() >= self.stop_threshold:
                reason = "threshold"
                break
        if whisks and not touched:
            _LOG.warning("none of the %d replayed whisks touched anything: was the object within reach, and does the "
                         "recording hold deflections in counts and angles in radians?", whisks)
        return self.result(reason)

    def result(self, reason: str) -> ExplorationResult:
        """The traces so far."""
        n = len(self.models)
        stack = (lambda xs, dt: np.array(xs, dtype=dt).reshape(-1, n))
        return ExplorationResult(stack(self._c, float), stack(self._icl, float), stack(self._imp, bool),
                                 list(self._poses), list(self._strats), self.refused_commands, reason)
