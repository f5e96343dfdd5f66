"""Front end for precomputed view ids (the observation is the id of a view already recognised elsewhere).

External ids are any non-negative integers; first-seen order numbers the local-view
cells. An observation may carry a per-axis offset: ``(view_id, offset_cells)`` with
``offset_cells`` of the pose grid's dimension, or - for a grid with a heading axis -
``(view_id, relative_rad)``, OpenRatSLAM's ``ViewTemplate`` message (the rotation of a
panoramic match, converted to cells on that axis).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from whisker_io.errors import CorruptFileError, InvalidInputError
from cansim.frontends.store import ViewMatch
from whisker_io.validation import config_field

__all__ = ["IdsFrontEnd"]

_MAX_ID = 2**62


class IdsFrontEnd:
    """View ids in, local-view cells out.

    Parameters
    ----------
    ndim : int
        Pose-grid dimension (length of ``offset_cells``).
    heading_axis : int or None
        Axis of a ``(view_id, relative_rad)`` rotation; None: offsets are given in cells.
    heading_cells : int
        Cells on the heading axis (2 pi per ``heading_cells``).
    """

    def __init__(self, ndim: int, heading_axis: int | None = None, heading_cells: int = 36) -> None:
        self.ndim = int(config_field(ndim, "ndim", int, minimum=1))
        self.heading_axis = config_field(heading_axis, "heading_axis", int, minimum=0, maximum=self.ndim - 1, optional=True)
        self.heading_cells = int(config_field(heading_cells, "heading_cells", int, minimum=1))
        self._ids: dict[int, int] = {}

    def __len__(self) -> int:
        return len(self._ids)

    def _parse(self, observation: Any) -> tuple[int, np.ndarray | None]:
        off = None
        if isinstance(observation, tuple):
            if len(observation) != 2:
                raise InvalidInputError(f"a (view_id, offset) observation needs 2 entries, got {len(observation)}")
            observation, raw = observation
            if self.heading_axis is not None and np.ndim(raw) == 0:
                try:
                    rad = float(raw)
                except (TypeError, ValueError):
                    raise InvalidInputError(f"relative_rad must be a real number, got {raw!r}") from None
                if not math.isfinite(rad) or abs(rad) > 1e3:
                    raise InvalidInputError(f"relative_rad must be a finite rotation within +-1000 rad, got {rad!r}")
                th_off = rad / (2.0 * math.pi) * self.heading_cells
                if th_off:
                    off = np.zeros(self.ndim)
                    off[self.heading_axis] = th_off
            else:
                try:
                    off = np.array(raw, dtype=np.float64).reshape(-1)
                except (TypeError, ValueError):
                    raise InvalidInputError(f"offset_cells must be {self.ndim} real numbers, got {raw!r}") from None
                if off.shape != (self.ndim,) or not np.isfinite(off).all() or np.abs(off).max(initial=0) > 1e6:
                    raise InvalidInputError(f"offset_cells must be {self.ndim} finite values within +-1e6 cells, got {raw!r}")
        if isinstance(observation, (bool, np.bool_)) or not isinstance(observation, (int, np.integer)):
            raise InvalidInputError(
                f"the ids front end takes an integer view id (or a (view_id, offset) pair), got "
                f"{type(observation).__name__}; use the visual or tactile front end for images"
            )
        ext = int(observation)
        if not 0 <= ext < _MAX_ID:
            raise InvalidInputError(f"view ids must lie in [0, 2**62), got {ext}")
        return ext, off

    def match(self, observation: Any) -> ViewMatch:
        """Map an external id to its local-view cell (validates first; only a new id is recorded)."""
        ext, off = self._parse(observation)
        internal = self._ids.get(ext)
        if internal is None:
            internal = self._ids[ext] = len(self._ids)
            return ViewMatch(internal, True, math.inf, off)
        return ViewMatch(internal, False, 0.0, off)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """State as named arrays (bit exact)."""
        return {f"{prefix}ids_map": np.array(sorted(self._ids.items()), dtype=np.int64).reshape(-1, 2)}

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str) -> None:
        """Restore :meth:`to_arrays` output; raises CorruptFileError naming a bad field."""
        key = f"{prefix}ids_map"
        if key not in arrays:
            raise CorruptFileError("missing", field=key)
        ids = np.asarray(arrays[key])
        if ids.ndim != 2 or ids.shape[1] != 2 or ids.dtype.kind != "i" or (len(ids) and ids.min() < 0):
            raise CorruptFileError(f"expected an (n, 2) array of non-negative integers, got {ids.shape} {ids.dtype}", field=key)
        mapping = {int(a): int(b) for a, b in ids.tolist()}
        if sorted(mapping.values()) != list(range(len(mapping))) or len(mapping) != len(ids):
            raise CorruptFileError("internal ids must be 0..n-1, each once", field=key)
        self._ids = mapping
