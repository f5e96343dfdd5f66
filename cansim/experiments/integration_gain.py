"""Path-integration linearity: decoded vs commanded packet speed in 1-D, 3-D and 6-D.

The packet is commanded to move at ``speed_cells_per_step`` along the first axis for
``duration_steps`` steps and its decoded position (Eq 5.11-5.12) is fitted by a line;
the slope is the decoded speed and ``gain = decoded / commanded``, reported with the
95% confidence interval of the slope.

* ``dynamics = False``: shifts alone (Fig 5.11, ``Population.integrate``): a weighted
  shift moves the packet's mass exactly, so the gain is 1 up to the decoder.
* ``dynamics = True``: each step is the full iteration (Alg 3-5, then the shift): the
  excitation/inhibition re-sharpen the packet every step, which pulls a fractional
  shift back toward the cell centres, so the packet lags its input - RatSLAM's gain is
  below 1 and depends on the speed's fractional part and on the kernel widths.

Grids (``ndim``): 1 - a ring of ``n_cells`` (default 120) with uniform motion; 3 -
OpenRatSLAM's pose cells (``n_cells`` x ``n_cells`` x 36, default 21; heading 0, so
the packet translates along x'); 6 - WhiskerRatSLAM's (x, y, z, roll, pitch, yaw) with
``n_cells`` cells along x (default 24) and 5 on every other axis, translating along x
at orientation 0 (Eq 5.7). The packet starts as one cell (``settle_steps`` steps at rest
first when the dynamics are on). The kernels are the same on every axis.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from cansim.axes import Axis
from cansim.experiments._ring import KERNEL_DEFAULTS, check_ring, kernel_params
from cansim.experiments.fitting import fit_line, unwrap_cells
from cansim.experiments.params import checked_seed, require, resolve
from cansim.path_integration import SixDofMotion
from cansim.population import Population

__all__ = ["check_params", "DEFAULTS", "run", "trajectory", "figure"]

DEFAULTS: dict = {
    "ndim": 1,
    "speed_cells_per_step": 0.3,
    "dynamics": True,
    "duration_steps": 100,
    "settle_steps": 20,
    "n_cells": 0,
    **KERNEL_DEFAULTS,
    "backend": "numba",
}

_DEFAULT_CELLS = {1: 120, 3: 21, 6: 24}
_CELL_M = {3: 1.0, 6: 0.02}  # metres per translational cell


def check_params(params) -> dict:
    """The cell's parameters, completed with :data:`DEFAULTS` and checked (a sweep calls it before starting)."""
    p = resolve(params, DEFAULTS, name="integration_gain", choices={"ndim": (1, 3, 6)})
    if p["n_cells"] == 0:
        p["n_cells"] = _DEFAULT_CELLS[p["ndim"]]
    n = p["n_cells"]
    require(5 <= n <= 4096, f"integration_gain: n_cells must lie in [5, 4096] (0: the preset's), got {n}")
    check_ring(p, "integration_gain", max_cells=4096)
    require(0 <= p["speed_cells_per_step"] < n / 2,
            f"integration_gain: speed_cells_per_step must lie in [0, n_cells / 2 = {n / 2}) so steps do not alias, "
            f"got {p['speed_cells_per_step']}")
    require(3 <= p["duration_steps"] <= 100_000, f"integration_gain: duration_steps must lie in [3, 1e5], got {p['duration_steps']}")
    require(0 <= p["settle_steps"] <= 10_000, f"integration_gain: settle_steps must lie in [0, 1e4], got {p['settle_steps']}")
    return p


