"""The three seeded simulated data sets of thesis Ch.4.

All three run the same sensing chain as the real array: the tapered-cantilever
signal model (:mod:`whisker_io.sim.signals`, Eq 2.33-2.38) synthesises 2 kHz angle
and deflection traces, :func:`whisker_io.contact.detection.detect_contacts`
finds the contacts and :func:`whisker_io.contact.features.contact_features`
extracts CP, CA, DV, DA, AV, AA, WL. Whisks whose contact the detector misses
are dropped (their number is logged), exactly as a missed contact would be on
the robot. The ground-truth radial distance is the simulator's.

* :func:`make_training_set` (Sec 4.1.2.1): a rod perpendicular to the whisking
  plane at 20 equally spaced radial distances from 25 mm to the tip, whisking
  at 0.2-2.5 Hz, whisker lengths 65, 78, 87, 88, 94, 107, 113, 137 mm. Whisking
  uses the Ch.4 RCP (:class:`~whisker_io.array.control.RetractAtMax`, Sec 4.1.1). The rod's
  position in the whisk range (the contact angle) is not given in the thesis;
  it is drawn per whisk uniformly from ``contact_angle_deg``.
* :func:`make_validation_set` (Sec 4.1.2.2-4.1.2.3): an 18-whisker array with
  the unseen lengths 50, 64, 80, 95, 101, 127, 128, 150, 154 mm among its
  whiskers explores the Box from held-still waypoints. The ground truth is the
  rigid-whisker sweep (:func:`whisker_io.sim.sweep.sweep_array`); each whisk is
  simulated by :class:`whisker_io.sim.simulator.ArraySimulator` (sweep + signals)
  under the Ch.4 RCP at a frequency drawn from 0.2-2.5 Hz. Waypoints are chosen "such that contact occurrences
  ranged from tip to anywhere along the length of the whiskers": each waypoint
  aims one whisker (round robin over the array) at a box edge at a random
  radial distance and whisk angle, and is kept if the sweep confirms that
  contact; every whisker's contact at that waypoint is then recorded. This
  uses geometry only, never a model's error.
* :func:`make_evans_set` (Sec 4.2.2): one 185-mm whisker, a rod driven linearly
  into the still whisker (:func:`whisker_io.sim.signals.simulate_rod_contact`) at
  101 radial distances 80-180 mm x 26 speeds 36-216 mm/s x 4 repeats.

Sizes: the defaults are the thesis' grids (training 8 x 20 x 6 frequencies x 2
whisks = 1920 whisks; Evans 10504 rod presses) and take seconds to synthesise;
:meth:`reduced` gives the smaller sets the tests use, drawn by the same generators.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from whisker_io.contact.detection import DetectionParams, detect_contacts
from whisker_io.contact.features import contact_features
from whisker_io.array.control import RetractAtMax, WhiskPattern
from whisker_io.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, number_tuple, validate_fields
from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import whisker_base_transforms
from whisker_io.radial.features import RadialDataset
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.sim.signals import SignalParams, WhiskContact, simulate_rod_contact, simulate_whisk_cycle

__all__ = [
    "TRAINING_LENGTHS_MM",
    "UNSEEN_LENGTHS_MM",
    "VALIDATION_LENGTHS_MM",
    "TrainingSetParams",
    "ValidationSetParams",
    "EvansSetParams",
    "ValidationSet",
    "features_from_records",
    "make_training_set",
    "make_validation_set",
    "make_evans_set",
    "validation_array",
]

log = logging.getLogger(__name__)

#: Whisker lengths of the training set, mm (Sec 4.1.2.1).
TRAINING_LENGTHS_MM: tuple[int, ...] = (65, 78, 87, 88, 94, 107, 113, 137)
#: Lengths in the validation set and not in training, mm (Sec 4.1.2.2).
UNSEEN_LENGTHS_MM: tuple[int, ...] = (50, 64, 80, 95, 101, 127, 128, 150, 154)
#: The 18 whiskers of the validation array, mm: the nine unseen lengths, the
#: eight training lengths and a second 107-mm whisker (decision; the thesis lists
#: only the unseen ones). Sorted and assigned row by row (row 1 rostral = shortest).
VALIDATION_LENGTHS_MM: tuple[int, ...] = tuple(sorted(UNSEEN_LENGTHS_MM + TRAINING_LENGTHS_MM + (107,)))


def _progress(it: Iterable[Any], on: bool, desc: str, total: int | None = None) -> Iterable[Any]:
    if not on:
        return it
    from tqdm.auto import tqdm

    return tqdm(it, desc=desc, total=total, leave=False)


def features_from_records(
    records: Sequence[WhiskRecord],
    whisker_lengths_m: Sequence[float] | np.ndarray,
    detection: DetectionParams = DetectionParams(),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detect contacts and extract the seven features of each record that has one.

    Parameters
    ----------
    records : sequence of WhiskRecord, length n
    whisker_lengths_m : array_like, shape (n,)
    detection : DetectionParams

    Returns
    -------
    features : ndarray, shape (k, 7)
        Rows of the detected contacts (:data:`~whisker_io.radial.features.FEATURE_NAMES`).
    kept : ndarray of int, shape (k,)
        Indices into ``records`` of those rows.
    onset_angle_rad : ndarray, shape (k,)
        Whisk angle at the detected onset (the contact angle used for FK).
    """
    dets = detect_contacts(records, detection)
    kept = np.array([i for i, d in enumerate(dets) if d is not None], dtype=int)
    wl = np.asarray(whisker_lengths_m, dtype=np.float64)
    if kept.size == 0:
        return np.zeros((0, 7)), kept, np.zeros(0)
    F = contact_features([records[i] for i in kept], [dets[i] for i in kept], wl[kept], detection.smoothing_span)
    good = np.isfinite(F).all(axis=1)
    angles = np.array([dets[i].contact_angle_rad for i in kept])
    return F[good], kept[good], angles[good]


