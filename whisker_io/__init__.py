"""whisker_io: the whisker-tactile array, from signals to contact points and features.

Follow one whisk through the subpackages, in data-flow order:

1. ``array`` - the 18-module array (``geometry``, Fig 2.15), where it is on the arm
   (``kinematics``, Eq 5.1-5.2) and how it whisks (``control``: open loop, RCP).
2. ``sim`` - a simulated whisk: trimesh ``objects`` (the thesis objects and the
   user's own meshes) and procedural ``shapes`` (the recognition library), the
   rigid ``sweep`` of every whisker, the tapered-cantilever deflection
   ``signals`` and the ``simulator`` that ties them into one whisk per module;
   arm ``trajectories`` around an object and the ``odometry_noise`` between
   whisks (Sec 6.1.3.1.1); the ``whisk_chain`` from an arm pose (or a recorded
   session) to the region features of Ch.5. (On the robot, ``hw`` delivers the
   same whisk: the UR arm and USB array drivers, the safety envelope, the
   recorder.)
3. ``records`` - the data types every stage exchanges (``whisk_record``:
   :class:`WhiskRecord`, :class:`PoseEntry`) and their files (``recording``:
   per-whisk CSVs and the pose log).
4. ``contact`` - contact ``detection`` on the deflection signal and the per-contact
   ``features``.
5. ``features`` - the ``tactile_image``, point feature histograms (``pfh``) and the
   slope distribution (``sda``) of Ch.5, and the ``region`` features of one whisk
   that combine them; ``radial`` regresses the radial contact distance (Ch.4).
6. ``plots`` - figures of the scene and the signals (``axes``: the shared helper).

Shared by every stage (top level): ``pose`` (the one pose type), ``angles``
(angle wrapping), ``validation`` (finite-value checks), ``errors`` (the one error
tree). Test doubles of the hardware are in ``testing``.

Names listed below are importable from the package directly; each is loaded from
its submodule on first access, so ``import whisker_io`` costs nothing.
"""

from __future__ import annotations

from whisker_io._lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    # shared by every stage
    "Pose": "whisker_io.pose",
    "as_pose": "whisker_io.pose",
    "wrap_to_pi": "whisker_io.angles",
    "wrap_to_pi_closed_above": "whisker_io.angles",
    "wrap_to_2pi": "whisker_io.angles",
    # array geometry, kinematics, control
    "WhiskerArray": "whisker_io.array.geometry",
    "WhiskerModule": "whisker_io.array.geometry",
    "thesis_array": "whisker_io.array.geometry",
    "contact_points": "whisker_io.array.kinematics",
    "whisker_frames": "whisker_io.array.kinematics",
    "WhiskPattern": "whisker_io.array.control",
    "OpenLoop": "whisker_io.array.control",
    "RCP": "whisker_io.array.control",
    "RetractAtMax": "whisker_io.array.control",
    # simulation
    "MeshTarget": "whisker_io.sim.sweep",
    "SweepParams": "whisker_io.sim.sweep",
    "SweepContact": "whisker_io.sim.sweep",
    "sweep_array": "whisker_io.sim.sweep",
    "ContactNoise": "whisker_io.sim.sweep",
    "add_contact_noise": "whisker_io.sim.sweep",
    "make_object": "whisker_io.sim.objects",
    "make_maze": "whisker_io.sim.objects",
    "OBJECT_NAMES": "whisker_io.sim.objects",
    "LoadedObject": "whisker_io.sim.objects",
    "load_object": "whisker_io.sim.objects",
    "resolve_object": "whisker_io.sim.catalogue",
    "make_shape": "whisker_io.sim.shapes",
    "library_names": "whisker_io.sim.shapes",
    "object_library": "whisker_io.sim.shapes",
    "novel_names": "whisker_io.sim.shapes",
    "novel_objects": "whisker_io.sim.shapes",
    "SignalParams": "whisker_io.sim.signals",
    "WhiskContact": "whisker_io.sim.signals",
    "simulate_whisk_cycle": "whisker_io.sim.signals",
    "simulate_rod_contact": "whisker_io.sim.signals",
    "ArraySimulator": "whisker_io.sim.simulator",
    "OdometryNoise": "whisker_io.sim.odometry_noise",
    "exact_odometry": "whisker_io.sim.odometry_noise",
    "noisy_odometry": "whisker_io.sim.odometry_noise",
    "integrate_odometry": "whisker_io.sim.odometry_noise",
    "LoopShape": "whisker_io.sim.trajectories",
    "object_trajectory": "whisker_io.sim.trajectories",
    "WhiskChain": "whisker_io.sim.whisk_chain",
    "RecordedChain": "whisker_io.sim.whisk_chain",
    # records and files
    "WhiskRecord": "whisker_io.records.whisk_record",
    "PoseEntry": "whisker_io.records.whisk_record",
    "RecordingWriter": "whisker_io.records.recording",
    "replay": "whisker_io.records.recording",
    "read_whisk_csv": "whisker_io.records.recording",
    "read_pose_log": "whisker_io.records.recording",
    # contact detection and features
    "DetectionParams": "whisker_io.contact.detection",
    "detect_contact": "whisker_io.contact.detection",
    "detect_contacts": "whisker_io.contact.detection",
    "contact_features": "whisker_io.contact.features",
    "FEATURE_NAMES": "whisker_io.contact.features",
    "slope_distribution": "whisker_io.features.sda",
    "nmse": "whisker_io.features.sda",
    "tactile_image": "whisker_io.features.tactile_image",
    "tactile_image_from_angles": "whisker_io.features.tactile_image",
    "tactile_image_from_contacts": "whisker_io.features.tactile_image",
    "PFHParams": "whisker_io.features.pfh",
    "point_feature_histogram": "whisker_io.features.pfh",
    "chi_squared": "whisker_io.features.pfh",
    "RegionFeatures": "whisker_io.features.region",
    "region_features": "whisker_io.features.region",
    # errors
    "CansimError": "whisker_io.errors",
    "ConfigError": "whisker_io.errors",
    "InvalidInputError": "whisker_io.errors",
    "ShapeError": "whisker_io.errors",
    "CorruptFileError": "whisker_io.errors",
    "HardwareError": "whisker_io.errors",
    "ConnectionFailedError": "whisker_io.errors",
    "StaleStateError": "whisker_io.errors",
    "SafetyViolationError": "whisker_io.errors",
    "USBFrameError": "whisker_io.errors",
    "DeviceRemovedError": "whisker_io.errors",
    "DeviceTimeoutError": "whisker_io.errors",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
