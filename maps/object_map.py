"""WhiskerRatSLAM's object map: the experience map on SE(3) plus the experience history (thesis Sec 5.1.2.4).

An object map is an :class:`~maps.experience_map.ExperienceMap` with the
:class:`~maps.se3.SE3Geometry` (positions and scalar-last unit quaternions, first
experience at the identity; Alg 6): complex experiences hold the pose-cell location,
the region (local-view id, whose PFH and SDA the whisk front end stores) and the map
pose; links hold the relative translation and rotation. On top of the core it keeps
the *experience history*, the current experience at every iteration, which Ch.5's
recognition (leaky integration of re-localisations) and Ch.6's follow-experience-history
search read. The history is saved with the map.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from maps.experience_map import ExperienceMap, MapConfig
from maps.se3 import SE3Geometry
from whisker_io.errors import CorruptFileError, InvalidInputError

__all__ = ["ObjectMap"]


class ObjectMap(ExperienceMap):
    """An SE(3) experience map with its experience history.

    Parameters
    ----------
    config : MapConfig
        Core parameters (``pc_shape`` of the 6-D pose cells, ``offset_axes=()``).
    geometry : SE3Geometry, optional
    """

    def __init__(self, config: MapConfig | None = None, geometry: SE3Geometry | None = None) -> None:
        config = config if config is not None else MapConfig(
            pc_shape=(5,) * 6, offset_axes=(), match_distance_cells=1.0, keep_first_accumulator=False
        )
        super().__init__(config, geometry if geometry is not None else SE3Geometry())
        if not isinstance(self.geometry, SE3Geometry):
            raise InvalidInputError("an ObjectMap needs the SE3Geometry")
        self._history = np.zeros(64, dtype=np.int64)
        self._n_hist = 0

    @property
    def history(self) -> np.ndarray:
        """Current experience per recorded iteration, (n_iterations,) int64 (-1 before the first); a copy."""
        return self._history[: self._n_hist].copy()

    def record(self) -> None:
        """Append the current experience (or -1 while empty) to the history (one call per iteration)."""
        if self._n_hist == len(self._history):
            self._history = np.concatenate([self._history, np.zeros(len(self._history), dtype=np.int64)])
        self._history[self._n_hist] = self.current_id if self.n_experiences else -1
        self._n_hist += 1

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The map's arrays plus ``history``."""
        arrays = super().to_arrays(prefix)
        arrays[prefix + "history"] = self.history
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> "ObjectMap":
        """Rebuild from :meth:`to_arrays` output (raises CorruptFileError naming a bad field)."""
        om = super().from_arrays(arrays, prefix)
        key = prefix + "history"
        if key not in arrays:
            raise CorruptFileError("missing", field=key)
        h = np.asarray(arrays[key])
        if h.ndim != 1 or h.dtype.kind != "i" or (len(h) and (h.min() < -1 or h.max() >= om.n_experiences)):
            raise CorruptFileError(f"expected experience ids in [-1, {om.n_experiences}), got {h.dtype} {h.shape}", field=key)
        om._history = np.concatenate([h.astype(np.int64), np.zeros(64, dtype=np.int64)])
        om._n_hist = len(h)
        return om
