"""A template front end's panoramic rotation as a pose-cell offset on the heading axis.

The visual and tactile template matchers report a :class:`~cansim.frontends.store.TemplateMatch`
with ``relative_rad``, the rotation between the view and the matched template
(OpenRatSLAM's ``vt_relative_rad``). The model loop takes a per-axis ``offset_cells``;
:class:`HeadingOffset` converts one into the other for a grid whose heading axis has
``heading_cells`` cells (``relative_rad / 2 pi * heading_cells`` cells, as OpenRatSLAM's
``vt_delta_pc_th``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cansim.frontends.store import ViewMatch
from whisker_io.validation import config_field

__all__ = ["HeadingOffset"]


class HeadingOffset:
    """Wrap a template front end (``match`` -> ``TemplateMatch``) as a loop front end (-> ``ViewMatch``).

    Parameters
    ----------
    templates : VisualTemplates or TactileTemplates
    ndim : int
        Pose-grid dimension.
    heading_axis : int
        Axis that a panoramic rotation shifts.
    heading_cells : int
        Cells on that axis.
    """

    def __init__(self, templates: Any, ndim: int, heading_axis: int, heading_cells: int) -> None:
        self.templates = templates
        self.ndim = int(config_field(ndim, "ndim", int, minimum=1))
        self.heading_axis = int(config_field(heading_axis, "heading_axis", int, minimum=0, maximum=self.ndim - 1))
        self.heading_cells = int(config_field(heading_cells, "heading_cells", int, minimum=1))

    def __len__(self) -> int:
        return len(self.templates)

    def match(self, observation: Any) -> ViewMatch:
        """Match with the wrapped front end; a non-zero rotation becomes ``offset_cells``."""
        m = self.templates.match(observation)
        th_off = m.relative_rad / (2.0 * math.pi) * self.heading_cells
        off = None
        if th_off:
            off = np.zeros(self.ndim)
            off[self.heading_axis] = th_off
        return ViewMatch(m.template_id, bool(m.is_new), m.error, off)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        """The wrapped front end's state."""
        return self.templates.to_arrays(prefix)

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str) -> None:
        """Restore the wrapped front end's state."""
        self.templates.from_arrays(arrays, prefix)