# ---------------------------------------------------------------- training (rod)


def _nested(signal: object, detection: object) -> None:
    """Refuse nested settings of the wrong type (InvalidInputError naming the class wanted)."""
    if not isinstance(signal, SignalParams):
        raise InvalidInputError(f"signal must be a SignalParams, got {type(signal).__name__}")
    if not isinstance(detection, DetectionParams):
        raise InvalidInputError(f"detection must be a DetectionParams, got {type(detection).__name__}")


@dataclass(frozen=True)
class TrainingSetParams(ConfigDataclass):
    """The rod training set of Sec 4.1.2.1.

    Parameters
    ----------
    lengths_mm : tuple of float
        Whisker lengths, mm.
    n_distances : int
        Equally spaced radial distances per whisker, from ``min_distance_m`` to the tip.
    min_distance_m : float
        First radial distance, m (25 mm).
    frequencies_hz : tuple of float
        Whisking frequencies used at every radial distance, Hz (0.2-2.5 Hz).
    whisks_per_setting : int
        Whisks per (length, distance, frequency), each with its own contact angle.
    contact_angle_deg : (float, float)
        Range of the rod's contact angle in the whisk, degrees (assumption).
    retract_at_max : bool
        Use the Ch.4 RCP (retract at the sensor maximum, Sec 4.1.1); else open loop.
    seed : int
    signal : SignalParams
    detection : DetectionParams
    """

    lengths_mm: tuple[float, ...] = TRAINING_LENGTHS_MM
    n_distances: int = checked(20, int, minimum=1, maximum=100_000, error=InvalidInputError)
    min_distance_m: float = checked(0.025, float, above=0, error=InvalidInputError)
    frequencies_hz: tuple[float, ...] = (0.2, 0.5, 1.0, 1.5, 2.0, 2.5)
    whisks_per_setting: int = checked(2, int, minimum=1, maximum=100_000, error=InvalidInputError)
    contact_angle_deg: tuple[float, float] = (-45.0, 30.0)
    retract_at_max: bool = checked(True, bool, error=InvalidInputError)
    seed: int = checked(0, int, minimum=0, error=InvalidInputError)
    signal: SignalParams = field(default_factory=SignalParams)
    detection: DetectionParams = field(default_factory=DetectionParams)

    def __post_init__(self) -> None:
        validate_fields(self)
        _nested(self.signal, self.detection)
        number_tuple(self.lengths_mm, "lengths_mm", above=0)
        number_tuple(self.frequencies_hz, "frequencies_hz", above=0)
        number_tuple(self.contact_angle_deg, "contact_angle_deg", length=2)
        if min(self.lengths_mm) * 1e-3 <= self.min_distance_m:
            raise InvalidInputError("every whisker length must exceed min_distance_m")
        lo, hi = self.contact_angle_deg
        if not -50.0 <= lo < hi < 50.0:
            raise InvalidInputError(f"contact_angle_deg must lie inside the +-50 deg whisk range, got {self.contact_angle_deg}")

    def reduced(self) -> "TrainingSetParams":
        """A smaller set for tests: 3 frequencies, 1 whisk per setting."""
        return replace(self, frequencies_hz=(0.5, 1.0, 2.0), whisks_per_setting=1)


