"""Small fits shared by the experiments: unwrapping decoded positions, a line with its confidence interval."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["LineFit", "fit_line", "unwrap_cells", "circular_distance_cells"]


class LineFit(NamedTuple):
    """Least-squares line ``y = intercept + slope * x``.

    Attributes
    ----------
    slope, intercept : float
    slope_ci_low, slope_ci_high : float
        Two-sided confidence interval of the slope (Student t, n - 2 degrees of freedom).
    r_squared : float
        Coefficient of determination (1 for a perfect line; 1 also when y is constant).
    n : int
        Number of points.
    """

    slope: float
    intercept: float
    slope_ci_low: float
    slope_ci_high: float
    r_squared: float
    n: int


def fit_line(x: np.ndarray, y: np.ndarray, level: float = 0.95) -> LineFit:
    """Ordinary least squares of ``y`` on ``x`` (at least 3 points) with the slope's CI at ``level``."""
    from scipy import stats

    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = len(x)
    if n < 3 or y.shape != x.shape:
        raise ValueError("fit_line needs at least 3 (x, y) points of equal length")
    xm, ym = x.mean(), y.mean()
    sxx = float(((x - xm) ** 2).sum())
    slope = float(((x - xm) * (y - ym)).sum() / sxx)
    intercept = float(ym - slope * xm)
    resid = y - (intercept + slope * x)
    ss_res = float((resid**2).sum())
    ss_tot = float(((y - ym) ** 2).sum())
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0
    se = float(np.sqrt(ss_res / (n - 2) / sxx))
    half = float(stats.t.ppf(0.5 + level / 2.0, n - 2)) * se
    return LineFit(slope, intercept, slope - half, slope + half, r2, n)


def unwrap_cells(positions: np.ndarray, n_cells: int) -> np.ndarray:
    """Decoded positions on a periodic axis of ``n_cells`` made continuous (steps of less than half the axis)."""
    ang = np.asarray(positions, dtype=np.float64) * (2.0 * np.pi / n_cells)
    return np.unwrap(ang, axis=0) * (n_cells / (2.0 * np.pi))


def circular_distance_cells(a, b, n_cells: int) -> np.ndarray:
    """Shortest distance between positions ``a`` and ``b`` on a periodic axis, in cells."""
    d = np.mod(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64), n_cells)
    return np.minimum(d, n_cells - d)
