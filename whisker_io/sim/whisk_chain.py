"""One whisk from an arm pose to the region features the front end matches (Sec 5.1.1, 6.1.3.1.2).

The chain is the thesis' sensor side of WhiskerRatSLAM, run on simulated or
recorded whisks; every step is an existing function of :mod:`whisker_io`:

1. **Whisk** at the end-effector pose against a trimesh object: the rigid sweep
   of every whisker (:func:`~whisker_io.sim.sweep.sweep_array`, Sec 4.1.2.3) and,
   on the signal path, the 2 kHz angle / deflection traces of the
   tapered-cantilever model (:class:`~whisker_io.sim.simulator.ArraySimulator`).
2. **Contact**: the sweep's first contacts (sweep path) or contact detection on
   the y-deflection (:func:`~whisker_io.contact.detection.detect_contacts`,
   Sec 5.1.1.1.1; signal and recorded paths); the contact angle is the sweep's,
   or the angle at the detected onset. Decision (simulated signal path): the
   detector's prominence and confirmation thresholds are calibrated to the
   simulated sensor as Sec 3.2.2 calibrates the contact threshold, 20 x the
   standard deviation of the y-deflection over one free-whisking cycle
   (:func:`~whisker_io.array.control.contact_threshold_from_noise`; 80 counts for
   the default 4-count noise), not the thesis' 500 counts. Those 500 counts are a
   threshold on the thesis' sensor, whose gain the simulator does not know (its
   full-scale moment is an assumption, :class:`~whisker_io.sim.signals.SignalParams`);
   on the simulated sensor they are 125 noise sigmas and reject every contact
   whose base moment stays small: a tip contact on a 160-mm whisker peaks at
   ~450 counts even 30 deg before full protraction. Measured on one loop of
   trajectory A per object (``examples/ch5_study.py``'s steps, noise-free contacts,
   seed 0), contacts detected of the sweep's and whisks with fewer than 3 contacts
   (no observation), 500 counts -> calibrated 80 counts (sweep-only path):
   Box 510 -> 680 of 720, 40 -> 12 of 88 whisks (4); Mug 107 -> 178 of 224, 15 -> 5
   of 37 (4); Barrel 81 -> 183 of 220, 10 -> 0 of 31 (0); Blob 33 -> 93 of 114,
   32 -> 19 of 37 (16); Plane 142 -> 188 of 208, 40 -> 28 of 66 (24); Kettle
   79 -> 162 of 193, 26 -> 7 of 42 (6) (``WhiskChain(mesh, signals=True,
   contact_model="tip", contact_noise=None)`` with and without
   ``detection_params=DetectionParams()``). No detection without a sweep contact
   occurred at either threshold. The recorded path (:class:`RecordedChain`, real
   sensors) keeps the thesis' values; a session recorded from the simulated signal
   path replays to the same features with
   ``RecordedChain(detection_params=chain.detection_params)``.

3. **Radial distance** along the shaft (``contact_model``):

   * ``"truth"`` - the simulator's exact radial distance (the "simulated ground
     truth process" of Sec 6.1.3.1.2; simulation only);
   * ``"tip"`` - the whisker length (the tip assumption of Ch.3/5);
   * ``"svr"`` - a trained Ch.4 regressor (``radial_model``: a ``.skops`` file
     written by :func:`whisker_io.radial.persistence.save_model` and loaded with
     its checks, a :class:`~whisker_io.radial.models.TrainedModel` or a fitted
     estimator) on the contact features CP, CA, DV, DA, AV, AA, WL
     (:func:`~whisker_io.contact.features.contact_features`); these come from
     the signals, so ``"svr"`` needs the signal or recorded path.

4. **Noise** (``contact_noise``, Sec 6.1.3.1.2; :func:`~whisker_io.sim.sweep.perturb_contacts`):
   N(0, 0.25 x whisker length) on the radial distance along the shaft, N(0, 0.33)
   on the slope, each contact registered with probability 0.98. ``None``: no
   added noise (a recorded session carries the real sensor's).
5. **Forward kinematics** (Eq 5.1-5.2) in the end-effector frame: the contact
   point of whisker i is ``T_EWi Rz(theta_c) Ty(r)``.
6. **Slopes**: Eq 6.12-6.14 (the contacted face's normal on the shaft frame at
   contact, :attr:`~whisker_io.sim.sweep.SweepContact.slope`) on the sweep path;
   the gradient of the y- against x-deflection over onset -> peak
   (:func:`~whisker_io.features.sda.slope_distribution`, Sec 5.1.1.1.3) on the
   signal and recorded paths. The two are different measurements of the surface
   (the shaft frame's x and y axes against the sensor's z and x axes, see
   :mod:`whisker_io.sim.signals`): a map built on one path is matched with
   features of the same path.
7. **Region features** (:func:`~whisker_io.features.region.region_features`): the
   PFH of the contact points (viewpoint the end-effector origin) and the SDA.

Entry points: :class:`WhiskChain` (simulated whisks, both paths; the sweep-only
path skips the signals, for the studies of thousands of whisks) and
:class:`RecordedChain` (recorded cycles: one cycle of records, or as the pipeline of
:mod:`whisker_io.hw.recorder` every cycle of a session, live or replayed from disk in
the format of :mod:`whisker_io.records.recording` as the real arm records it).

Randomness: every call takes a ``numpy.random.Generator``; the same seed gives the
same features.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
import trimesh
from numpy.typing import NDArray

from whisker_io.array.control import WhiskController
from whisker_io.array.geometry import WhiskerArray
from whisker_io.array.kinematics import rotate_shaft
from whisker_io.contact.detection import DetectedContact, DetectionParams, _detect_smoothed, warm_up_kernels
from whisker_io.contact.features import contact_features
from whisker_io.errors import ConfigError, InvalidInputError
from whisker_io.features.pfh import PFHParams
from whisker_io.features.region import RegionFeatures, region_features
from whisker_io.features.sda import _slope_distribution_smoothed
from whisker_io.pose import Pose, PoseLike, as_pose
from whisker_io.radial.pipeline import RadialPredictor, RadialSource, estimate_radial_distance, resolve_radial_model
from whisker_io.records.recording import RecordingWriter, ReplayedCycle
from whisker_io.records.whisk_record import PoseEntry, WhiskRecord
from whisker_io.sim.signals import SignalParams, free_whisking_threshold_counts
from whisker_io.sim.simulator import ArraySimulator
from whisker_io.sim.sweep import ContactNoise, MeshTarget, SweepContact, SweepParams, perturb_contacts, sweep_array

__all__ = [
    "ContactModel",
    "CHAIN_SWEEP_PARAMS",
    "ChainWhisk",
    "WhiskChain",
    "RecordedChain",
]

ContactModel = Literal["truth", "tip", "svr"]

CHAIN_SWEEP_PARAMS = SweepParams(refine_subdivisions=18, angle_tolerance_rad=1e-3)
"""Sweep parameters of the chain: contact angles to 1e-3 rad (0.06 deg, about the noise of
the angle sensor, 0.16 mm along a 160-mm whisker against the 40-mm contact-position
noise) in one refinement pass instead of the three of the default ``SweepParams``."""


def _check_generator(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise InvalidInputError(
            f"rng must be a numpy Generator (np.random.default_rng(seed)), got {type(rng).__name__}")
    return rng


def _check_contact_model(contact_model: object, radial_model: object, allowed: tuple[str, ...]) -> RadialPredictor | None:
    if contact_model not in ("truth", "tip", "svr"):
        raise ConfigError(f"unknown contact_model {contact_model!r}; use 'truth', 'tip' or 'svr'")
    if contact_model not in allowed:
        hint = ("'svr' needs the contact features of the signals: use signals=True or a recording"
                if contact_model == "svr" else "'truth' needs the simulator's ground truth: use 'tip' or 'svr'")
        raise ConfigError(f"contact_model {contact_model!r} is not available here; {hint}")
    if contact_model == "svr":
        if radial_model is None:
            raise ConfigError("contact_model='svr' needs radial_model: a .skops file path, a TrainedModel "
                              "or a fitted estimator")
        return resolve_radial_model(radial_model)  # type: ignore[arg-type]
    if radial_model is not None:
        raise ConfigError(f"radial_model is only used with contact_model='svr', not {contact_model!r}")
    return None


def _check_noise(noise: object) -> ContactNoise | None:
    if noise is not None and not isinstance(noise, ContactNoise):
        raise InvalidInputError(f"contact_noise must be a ContactNoise or None, got {type(noise).__name__}")
    return noise


def _calibrated_threshold(simulator: ArraySimulator) -> float:
    """20 x the y-deflection noise std over one free-whisking cycle of ``simulator``'s sensor
    and whisk pattern (Sec 3.2.2's calibration; module docstring, item 2), counts. The cycle
    draws from its own fixed generator, so the simulator's noise stream is unchanged."""
    return free_whisking_threshold_counts(simulator.controller.pattern, simulator.signal_params, simulator.array.names,
                                          np.random.default_rng(0))


class _Kinematics:
    """Whisker base frames in the end-effector frame, for FK of many whisks (Eq 5.1-5.2)."""

    def __init__(self, array: WhiskerArray) -> None:
        R = array.rotations
        self.base = array.positions_m
        self.x, self.y = R[:, :, 0], R[:, :, 1]
        self.length = array.lengths_m

    def points(self, theta: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
        """``T_EWi Rz(theta) Ty(r)`` per whisker, (N, 3), end-effector frame."""
        return self.base + r[:, None] * rotate_shaft(self.x, self.y, theta)


def _features(
    kin: _Kinematics,
    present: NDArray[np.bool_],
    theta: NDArray[np.float64],
    r: NDArray[np.float64],
    slope: NDArray[np.float64],
    slope_ok: NDArray[np.bool_],
    noise: ContactNoise | None,
    rng: np.random.Generator | None,
    pfh_params: PFHParams,
) -> RegionFeatures:
    """Noise (optional) -> FK -> region features from per-whisker contact arrays."""
    if noise is not None:
        present, r, slope, offset = perturb_contacts(present, r, slope, kin.length, noise, rng)
    else:
        offset = None
    theta = np.where(present, theta, 0.0)
    pts = kin.points(theta, np.where(present, r, 0.0))
    if offset is not None:
        pts = pts + offset
    mask = present & slope_ok & np.isfinite(slope)
    return region_features(pts[present], np.where(mask, slope, 0.0), mask, pfh_params)


def _signal_features(
    array: WhiskerArray,
    kin: _Kinematics,
    records: Sequence[WhiskRecord],
    detections: Sequence[DetectedContact | None],
    y_smoothed: Sequence[NDArray[np.float64]],
    contact_model: str,
    predictor: RadialPredictor | None,
    truth_radial_m: NDArray[np.float64] | None,
    noise: ContactNoise | None,
    rng: np.random.Generator | None,
    pfh_params: PFHParams,
    detection_params: DetectionParams,
) -> RegionFeatures:
    """Detected contacts of one cycle (array order) -> radial distance -> region features.

    ``y_smoothed``: the smoothed y-deflection of each record from contact detection
    (:func:`~whisker_io.contact.detection._detect_smoothed`), reused by the SDA."""
    n = len(array)
    present = np.array([d is not None for d in detections], dtype=bool)
    theta = np.array([d.contact_angle_rad if d is not None else 0.0 for d in detections])
    r = kin.length.copy()  # "tip"
    if contact_model == "truth":
        truth = np.full(n, np.nan) if truth_radial_m is None else truth_radial_m
        present &= np.isfinite(truth)  # a detection without a simulated contact has no ground truth
        r = np.where(present, truth, r)
    elif contact_model == "svr" and present.any():
        idx = np.flatnonzero(present)
        F = contact_features([records[i] for i in idx], [detections[i] for i in idx], kin.length[idx],
                             detection_params.smoothing_span)
        good = np.isfinite(F).all(axis=1)
        present[idx[~good]] = False
        if good.any():
            r[idx[good]] = estimate_radial_distance(F[good], predictor)  # type: ignore[arg-type]
    sda = _slope_distribution_smoothed(records, detections, y_smoothed, detection_params.smoothing_span)
    if sda.slopes.shape != (n,):  # pragma: no cover - records are one per module
        raise InvalidInputError(f"expected {n} records, got {sda.slopes.shape[0]}")
    return _features(kin, present, theta, r, sda.slopes, sda.mask, noise, rng, pfh_params)


@dataclass(frozen=True, eq=False)
class ChainWhisk:
    """One whisk through the chain.

    Attributes
    ----------
    pose : Pose
        End-effector pose ``T_BE`` of the whisk (world frame).
    features : RegionFeatures
        What the front end matches (contact points in the end-effector frame).
    sweep_contacts : tuple of (SweepContact or None)
        The rigid sweep's ground-truth contact per module (world frame).
    records : tuple of WhiskRecord, or None
        The simulated signals (signal path), in array order; ``None`` on the sweep path.
    detections : tuple of (DetectedContact or None), or None
        Contact detection per module (signal path).
    """

    pose: Pose
    features: RegionFeatures
    sweep_contacts: tuple[SweepContact | None, ...]
    records: tuple[WhiskRecord, ...] | None = None
    detections: tuple[DetectedContact | None, ...] | None = None

    def write(self, writer: RecordingWriter, time_s: float) -> PoseEntry:
        """Record this whisk (per-module CSVs + pose-log line) with a :class:`RecordingWriter`.

        Raises
        ------
        InvalidInputError
            On the sweep path (no signals to record).
        """
        if self.records is None:
            raise InvalidInputError("a sweep-path whisk has no signals to record; use WhiskChain(signals=True)")
        return writer.write_cycle(self.records, time_s, self.pose)


class WhiskChain:
    """Simulated whisks from arm poses to :class:`RegionFeatures` (see the module docstring).

    Parameters
    ----------
    target : trimesh.Trimesh or MeshTarget
        The object in the world frame (metres). A mesh is prepared once for ray
        casting (Embree when ``embreex`` is installed).
    array : WhiskerArray, optional
        Default the thesis' 18-module array (Fig 2.15).
    signals : bool, default False
        False: the sweep-only path (rigid sweep -> contacts, no signal
        simulation; fast). True: the signal path (sweep -> 2 kHz signals ->
        detection -> features), which is also what a recording replays.
    contact_model : {"truth", "tip", "svr"}, default "truth"
        Radial distance along the shaft (module docstring, item 3). The default with
        the default ``contact_noise`` is the thesis' simulation of Sec 6.1.3.1.2.
    radial_model : str, path or estimator, optional
        The Ch.4 regressor for ``contact_model="svr"``; loaded once here.
    contact_noise : ContactNoise or None, default ContactNoise()
        Sec 6.1.3.1.2 noise added to every contact; ``None`` for none.
    pfh_params : PFHParams
        Histogram parameters (81 bins, r = 0.3 m).
    sweep_params : SweepParams, default :data:`CHAIN_SWEEP_PARAMS`
    signal_params : SignalParams, optional
        Beam and sensor model (signal path).
    controller : WhiskController, optional
        Whisking controller (signal path; default 1-Hz open loop over the full range).
    detection_params : DetectionParams, optional
        Contact detection (signal path). Default: the thesis' pipeline with the
        prominence and confirmation thresholds calibrated to the simulated sensor
        (module docstring, item 2; :attr:`contact_threshold_counts`).

    Attributes
    ----------
    contact_threshold_counts : float or None
        The calibrated threshold (20 x the free-whisking noise std), counts, on the
        signal path; None on the sweep path.

    Raises
    ------
    ConfigError
        ``"svr"`` without ``signals`` or without a model, a model with another
        contact model, an unknown contact model.
    InvalidInputError
        A bad target, array or parameter object; the model file's errors
        (:func:`~whisker_io.radial.persistence.load_model`).

    Examples
    --------
    >>> import numpy as np
    >>> from whisker_io.sim.objects import make_object
    >>> from whisker_io.sim.trajectories import object_trajectory
    >>> mesh = make_object("box")
    >>> chain = WhiskChain(mesh)
    >>> pose = object_trajectory(mesh, "A", n_loops=1)[0]
    >>> chain.features(pose, np.random.default_rng(0)).is_observation
    True
    """

    def __init__(
        self,
        target: trimesh.Trimesh | MeshTarget,
        *,
        array: WhiskerArray | None = None,
        signals: bool = False,
        contact_model: ContactModel = "truth",
        radial_model: RadialSource | None = None,
        contact_noise: ContactNoise | None = ContactNoise(),
        pfh_params: PFHParams = PFHParams(),
        sweep_params: SweepParams = CHAIN_SWEEP_PARAMS,
        signal_params: SignalParams | None = None,
        controller: WhiskController | None = None,
        detection_params: DetectionParams | None = None,
    ) -> None:
        if isinstance(target, trimesh.Trimesh):
            target = MeshTarget(target)
        if not isinstance(target, MeshTarget):
            raise InvalidInputError(f"target must be a trimesh.Trimesh or MeshTarget, got {type(target).__name__}")
        arr = WhiskerArray.thesis() if array is None else array
        if not isinstance(arr, WhiskerArray):
            raise InvalidInputError(f"array must be a WhiskerArray, got {type(arr).__name__}")
        if not isinstance(signals, bool):
            raise InvalidInputError(f"signals must be True or False, got {signals!r}")
        allowed = ("truth", "tip", "svr") if signals else ("truth", "tip")
        self._predictor = _check_contact_model(contact_model, radial_model, allowed)
        for name, value, kind in (("pfh_params", pfh_params, PFHParams), ("sweep_params", sweep_params, SweepParams)):
            if not isinstance(value, kind):
                raise InvalidInputError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
        if detection_params is not None and not isinstance(detection_params, DetectionParams):
            raise InvalidInputError(f"detection_params must be a DetectionParams, got {type(detection_params).__name__}")
        self._simulator = (ArraySimulator(arr, controller, signal_params, sweep_params, seed=0)
                           if signals else None)
        self.contact_threshold_counts: float | None = None
        det = DetectionParams() if detection_params is None else detection_params
        if self._simulator is not None and detection_params is None:
            self.contact_threshold_counts = _calibrated_threshold(self._simulator)
            det = replace(det, min_prominence_counts=self.contact_threshold_counts,
                          confirm_threshold_counts=self.contact_threshold_counts)
        self.target = target
        self.array = arr
        self.signals = signals
        self.contact_model: str = contact_model
        self.contact_noise = _check_noise(contact_noise)
        self.pfh_params = pfh_params
        self.sweep_params = sweep_params
        self.detection_params = det
        self._kin = _Kinematics(arr)
        if signals:
            warm_up_kernels()  # the synthesis kernel was compiled by the calibration above

    def whisk(self, pose: PoseLike, rng: np.random.Generator) -> ChainWhisk:
        """Whisk once at ``pose`` and return the features with everything that led to them.

        Parameters
        ----------
        pose : PoseLike
            End-effector pose ``T_BE`` in the mesh's frame (a Pose, a 4x4 transform,
            a (position_m, quaternion_xyzw) pair; quaternion scalar-last).
        rng : numpy Generator
            Source of the contact noise (and of the sensor noise on the signal path).

        Returns
        -------
        ChainWhisk

        Raises
        ------
        InvalidInputError
            An invalid pose (NaN/inf, a non-unit quaternion) or ``rng`` not a Generator.
        """
        pose = as_pose(pose)
        gen = _check_generator(rng)
        if self._simulator is None:
            sweep = sweep_array(self.array, self.target, pose, self.sweep_params)
            present = np.array([c is not None for c in sweep], dtype=bool)
            theta = np.array([c.angle_rad if c is not None else 0.0 for c in sweep])
            slope = np.array([c.slope if c is not None else 0.0 for c in sweep])
            r = (np.array([c.radial_distance_m if c is not None else 0.0 for c in sweep])
                 if self.contact_model == "truth" else self._kin.length.copy())
            feats = _features(self._kin, present, theta, r, slope, present, self.contact_noise, gen,
                              self.pfh_params)
            return ChainWhisk(pose, feats, sweep)
        result = self._simulator.whisk(self.target, pose, rng=gen)
        found, smoothed = _detect_smoothed(result.records, self.detection_params)
        dets = tuple(found)
        truth = np.array([c.radial_distance_m if c is not None else np.nan for c in result.sweep_contacts])
        feats = _signal_features(self.array, self._kin, result.records, dets, smoothed, self.contact_model,
                                 self._predictor, truth, self.contact_noise, gen, self.pfh_params,
                                 self.detection_params)
        return ChainWhisk(pose, feats, result.sweep_contacts, result.records, dets)

    def features(self, pose: PoseLike, rng: np.random.Generator) -> RegionFeatures:
        """``whisk(pose, rng).features``: the region features of one whisk at ``pose``."""
        return self.whisk(pose, rng).features


class RecordedChain:
    """The chain for recorded whisk cycles: detection -> radial distance -> FK -> PFH + SDA.

    What a session recorded on the real arm (or written by :meth:`ChainWhisk.write`) goes
    through: the same steps as the signal path of :class:`WhiskChain`, from the records.
    It is a pipeline of :mod:`whisker_io.hw.recorder` (see :meth:`__call__`).

    Parameters
    ----------
    array : WhiskerArray, optional
        Default the thesis array; the records of a cycle are its modules, in its order.
    contact_model : {"tip", "svr"}, default "tip"
        Radial distance: the tip assumption or the regressor ``radial_model``.
    radial_model : str, path or estimator, optional
        For ``"svr"``: a ``.skops`` file (loaded once, here, with its checks), a
        :class:`~whisker_io.radial.models.TrainedModel` or a fitted estimator.
    contact_noise : ContactNoise or None, default None
        Noise added to the contacts (none for real data, which carry their own).
    pfh_params : PFHParams
    detection_params : DetectionParams, optional
        Thesis defaults (Sec 5.1.1.1.1).

    Raises
    ------
    ConfigError, InvalidInputError
        A bad contact model or model file, or bad parameter objects.

    Examples
    --------
    >>> from whisker_io.hw.recorder import replay_session
    >>> chain = RecordedChain()
    >>> whisks = replay_session("session_dir", chain)   # [(pose, features), ...]  # doctest: +SKIP
    """

    def __init__(
        self,
        *,
        array: WhiskerArray | None = None,
        contact_model: Literal["tip", "svr"] = "tip",
        radial_model: RadialSource | None = None,
        contact_noise: ContactNoise | None = None,
        pfh_params: PFHParams = PFHParams(),
        detection_params: DetectionParams | None = None,
    ) -> None:
        arr = WhiskerArray.thesis() if array is None else array
        if not isinstance(arr, WhiskerArray):
            raise InvalidInputError(f"array must be a WhiskerArray, got {type(arr).__name__}")
        self._predictor = _check_contact_model(contact_model, radial_model, ("tip", "svr"))
        det = DetectionParams() if detection_params is None else detection_params
        if not isinstance(pfh_params, PFHParams) or not isinstance(det, DetectionParams):
            raise InvalidInputError("pfh_params must be a PFHParams and detection_params a DetectionParams")
        self.array = arr
        self.contact_model: str = contact_model
        self.contact_noise = _check_noise(contact_noise)
        self.pfh_params = pfh_params
        self.detection_params = det
        self._kin = _Kinematics(arr)
        warm_up_kernels()

    def _generator(self, rng: np.random.Generator | None) -> np.random.Generator | None:
        return _check_generator(rng) if self.contact_noise is not None else None

    def features(self, records: Sequence[WhiskRecord], rng: np.random.Generator | None = None) -> RegionFeatures:
        """Region features of one whisk cycle.

        Parameters
        ----------
        records : sequence of WhiskRecord
            One record per module of the array, in array order.
        rng : numpy Generator, optional
            Needed when the chain adds ``contact_noise``.

        Raises
        ------
        InvalidInputError
            Records that are not the array's modules in order; noise without a generator.
        """
        recs = list(records)
        names = tuple(r.module if isinstance(r, WhiskRecord) else None for r in recs)
        if names != self.array.names:
            raise InvalidInputError(f"records must be one WhiskRecord per module in array order "
                                    f"{list(self.array.names)}, got {list(names)}")
        return self._features(recs, self._generator(rng))

    def _features(self, records: list[WhiskRecord], rng: np.random.Generator | None) -> RegionFeatures:
        dets, smoothed = _detect_smoothed(records, self.detection_params)
        return _signal_features(self.array, self._kin, records, dets, smoothed, self.contact_model, self._predictor,
                                None, self.contact_noise, rng, self.pfh_params, self.detection_params)

    def __call__(self, cycle: ReplayedCycle) -> tuple[Pose, RegionFeatures]:
        """The chain as a pipeline of :mod:`whisker_io.hw.recorder`: one recorded cycle -> ``(pose, features)``.

        ``Recorder(directory, pipeline=chain)`` runs it on every live cycle once it is
        on disk, and ``whisker_io.hw.recorder.replay_session(directory, chain)`` on
        every cycle of a session recorded earlier (the per-whisk CSVs and the pose
        log of :mod:`whisker_io.records.recording`), so live and replayed whisks
        take the same path. Without ``contact_noise`` (the default) nothing is drawn.

        Raises
        ------
        InvalidInputError
            Not a ``ReplayedCycle``, a cycle without one of the array's modules, or
            ``contact_noise`` set (a pipeline gets no generator: use :meth:`features`).
        """
        if not isinstance(cycle, ReplayedCycle):
            raise InvalidInputError(f"expected a ReplayedCycle, got {type(cycle).__name__}")
        missing = [m for m in self.array.names if m not in cycle.records]
        if missing:
            raise InvalidInputError(
                f"cycle {cycle.entry.whisk_file} holds modules {sorted(cycle.records)}, the chain's array has "
                f"{len(self.array.names)} ({', '.join(self.array.names)}): {missing} missing. Was the session recorded "
                "with another array? Give the chain that array (array=WhiskerArray(...)), or record with this one")
        if self.contact_noise is not None:
            raise InvalidInputError("a pipeline call draws no noise; call features(records, rng) to add contact_noise")
        return cycle.entry.pose, self._features([cycle.records[m] for m in self.array.names], None)