def make_training_set(params: TrainingSetParams = TrainingSetParams(), progress: bool = False) -> RadialDataset:
    """Rod contacts at known radial distances (Sec 4.1.2.1).

    Returns
    -------
    RadialDataset
        ``meta``: ``frequency_hz``, ``contact_angle_rad`` (true), ``onset_angle_rad``
        (detected).
    """
    rng = np.random.default_rng(params.seed)
    lo, hi = np.deg2rad(params.contact_angle_deg)
    rows: list[RadialDataset] = []
    missed = total = 0
    settings = [(L, f, w) for L in params.lengths_mm for f in params.frequencies_hz for w in range(params.whisks_per_setting)]
    for L_mm, f, _ in _progress(settings, progress, "training set (rod)"):
        L = L_mm * 1e-3
        a = np.linspace(params.min_distance_m, L, params.n_distances)
        theta_c = rng.uniform(lo, hi, a.size)
        contacts = [WhiskContact(float(t), float(ai), L) for t, ai in zip(theta_c, a)]
        pattern = WhiskPattern(frequency_hz=f, sample_rate_hz=params.signal.sample_rate_hz)
        ctrl = RetractAtMax(pattern) if params.retract_at_max else None
        records, _ = simulate_whisk_cycle(contacts, ctrl, params.signal, seed=rng)
        F, kept, onset = features_from_records(records, np.full(a.size, L), params.detection)
        total += a.size
        missed += a.size - kept.size
        rows.append(
            RadialDataset(
                F,
                a[kept],
                meta={"frequency_hz": np.full(kept.size, f), "contact_angle_rad": theta_c[kept], "onset_angle_rad": onset},
            )
        )
    log.info("training set: %d of %d rod whisks detected", total - missed, total)
    return RadialDataset.concatenate(rows, name="training (rod)")


# ---------------------------------------------------------------- Evans-style


@dataclass(frozen=True)
class EvansSetParams(ConfigDataclass):
    """The Evans et al. (2013) style rod set of Sec 4.2.2 (one still 185-mm whisker).

    Parameters
    ----------
    whisker_length_m : float
    distances_m : (float, float, int)
        First, last radial distance, m, and their number (80-180 mm, 101).
    speeds_m_s : (float, float, int)
        First, last rod speed, m/s, and their number (36-216 mm/s, 26).
    repeats : int
        Presses per (distance, speed) (4).
    seed : int
    signal : SignalParams
        Default :meth:`SignalParams.evans2013` (ABS whisker, 2 -> 0.5 mm).
    detection : DetectionParams
    """

    whisker_length_m: float = checked(0.185, float, above=0, error=InvalidInputError)
    distances_m: tuple[float, float, int] = (0.080, 0.180, 101)
    speeds_m_s: tuple[float, float, int] = (0.036, 0.216, 26)
    repeats: int = checked(4, int, minimum=1, maximum=100_000, error=InvalidInputError)
    seed: int = checked(2, int, minimum=0, error=InvalidInputError)
    signal: SignalParams = field(default_factory=SignalParams.evans2013)
    detection: DetectionParams = field(default_factory=DetectionParams)

    def __post_init__(self) -> None:
        validate_fields(self)
        _nested(self.signal, self.detection)
        for name, grid in (("distances_m", self.distances_m), ("speeds_m_s", self.speeds_m_s)):
            first, last, n = number_tuple(grid, name, length=3, minimum=0)
            if not (float(n).is_integer() and 1 <= n <= 100_000):
                raise InvalidInputError(f"{name}: the number of grid points must be a whole number in [1, 100000], got {grid!r}")
        if not 0 < self.distances_m[0] <= self.distances_m[1] <= self.whisker_length_m:
            raise InvalidInputError("Evans radial distances must lie on the whisker")

    def reduced(self) -> "EvansSetParams":
        """A smaller set for tests: 26 distances x 9 speeds x 1 repeat (same ranges)."""
        return replace(self, distances_m=self.distances_m[:2] + (26,), speeds_m_s=self.speeds_m_s[:2] + (9,), repeats=1)


