"""maps: experience maps and object maps on networkx, relaxation, metrics.

Names below load from their submodules on first access (``import maps`` is free).
"""

from __future__ import annotations

from whisker_io._lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "ExperienceMap": "maps.experience_map",
    "MapConfig": "maps.experience_map",
    "SE2Geometry": "maps.se2",
    "SE3Geometry": "maps.se3",
    "PlanarOdometry": "maps.odometry",
    "SpatialOdometry": "maps.odometry",
    "ObjectMap": "maps.object_map",
    "relocalisation_errors": "maps.localisation",
    "map_pose_errors": "maps.localisation",
    "step_sizes": "maps.localisation",
    "rotation_error_rad": "maps.localisation",
    "experience_metric": "maps.metrics",
    "energy_metric": "maps.metrics",
    "absolute_trajectory_error": "maps.metrics",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
