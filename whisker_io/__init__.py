"""whisker_io: the whisker-tactile array, from signals to contact points and features.

Follow one whisk through the modules: ``geometry`` (the 18-module array of Fig 2.15)
-> ``kinematics`` (Eq 5.1-5.2) -> ``sweep`` / ``objects`` / ``simulator`` (the rigid
sweep against trimesh objects and the beam-model signals of ``signals``) ->
``recording`` (per-whisk CSVs and the pose log) -> ``contact_detection`` ->
``contact_features`` / ``sda`` / ``pfh`` / ``tactile_image`` -> ``radial`` (radial
distance regression) ; ``hw`` holds the robot-arm and USB-array drivers.

Names listed below are importable from the package directly; each is loaded from
its submodule on first access, so ``import whisker_io`` costs nothing.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    # geometry and kinematics
    "WhiskerArray": "geometry",
    "WhiskerModule": "geometry",
    "thesis_array": "geometry",
    "as_transform": "kinematics",
    "contact_points": "kinematics",
    "whisker_frames": "kinematics",
    # simulator pieces
    "MeshTarget": "sweep",
    "SweepParams": "sweep",
    "SweepContact": "sweep",
    "sweep_array": "sweep",
    "ContactNoise": "sweep",
    "add_contact_noise": "sweep",
    "make_object": "objects",
    "make_maze": "objects",
    "OBJECT_NAMES": "objects",
    "ArraySimulator": "simulator",
    # signals, control, recording
    "SignalParams": "signals",
    "WhiskContact": "signals",
    "simulate_whisk_cycle": "signals",
    "simulate_rod_contact": "signals",
    "WhiskPattern": "control",
    "OpenLoop": "control",
    "RCP": "control",
    "RetractAtMax": "control",
    "WhiskRecord": "recording",
    "RecordingWriter": "recording",
    "replay": "recording",
    "read_whisk_csv": "recording",
    "read_pose_log": "recording",
    # contact detection and features
    "DetectionParams": "contact_detection",
    "detect_contact": "contact_detection",
    "detect_contacts": "contact_detection",
    "contact_features": "contact_features",
    "FEATURE_NAMES": "contact_features",
    "slope_distribution": "sda",
    "nmse": "sda",
    "tactile_image": "tactile_image",
    "tactile_image_from_angles": "tactile_image",
    "tactile_image_from_contacts": "tactile_image",
    "PFHParams": "pfh",
    "point_feature_histogram": "pfh",
    "chi_squared": "pfh",
    "match_region": "pfh",
    # errors
    "CansimError": "errors",
    "ConfigError": "errors",
    "InvalidInputError": "errors",
    "CorruptFileError": "errors",
    "HardwareError": "errors",
    "ConnectionFailedError": "errors",
    "StaleStateError": "errors",
    "SafetyViolationError": "errors",
    "USBFrameError": "errors",
    "DeviceRemovedError": "errors",
    "DeviceTimeoutError": "errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'whisker_io' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"whisker_io.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