def make_evans_set(params: EvansSetParams = EvansSetParams(), progress: bool = False) -> RadialDataset:
    """Rod driven into a still whisker at each (distance, speed, repeat) (Sec 4.2.2).

    The whisker does not whisk, so AV and AA are ~0; the comparison uses CP, CA,
    DV, DA only.

    Returns
    -------
    RadialDataset
        ``meta``: ``speed_m_s``.
    """
    rng = np.random.default_rng(params.seed)
    a = np.linspace(*params.distances_m[:2], params.distances_m[2])
    v = np.linspace(*params.speeds_m_s[:2], params.speeds_m_s[2])
    grid = [(ai, vi) for ai in a for vi in v for _ in range(params.repeats)]
    records, dist, speed = [], [], []
    for ai, vi in _progress(grid, progress, "Evans-style set (rod into still whisker)"):
        rec, _ = simulate_rod_contact(float(ai), params.whisker_length_m, float(vi), params.signal, seed=rng)
        records.append(rec)
        dist.append(ai)
        speed.append(vi)
    F, kept, _ = features_from_records(records, np.full(len(records), params.whisker_length_m), params.detection)
    log.info("Evans set: %d of %d rod presses detected", kept.size, len(records))
    return RadialDataset(F, np.asarray(dist)[kept], name="Evans-style (185 mm)", meta={"speed_m_s": np.asarray(speed)[kept]})


# ---------------------------------------------------------------- validation (Box)


def validation_array(lengths_mm: Sequence[float] = VALIDATION_LENGTHS_MM) -> WhiskerArray:
    """The thesis array (Fig 2.15) with the validation whisker lengths.

    The lengths are sorted and assigned in module order grouped by row: the six
    shortest to row 1 (rostral), the next six to row 2, the longest to row 3.
    """
    base = WhiskerArray.thesis()
    if len(lengths_mm) != len(base):
        raise InvalidInputError(f"need {len(base)} whisker lengths, got {len(lengths_mm)}")
    order = sorted(range(len(base)), key=lambda i: (base.modules[i].row, base.modules[i].column))
    lengths = sorted(float(x) * 1e-3 for x in lengths_mm)
    return base.with_lengths({base.modules[i].name: lengths[k] for k, i in enumerate(order)})


@dataclass(frozen=True)
class ValidationSetParams(ConfigDataclass):
    """The Box exploration of Sec 4.1.2.2.

    Parameters
    ----------
    object_name : str
        Mesh from :func:`whisker_io.sim.objects.make_object`.
    lengths_mm : tuple of float
        The 18 whisker lengths (see :data:`VALIDATION_LENGTHS_MM`).
    n_waypoints : int
        Held-still poses.
    whisks_per_waypoint : int
        Whisk cycles recorded at each waypoint (the thesis held each pose 1 min).
    frequency_range_hz : (float, float)
        Each whisk's frequency is drawn uniformly from this range, Hz.
    aim_fraction : (float, float)
        Range of the aimed whisker's contact position, fraction of its length.
    aim_angle_deg : (float, float)
        Range of the aimed whisker's contact angle, degrees.
    min_base_clearance_m : float
        Whisker bases must be at least this far outside the object and above the
        table (z = 0).
    max_candidates : int
        Candidate poses tried before giving up.
    seed : int
    signal : SignalParams
    detection : DetectionParams
    """

    object_name: str = checked("box", str, error=InvalidInputError)
    lengths_mm: tuple[float, ...] = VALIDATION_LENGTHS_MM
    n_waypoints: int = checked(36, int, minimum=1, maximum=100_000, error=InvalidInputError)
    whisks_per_waypoint: int = checked(3, int, minimum=1, maximum=100_000, error=InvalidInputError)
    frequency_range_hz: tuple[float, float] = (0.2, 2.5)
    aim_fraction: tuple[float, float] = (0.15, 0.7)
    aim_angle_deg: tuple[float, float] = (-35.0, 35.0)
    min_base_clearance_m: float = checked(0.01, float, minimum=0, error=InvalidInputError)
    max_candidates: int = checked(5000, int, minimum=1, maximum=10_000_000, error=InvalidInputError)
    seed: int = checked(1, int, minimum=0, error=InvalidInputError)
    signal: SignalParams = field(default_factory=SignalParams)
    detection: DetectionParams = field(default_factory=DetectionParams)

    def __post_init__(self) -> None:
        validate_fields(self)
        _nested(self.signal, self.detection)
        number_tuple(self.lengths_mm, "lengths_mm", above=0)
        number_tuple(self.aim_fraction, "aim_fraction", length=2, minimum=0)
        number_tuple(self.aim_angle_deg, "aim_angle_deg", length=2)
        lo, hi = number_tuple(self.frequency_range_hz, "frequency_range_hz", length=2)
        if not 0 < lo <= hi:
            raise InvalidInputError(f"frequency_range_hz must be positive and ordered, got {self.frequency_range_hz}")

    def reduced(self) -> "ValidationSetParams":
        """A smaller set for tests: 18 waypoints (one per whisker), 2 whisks each."""
        return replace(self, n_waypoints=18, whisks_per_waypoint=2)


