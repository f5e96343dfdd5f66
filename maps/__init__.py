"""maps: experience maps and object maps on networkx, relaxation, metrics.

Names below load from their submodules on first access (``import maps`` is free).
"""

from __future__ import annotations

from whisker_io._lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "ExperienceMap": "maps.experience_map",
    "ExperienceMapConfig": "maps.experience_map",
    "experience_metric": "maps.metrics",
    "energy_metric": "maps.metrics",
    "absolute_trajectory_error": "maps.metrics",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