def _population(p: dict) -> tuple[Population, object, object]:
    """The grid, and the per-step velocity and omega that command ``speed_cells_per_step`` along axis 0."""
    n, ndim, v = p["n_cells"], p["ndim"], p["speed_cells_per_step"]
    params = kernel_params(p)
    if ndim == 1:
        pop = Population((Axis.angle("heading", n),), params, backend=p["backend"])
        return pop, v * pop.axes[0].step, None
    if ndim == 3:
        pop = Population.openratslam(n, 36, _CELL_M[3], params=params, backend=p["backend"])
        pop.reset_cell([n // 2, n // 2, 0])  # heading 0: translation along +x'
        return pop, v * _CELL_M[3], 0.0
    c = _CELL_M[6]
    axes = [Axis.linear("x", n, c), Axis.linear("y", 5, c), Axis.linear("z", 5, c),
            Axis.angle("roll", 5), Axis.angle("pitch", 5), Axis.angle("yaw", 5)]
    pop = Population(axes, params, motion=SixDofMotion(), backend=p["backend"])
    pop.reset_cell([n // 2, 2, 2, 0, 0, 0])  # orientation 0: translation along +x
    return pop, np.array([v * c, 0.0, 0.0]), np.zeros(3)


def trajectory(params: dict) -> np.ndarray:
    """Decoded position along the commanded axis after each of the ``duration_steps`` steps (cells, unwrapped)."""
    p = check_params(params)
    pop, vel, om = _population(p)
    T = p["duration_steps"]
    if p["dynamics"]:
        if p["settle_steps"]:
            pop.run(n_steps=p["settle_steps"])
        start = pop.decode()[0]
        vs = np.broadcast_to(vel, (T,) + np.shape(vel))
        oms = None if om is None else np.broadcast_to(om, (T,) + np.shape(om))
        x = pop.run(vs, oms)[:, 0]
    else:
        start = pop.decode()[0]
        x = np.empty(T)
        for t in range(T):
            pop.integrate(vel, om, 1.0)
            x[t] = pop.decode()[0]
    return unwrap_cells(np.concatenate([[start], x]), p["n_cells"])[1:]


def run(params: dict, seed: int) -> dict:
    """Fit the decoded speed and the gain.

    Parameters
    ----------
    params : dict
        Any of :data:`DEFAULTS`: ``ndim`` (1, 3 or 6), ``speed_cells_per_step``,
        ``dynamics`` (False: shifts alone), ``duration_steps``, ``settle_steps``,
        ``n_cells`` (0: the preset's), kernel parameters, ``backend``.
    seed : int
        Unused (the experiment is deterministic); accepted as every experiment's.

    Returns
    -------
    dict
        The parameters and ``commanded_speed_cells_per_step``,
        ``decoded_speed_cells_per_step``, ``gain`` with ``gain_ci_low`` / ``gain_ci_high``
        (95%), ``r_squared`` of the line and ``n_fit_steps`` (the last three quarters of
        the run; the first quarter is the packet's transient).
    """
    seed = checked_seed(seed)
    p = check_params(params)
    x = trajectory(p)
    T = len(x)
    first = T // 4
    t = np.arange(1, T + 1, dtype=np.float64)
    v = p["speed_cells_per_step"]
    out = dict(p)
    out["commanded_speed_cells_per_step"] = v
    fit = fit_line(t[first:], x[first:])
    out.update(decoded_speed_cells_per_step=fit.slope, r_squared=fit.r_squared, n_fit_steps=fit.n)
    if v > 0:
        out.update(gain=fit.slope / v, gain_ci_low=fit.slope_ci_low / v, gain_ci_high=fit.slope_ci_high / v)
    else:
        out.update(gain=1.0 if abs(fit.slope) < 1e-9 else 0.0, gain_ci_low=0.0, gain_ci_high=0.0)
    return out


def figure(results: Sequence[dict]):
    """Decoded against commanded speed and the gain with its CI, one line per (ndim, dynamics).

    ``results``: :func:`run` results; returns a matplotlib Figure.
    """
    import matplotlib.pyplot as plt

    fig, (ax_v, ax_g) = plt.subplots(1, 2, figsize=(9, 3.6))
    top = max([r["speed_cells_per_step"] for r in results] + [1.0])
    ax_v.plot([0, top], [0, top], "k--", lw=0.8, label="gain 1")
    for key in sorted({(r["ndim"], r["dynamics"]) for r in results}):
        rows = sorted((r for r in results if (r["ndim"], r["dynamics"]) == key), key=lambda r: r["speed_cells_per_step"])
        xs = [r["speed_cells_per_step"] for r in rows]
        label = f"{key[0]}-D, {'dynamics' if key[1] else 'shifts alone'}"
        ax_v.plot(xs, [r["decoded_speed_cells_per_step"] for r in rows], "o-", label=label)
        moving = [r for r in rows if r["speed_cells_per_step"] > 0]
        g = np.array([r["gain"] for r in moving])
        err = np.array([[r["gain"] - r["gain_ci_low"] for r in moving], [r["gain_ci_high"] - r["gain"] for r in moving]])
        ax_g.errorbar([r["speed_cells_per_step"] for r in moving], g, yerr=err, fmt="o-", capsize=3, label=label)
    ax_v.set(xlabel="commanded speed (cells / step)", ylabel="decoded speed (cells / step)", title="Path integration")
    ax_g.set(xlabel="commanded speed (cells / step)", ylabel="gain (95% CI)", title="Gain")
    ax_v.legend(fontsize=7)
    fig.tight_layout()
    return fig
