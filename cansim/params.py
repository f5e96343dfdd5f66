"""Parameters of the attractor dynamics (Alg 3-5, OpenRatSLAM's step order)."""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Sequence, Union

from cansim.errors import InvalidInputError
from cansim.kernels import NORMALISATIONS, SeparableKernel
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, validate_fields, whole_number

__all__ = ["AttractorParams"]

PerAxis = Union[int, float, Sequence[float]]


def _per_axis(value: PerAxis, ndim: int, name: str) -> tuple[float, ...]:
    if isinstance(value, (numbers.Real, str, bytes)) or value is None:  # one value for every axis (checked later)
        return (value,) * ndim
    try:
        vals = tuple(value)
    except TypeError:
        raise InvalidInputError(f"{name}: expected a number or one number per axis, got {value!r}") from None
    if len(vals) != ndim:
        raise InvalidInputError(f"{name}: expected a scalar or {ndim} values (one per axis), got {len(vals)}")
    return vals


@dataclass(frozen=True)
class AttractorParams(ConfigDataclass):
    """Local excitation / inhibition and global inhibition of a CAN population.

    Each width/sigma is a scalar (same on every axis) or one value per axis.

    Parameters
    ----------
    exc_width : int or sequence of int
        Excitation kernel taps per axis, odd (OpenRatSLAM ``pc_w_e_dim``, default 7).
    exc_sigma : float or sequence of float
        Excitation standard deviation in cells (OpenRatSLAM ``pc_w_e_var``, used as sigma; 1).
    inh_width : int or sequence of int
        Inhibition kernel taps per axis, odd (``pc_w_i_dim``, default 5).
    inh_sigma : float or sequence of float
        Inhibition standard deviation in cells (``pc_w_i_var``, default 2).
    global_inhibition : float
        phi of Alg 5 (``pc_global_inhib``, default 2e-5): ``A <- max(A - phi, 0)``.

    The OpenRatSLAM names are for translating its config files; cansim's API uses these
    fields (:mod:`cansim.models.openratslam_config` maps the keys).
    kernel_normalisation : {"sum", "pdf", "none"}
        ``"sum"`` (default, OpenRatSLAM): each kernel sums to 1; ``"pdf"``: the sampled
        normal density as Eq 5.10 is printed (the thesis' 6-D preset); ``"none"``: peak 1.
    """

    exc_width: PerAxis = 7
    exc_sigma: PerAxis = 1.0
    inh_width: PerAxis = 5
    inh_sigma: PerAxis = 2.0
    global_inhibition: float = checked(2e-5, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                                       message="{name} must be finite and >= 0, got {value!r}")
    kernel_normalisation: str = checked("sum", str, choices=NORMALISATIONS, error=InvalidInputError,
                                        message=f"{{name}} must be one of {NORMALISATIONS}, got {{value!r}}")

    def __post_init__(self) -> None:
        validate_fields(self)  # numpy scalars, lists -> Python numbers, tuples (equal, hashable, JSON-able) first

    def kernels(self, ndim: int) -> tuple[SeparableKernel, SeparableKernel]:
        """The (excitation, inhibition) separable kernels for an ``ndim``-axis grid."""
        ndim = whole_number(ndim, "ndim", minimum=1)
        ew = _per_axis(self.exc_width, ndim, "exc_width")
        es = _per_axis(self.exc_sigma, ndim, "exc_sigma")
        iw = _per_axis(self.inh_width, ndim, "inh_width")
        is_ = _per_axis(self.inh_sigma, ndim, "inh_sigma")
        return (
            SeparableKernel.gaussian(ew, es, normalise=self.kernel_normalisation),
            SeparableKernel.gaussian(iw, is_, normalise=self.kernel_normalisation),
        )
