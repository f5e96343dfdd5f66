"""The head-direction ring the 1-D experiments run on, and measures of its packet."""

from __future__ import annotations

import numpy as np

from cansim.axes import Axis
from cansim.params import AttractorParams
from cansim.population import Population

__all__ = ["ring", "kernel_params", "check_ring", "packet_fwhm_cells", "packet_std_cells"]

#: largest ring (cells) and kernel (taps) an experiment accepts
MAX_CELLS = 100_000
MAX_TAPS = 1001

#: the kernel parameters every 1-D experiment takes (OpenRatSLAM's defaults)
KERNEL_DEFAULTS = {
    "exc_width_cells": 7,
    "exc_sigma_cells": 1.0,
    "inh_width_cells": 5,
    "inh_sigma_cells": 2.0,
    "global_inhibition": 2e-5,
}


def check_ring(p: dict, name: str, *, max_cells: int = MAX_CELLS) -> None:
    """Bounds of the ring size and kernel parameters shared by the experiments (InvalidInputError)."""
    from cansim.experiments.params import require

    require(3 <= p["n_cells"] <= max_cells, f"{name}: n_cells must lie in [3, {max_cells}], got {p['n_cells']}")
    for key in ("exc_width_cells", "inh_width_cells"):
        require(1 <= p[key] <= MAX_TAPS and p[key] % 2 == 1, f"{name}: {key} must be an odd number of taps in [1, {MAX_TAPS}], got {p[key]}")
    for key in ("exc_sigma_cells", "inh_sigma_cells"):
        require(0 < p[key] <= 1e6, f"{name}: {key} must lie in (0, 1e6] cells, got {p[key]}")
    require(0 <= p["global_inhibition"] <= 1e6, f"{name}: global_inhibition must lie in [0, 1e6], got {p['global_inhibition']}")


def kernel_params(p: dict) -> AttractorParams:
    """The :class:`AttractorParams` of resolved experiment parameters ``p`` (kernel keys of :data:`KERNEL_DEFAULTS`)."""
    return AttractorParams(exc_width=p["exc_width_cells"], exc_sigma=p["exc_sigma_cells"],
                           inh_width=p["inh_width_cells"], inh_sigma=p["inh_sigma_cells"],
                           global_inhibition=p["global_inhibition"])


def ring(p: dict) -> Population:
    """A ring of ``p["n_cells"]`` angular cells with the kernels of ``p`` on backend ``p["backend"]``."""
    return Population((Axis.angle("heading", p["n_cells"]),), kernel_params(p), backend=p["backend"])


def packet_fwhm_cells(activity: np.ndarray) -> float:
    """Full width at half maximum of the packet around the most active cell of a ring, in cells.

    The half-maximum crossings on either side of the peak are interpolated linearly
    between cells; 0 for a silent ring, the ring's length when no cell is below half.
    """
    a = np.asarray(activity, dtype=np.float64)
    n = len(a)
    peak = int(np.argmax(a))
    top = a[peak]
    if top <= 0:
        return 0.0
    half = top / 2.0
    width = 0.0
    for direction in (1, -1):
        k = 0
        while k < n and a[(peak + direction * (k + 1)) % n] >= half:
            k += 1
        if k >= n:
            return float(n)
        inner, outer = a[(peak + direction * k) % n], a[(peak + direction * (k + 1)) % n]
        width += k + (inner - half) / (inner - outer)  # crossing between cell k and k + 1
    return float(width)


def packet_std_cells(activity: np.ndarray, centre: float) -> float:
    """Activity-weighted standard deviation of the ring's cells about ``centre`` (circular distances), in cells."""
    a = np.asarray(activity, dtype=np.float64)
    n = len(a)
    total = a.sum()
    if total <= 0:
        return 0.0
    d = (np.arange(n) - centre + n / 2.0) % n - n / 2.0
    return float(np.sqrt((a * d * d).sum() / total))