@dataclass(frozen=True)
class ValidationSet:
    """Validation contacts with the scene they came from.

    Attributes
    ----------
    data : RadialDataset
        ``meta``: ``pose`` (n, 4, 4) end-effector pose, ``module`` (n,) module
        index, ``angle_rad`` (n,) detected contact angle, ``true_angle_rad`` (n,)
        swept contact angle, ``waypoint`` (n,), ``frequency_hz`` (n,).
    array : WhiskerArray
        The validation array (its whisker lengths).
    mesh : trimesh.Trimesh
        The object in the world frame.
    poses : ndarray, shape (w, 4, 4)
        The waypoints.
    unseen_lengths_mm : tuple of float
        Lengths that count as unseen.
    """

    data: RadialDataset
    array: WhiskerArray
    mesh: Any
    poses: np.ndarray
    unseen_lengths_mm: tuple[float, ...] = UNSEEN_LENGTHS_MM

    @property
    def unseen(self) -> np.ndarray:
        """Boolean mask of contacts on whiskers of unseen length, shape (n,)."""
        wl_mm = self.data.whisker_length_m * 1e3
        return np.isin(np.round(wl_mm, 3), np.asarray(self.unseen_lengths_mm, dtype=float))


def _sharp_edges(mesh: Any, z_min: float) -> tuple[np.ndarray, np.ndarray]:
    """Convex edges of the mesh above ``z_min``: segments (m, 2, 3) and outward bisectors (m, 3)."""
    sel = (mesh.face_adjacency_angles > np.radians(20.0)) & mesh.face_adjacency_convex
    seg = mesh.vertices[mesh.face_adjacency_edges[sel]]
    n = mesh.face_normals[mesh.face_adjacency[sel]]
    bis = n.sum(axis=1)
    bis /= np.linalg.norm(bis, axis=1, keepdims=True)
    keep = seg[:, :, 2].min(axis=1) > z_min
    return seg[keep], bis[keep]


def _aim_pose(
    array: WhiskerArray, module: int, point: np.ndarray, edge: np.ndarray, bisector: np.ndarray,
    radial: float, theta: float, phi: float,
) -> np.ndarray:
    """End-effector pose putting ``module``'s shaft through ``point`` at (radial, theta).

    The whisk axis is along the edge; the shaft direction at ``theta`` makes the
    angle ``phi`` with the edge-normal direction ``w = e x b`` toward ``b``, so the
    protraction motion (``z x d``) heads into the object (``-b``) for |phi| < 90 deg.
    """
    e = edge / np.linalg.norm(edge)
    b = bisector - e * (bisector @ e)
    b /= np.linalg.norm(b)
    w = np.cross(e, b)
    d = math.cos(phi) * w + math.sin(phi) * b
    z = e
    # d = Rz(theta) y  =>  y = rotation of d about z by -theta
    y = d * math.cos(-theta) + np.cross(z, d) * math.sin(-theta)
    x = np.cross(y, z)
    T_BW = np.eye(4)
    T_BW[:3, :3] = np.column_stack([x, y, z])
    T_BW[:3, 3] = point - radial * d
    return T_BW @ np.linalg.inv(array.T_EW[module])


