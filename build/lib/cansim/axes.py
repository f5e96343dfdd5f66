"""Axes of a periodic population grid."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cansim.errors import InvalidInputError
from whisker_io.validation import finite_scalar

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
        if not isinstance(self.size, (int,)):
            raise InvalidInputError(f"axis {self.name!r}: size must be a positive integer, got {self.size!r}")
        _cells(self.name, self.size)
        if not finite_scalar(self.step, f"axis {self.name!r} step") > 0:
            raise InvalidInputError(
                f"axis {self.name!r}: step must be a finite positive number "
                f"(metres or radians per cell), got {self.step!r}"
            )

    @classmethod
    def linear(cls, name: str, size: int, step: float) -> "Axis":
        """A translational axis with ``step`` metres per cell."""
        return cls(name=name, size=_cells(name, size), step=finite_scalar(step, f"axis {name!r} step"), angular=False)

    @classmethod
    def angle(cls, name: str, size: int) -> "Axis":
        """An angular axis of ``size`` cells covering ``2*pi`` rad (step ``2*pi/size``)."""
        n = _cells(name, size)
        return cls(name=name, size=n, step=2.0 * math.pi / n, angular=True)

    @property
    def period(self) -> float:
        """Physical length of the whole axis (``size * step``), metres or radians."""
        return self.size * self.step


def _cells(name: str, size: object) -> int:
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, (int, np.integer)) or size < 1:
        raise InvalidInputError(f"axis {name!r}: size must be a positive integer, got {size!r}")
    finite_scalar(size, f"axis {name!r} size")  # the step 2 pi / size and the decoders need it as a float
    return int(size)
