"""Axes of a periodic population grid."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from cansim.errors import InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, validate_fields

__all__ = ["Axis"]


@dataclass(frozen=True)
class Axis(ConfigDataclass):
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
    size: int = checked(kind=int, minimum=1, maximum=sys.float_info.max, error=InvalidInputError,
                        label="axis {config.name!r}", message="{name}: size must be a positive integer, got {value!r}")
    step: float = checked(kind=float, above=0, error=InvalidInputError, reader=finite_scalar,
                          label="axis {config.name!r} step",
                          message="axis {config.name!r}: step must be a finite positive number "
                                  "(metres or radians per cell), got {value!r}")
    angular: bool = False

    def __post_init__(self) -> None:
        validate_fields(self)  # size: an int the decoders can use as a float (2 pi / size)
        if self.angular and not math.isclose(self.size * self.step, 2.0 * math.pi, rel_tol=1e-6):  # float32 steps pass
            raise InvalidInputError(
                f"axis {self.name!r}: an angular axis covers a whole turn, so its step must be 2*pi/size = "
                f"{2.0 * math.pi / self.size:.6g} rad, got {self.step!r} ({self.size} x {self.step!r} = "
                f"{self.size * self.step:.6g} rad); use Axis.angle({self.name!r}, {self.size}), or angular=False "
                "for an axis that is not an angle")

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
