"""Growable store of view templates shared by the visual and tactile front ends."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from whisker_io.errors import CorruptFileError

__all__ = ["TemplateMatch", "TemplateStore", "ViewMatch"]


@dataclass(frozen=True)
class TemplateMatch:
    """Result of matching one observation against the stored templates.

    Attributes
    ----------
    template_id : int
        Id of the matched template, or of the template just created.
    is_new : bool
        True when no stored template matched and the observation became a new template.
    error : float
        Matching error of the best stored template (``inf`` when none was compared).
    relative_rad : float
        Rotation (rad) between the view and the matched template (panoramic mode; else 0).
    """

    template_id: int
    is_new: bool
    error: float
    relative_rad: float = 0.0


@dataclass(frozen=True)
class ViewMatch:
    """What a front end hands the model loop for one observation.

    Attributes
    ----------
    view_id : int
        Local-view cell of the observation (consecutive from 0; a new one is ``n_views``).
    is_new : bool
        The observation became a new view.
    error : float
        Matching error of the best stored view (``inf`` when none was compared).
    offset_cells : ndarray (ndim,) or None
        Per pose-cell axis, the offset (cells) between the observation and the stored
        view (a panoramic rotation on RatSLAM's theta axis); None when there is none.
    """

    view_id: int
    is_new: bool
    error: float
    offset_cells: np.ndarray | None = None


class TemplateStore:
    """Templates of one shape in a growable float64 array, plus current/previous ids.

    Parameters
    ----------
    shape : tuple of int
        Shape of one template.
    """

    def __init__(self, shape: tuple[int, ...]) -> None:
        self.shape = tuple(int(s) for s in shape)
        self._data = np.zeros((16,) + self.shape)
        self._n = 0
        self.current_id = 0
        self.prev_id = 0

    def __len__(self) -> int:
        return self._n

    @property
    def data(self) -> np.ndarray:
        """Stored templates, shape (n,) + template shape (a read-only view)."""
        view = self._data[: self._n]
        view.flags.writeable = False
        return view

    def add(self, template: np.ndarray) -> int:
        """Append a template; returns its id."""
        if self._n == self._data.shape[0]:
            grown = np.zeros((2 * self._n,) + self.shape)
            grown[: self._n] = self._data[: self._n]
            self._data = grown
        self._data[self._n] = template
        self._n += 1
        return self._n - 1

    def set_current(self, template_id: int) -> None:
        """Record ``template_id`` as the current view (the old one becomes previous)."""
        self.prev_id = self.current_id
        self.current_id = int(template_id)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """The store as named arrays (for an ``.npz`` file); bit exact."""
        return {
            f"{prefix}templates": self._data[: self._n].copy(),
            f"{prefix}ids": np.array([self.current_id, self.prev_id], dtype=np.int64),
        }

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str) -> None:
        """Restore from :meth:`to_arrays` output; raises CorruptFileError naming a bad field."""
        for key in (f"{prefix}templates", f"{prefix}ids"):
            if key not in arrays:
                raise CorruptFileError("missing", field=key)
        data = np.asarray(arrays[f"{prefix}templates"])
        ids = np.asarray(arrays[f"{prefix}ids"])
        if data.shape[1:] != self.shape or data.dtype.kind != "f":
            raise CorruptFileError(f"shape {data.shape} / dtype {data.dtype}, expected (n,)+{self.shape} floats", field=f"{prefix}templates")
        if ids.shape != (2,) or ids.dtype.kind != "i":
            raise CorruptFileError(f"expected 2 integers, got shape {ids.shape}", field=f"{prefix}ids")
        self._data = np.zeros((max(16, data.shape[0]),) + self.shape)
        self._data[: data.shape[0]] = data
        self._n = int(data.shape[0])
        self.current_id, self.prev_id = int(ids[0]), int(ids[1])
