"""Separable Gaussian kernels for local excitation and inhibition.

A Gaussian with a diagonal covariance is the product of 1-D Gaussians (Eq 2.19
for 3-D RatSLAM, Eq 5.10 for the 6-D grid), so every kernel here is stored as
one 1-D array per axis and applied as successive periodic 1-D passes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from cansim.errors import InvalidInputError
from whisker_io.validation import finite_scalar, whole_number

__all__ = ["gaussian_kernel_1d", "SeparableKernel"]


NORMALISATIONS = ("sum", "pdf", "none")

#: smallest kernel sigma, cells: below ~1e-154 the sigma^2 of the Gaussian underflows to 0 and the
#: centre tap is 0/0 = NaN (any sigma far below 1 cell is a one-tap kernel anyway)
MIN_SIGMA_CELLS = 1e-150
#: most taps of a 1-D kernel (a wider one is a mistyped width: 1e17 taps would not fit in memory, and a
#: 376,717-tap kernel made one step of a 12-cell ring take 16 s)
MAX_KERNEL_TAPS = 10_001


def gaussian_kernel_1d(width: int, sigma: float, *, normalise: str = "sum") -> np.ndarray:
    """Sampled 1-D Gaussian ``exp(-d^2 / (2 sigma^2))`` for ``d = -(width//2) .. width//2``.

    Parameters
    ----------
    width : int
        Number of taps, odd and >= 1 (OpenRatSLAM's ``pc_w_e_dim`` / ``pc_w_i_dim``).
    sigma : float
        Standard deviation in cells (OpenRatSLAM's ``pc_w_e_var`` is used as sigma;
        the thesis' Eq 5.10 gives a *variance*, pass ``sqrt(variance)``).
    normalise : {"sum", "pdf", "none"}
        ``"sum"``: scale the taps to sum 1 (OpenRatSLAM); ``"pdf"``: the normal density
        ``exp(-d^2 / (2 sigma^2)) / sqrt(2 pi sigma^2)`` sampled at the taps, as Eq 5.10 is
        printed (on the thesis' 5-tap 6-D kernels the excitation sums to 0.9464 over the
        window, the inhibition to 0.6430); ``"none"``: peak 1.

    Returns
    -------
    numpy.ndarray
        Shape ``(width,)``, float64; index ``width//2`` is the centre.
    """
    if not isinstance(width, (int, np.integer)) or width < 1 or width % 2 == 0 or width > MAX_KERNEL_TAPS:
        raise InvalidInputError(f"kernel width must be a positive odd integer <= {MAX_KERNEL_TAPS}, got {width!r}")
    if not finite_scalar(sigma, "kernel sigma") >= MIN_SIGMA_CELLS:
        raise InvalidInputError(f"kernel sigma must be finite and >= {MIN_SIGMA_CELLS:g} cells, got {sigma!r}")
    if normalise not in NORMALISATIONS:
        raise InvalidInputError(f"kernel normalisation must be one of {NORMALISATIONS}, got {normalise!r}")
    d = np.arange(width, dtype=np.float64) - width // 2
    k = np.exp(-(d * d) / (2.0 * sigma * sigma))
    if normalise == "sum":
        k /= k.sum()
    elif normalise == "pdf":
        k /= math.sqrt(2.0 * math.pi * sigma * sigma)
    return k


@dataclass(frozen=True)
class SeparableKernel:
    """A product kernel ``K(d_0, ..., d_{n-1}) = prod_a k_a(d_a)``, one 1-D tap array per axis.

    Parameters
    ----------
    taps : tuple of numpy.ndarray
        One odd-length 1-D array per axis, centre at ``len // 2``.
    """

    taps: tuple[np.ndarray, ...]

    @classmethod
    def gaussian(
        cls,
        widths: Sequence[int],
        sigmas: Sequence[float],
        *,
        normalise: str = "sum",
    ) -> "SeparableKernel":
        """Build a Gaussian product kernel; each 1-D factor normalised as :func:`gaussian_kernel_1d` says.

        The product of normalised factors is the normalised N-D kernel, so this equals
        OpenRatSLAM's kernel ``exp(-(dx^2+dy^2+dth^2)/(2 var^2))`` divided by its sum.
        """
        if len(widths) != len(sigmas):
            raise InvalidInputError(
                f"one kernel width per axis and one sigma per axis expected, "
                f"got {len(widths)} widths and {len(sigmas)} sigmas"
            )
        taps = tuple(
            gaussian_kernel_1d(whole_number(w, "kernel width"), finite_scalar(s, "kernel sigma"), normalise=normalise)
            for w, s in zip(widths, sigmas)
        )
        for t in taps:
            t.setflags(write=False)
        return cls(taps=taps)

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return len(self.taps)

    def dense(self) -> np.ndarray:
        """The full N-D kernel (outer product of the taps); for tests and plots only."""
        out = np.ones((), dtype=np.float64)
        for t in self.taps:
            out = np.multiply.outer(out, t)
        return out
