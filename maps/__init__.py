"""maps: experience maps and object maps on networkx, relaxation, metrics.

Names below load from their submodules on first access (``import maps`` is free).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    "ExperienceMap": "experience_map",
    "MapConfig": "experience_map",
    "SE2Geometry": "se2",
    "SE3Geometry": "se3",
    "PlanarOdometry": "odometry",
    "SpatialOdometry": "odometry",
    "experience_metric": "metrics",
    "energy_metric": "metrics",
    "absolute_trajectory_error": "metrics",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'maps' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"maps.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