def make_validation_set(params: ValidationSetParams = ValidationSetParams(), progress: bool = False) -> ValidationSet:
    """The array exploring the Box from held-still waypoints (Sec 4.1.2.2-4.1.2.3).

    Ground truth per contact is the rigid sweep's radial distance; contacts at
    the retraction limit (a whisker already resting on the object when the whisk
    starts, which the deflection model cannot represent) are not recorded.

    Raises
    ------
    InvalidInputError
        If fewer than ``n_waypoints`` poses are found in ``max_candidates`` tries.
    """
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.simulator import ArraySimulator
    from whisker_io.sim.sweep import MeshTarget, sweep_array

    rng = np.random.default_rng(params.seed)
    array = validation_array(params.lengths_mm)
    mesh = make_object(params.object_name)
    target = MeshTarget(mesh)
    segs, bis = _sharp_edges(mesh, z_min=0.02)
    clear = params.min_base_clearance_m
    lengths = array.lengths_m
    poses: list[np.ndarray] = []
    sweeps: list[tuple[Any, ...]] = []
    tries = 0
    bar = _progress(range(params.n_waypoints), progress, "validation waypoints")
    for k in bar:
        module = k % len(array)
        while True:
            tries += 1
            if tries > params.max_candidates:
                raise InvalidInputError(
                    f"found only {len(poses)} of {params.n_waypoints} waypoints in {params.max_candidates} "
                    "candidates; raise max_candidates or relax aim_fraction/aim_angle_deg"
                )
            j = rng.integers(len(segs))
            point = segs[j, 0] + rng.uniform(0.1, 0.9) * (segs[j, 1] - segs[j, 0])
            radial = rng.uniform(*params.aim_fraction) * lengths[module]
            theta = np.deg2rad(rng.uniform(*params.aim_angle_deg))
            phi = np.deg2rad(rng.uniform(-60.0, 60.0))
            T = _aim_pose(array, module, point, segs[j, 1] - segs[j, 0], bis[j], radial, theta, phi)
            bases = whisker_base_transforms(array, T)[:, :3, 3]
            if bases[:, 2].min() < clear or np.any(-mesh.nearest.signed_distance(bases) < clear):
                continue
            hits = sweep_array(array, target, T)
            c = hits[module]
            if c is None or abs(c.radial_distance_m - radial) > 2e-3 or abs(c.angle_rad - theta) > np.deg2rad(2.0):
                continue
            poses.append(T)
            sweeps.append(hits)
            break
    log.info("validation: %d waypoints from %d candidate poses", len(poses), tries)

    parts: list[RadialDataset] = []
    lo_angle = array.retraction_rad + np.deg2rad(0.5)
    jobs = [(w, r) for w in range(len(poses)) for r in range(params.whisks_per_waypoint)]
    for w, _ in _progress(jobs, progress, "validation whisks"):
        f = float(rng.uniform(*params.frequency_range_hz))
        pattern = WhiskPattern(
            frequency_hz=f,
            retraction_rad=array.retraction_rad,
            protraction_rad=array.protraction_rad,
            sample_rate_hz=params.signal.sample_rate_hz,
        )
        sim = ArraySimulator(array, RetractAtMax(pattern), params.signal, seed=rng)
        whisk = sim.whisk(target, poses[w])
        hits = whisk.sweep_contacts
        F, kept, onset = features_from_records(whisk.records, lengths, params.detection)
        ok = np.array([hits[i] is not None and hits[i].angle_rad > lo_angle for i in kept], dtype=bool)
        if np.any([hits[i] is None for i in kept]):
            log.warning("validation waypoint %d: contact detected on a whisker the sweep says is free", w)
        mods = kept[ok]
        parts.append(
            RadialDataset(
                F[ok],
                np.array([min(hits[i].radial_distance_m, lengths[i]) for i in mods]),
                meta={
                    "pose": np.repeat(poses[w][None], mods.size, axis=0),
                    "module": mods,
                    "angle_rad": onset[ok],
                    "true_angle_rad": np.array([hits[i].angle_rad for i in mods]),
                    "waypoint": np.full(mods.size, w),
                    "frequency_hz": np.full(mods.size, f),
                },
            )
        )
    data = RadialDataset.concatenate(parts, name=f"validation ({params.object_name})")
    return ValidationSet(data, array, mesh, np.asarray(poses))
