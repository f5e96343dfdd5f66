"""Axes of a periodic population grid."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cansim.errors import InvalidInputError

__all__ = ["Axis"]


@dataclass(frozen=True)
class Axis:
    """One periodic (wrap-around) axis of a population.

    Parameters
    ----------
    name : str
        Axis name, e.g. ``"x"``, ``"theta"``, ``"roll"``.
    size : int
        Number of cells along the axis (>= 1).
    step : float
        Physical size of one cell: metres per cell for a translational axis,
        radians per cell (``2*pi/size``) for an angular axis.
    angular : bool
        True when the axis encodes an angle (its period is ``2*pi``).
    """

    name: str
    size: int
    step: float
    angular: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.size, (int,)) or isinstance(self.size, bool) or self.size < 1:
            raise InvalidInputError(
                f"axis {self.name!r}: size must be a positive integer, got {self.size!r}"
            )
        if not (math.isfinite(self.step) and self.step > 0):
            raise InvalidInputError(
                f"axis {self.name!r}: step must be a finite positive number "
                f"(metres or radians per cell), got {self.step!r}"
            )

    @classmethod
    def linear(cls, name: str, size: int, step: float) -> "Axis":
        """A translational axis with ``step`` metres per cell."""
        return cls(name=name, size=int(size), step=float(step), angular=False)

    @classmethod
    def angle(cls, name: str, size: int) -> "Axis":
        """An angular axis of ``size`` cells covering ``2*pi`` rad (step ``2*pi/size``)."""
        return cls(name=name, size=int(size), step=2.0 * math.pi / int(size), angular=True)

    @property
    def period(self) -> float:
        """Physical length of the whole axis (``size * step``), metres or radians."""
        return self.size * self.step
