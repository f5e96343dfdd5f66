"""Drift and diffusion of the packet under input noise.

A packet on a 1-D ring at rest is driven by noisy input for ``duration_steps`` steps in
``n_trials`` independent trials, and the decoded position's displacement is followed
(thesis Alg 3-5 with the shift of Fig 5.11):

* ``noise_kind = "velocity"``: the velocity input is zero-mean Gaussian noise of
  ``noise_std_cells`` cells per step (path-integration noise);
* ``noise_kind = "injection"``: every cell receives ``noise_energy * |N(0, 1)|`` energy
  per step before the dynamics (noisy external input, as a jittery view injection).

A random walk has a mean squared displacement (MSD) growing linearly in time,
``MSD(t) = 2 D t``; the experiment fits ``MSD(t) = a + 2 D t`` over the trials and
reports D, the fit's R^2 (near 1 when the variance grows linearly), the drift (mean
displacement per step) and, for velocity noise, D against ``noise_std_cells^2 / 2``,
the diffusion of the input itself.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from cansim.errors import ZeroActivityError
from cansim.experiments._ring import KERNEL_DEFAULTS, check_ring, ring
from cansim.experiments.fitting import fit_line, unwrap_cells
from cansim.experiments.params import checked_seed, require, resolve

__all__ = ["check_params", "DEFAULTS", "run", "msd", "figure"]

DEFAULTS: dict = {
    "n_cells": 60,
    "noise_kind": "velocity",
    "noise_std_cells": 0.3,
    "noise_energy": 0.002,
    "n_trials": 32,
    "duration_steps": 200,
    "settle_steps": 20,
    **KERNEL_DEFAULTS,
    "backend": "numba",
}


def check_params(params) -> dict:
    """The cell's parameters, completed with :data:`DEFAULTS` and checked (a sweep calls it before starting)."""
    p = resolve(params, DEFAULTS, name="diffusion", choices={"noise_kind": ("velocity", "injection")})
    check_ring(p, "diffusion")
    require(p["noise_std_cells"] >= 0, f"diffusion: noise_std_cells must be >= 0, got {p['noise_std_cells']}")
    require(p["noise_energy"] >= 0, f"diffusion: noise_energy must be >= 0, got {p['noise_energy']}")
    require(2 <= p["n_trials"] <= 10_000, f"diffusion: n_trials must lie in [2, 10000], got {p['n_trials']}")
    require(3 <= p["duration_steps"] <= 1_000_000, f"diffusion: duration_steps must lie in [3, 1e6], got {p['duration_steps']}")
    require(0 <= p["settle_steps"] <= 100_000, f"diffusion: settle_steps must lie in [0, 1e5], got {p['settle_steps']}")
    return p


def msd(params: dict, seed: int) -> tuple[np.ndarray, int]:
    """The displacement of every trial: (trials, duration_steps + 1) cells from the start, and the number collapsed.

    Trials whose packet collapsed are left out.
    """
    p = check_params(params)
    rng = np.random.default_rng(seed)
    n, T = p["n_cells"], p["duration_steps"]
    disp, collapsed = [], 0
    for _ in range(p["n_trials"]):
        pop = ring(p)
        pop.reset_cell([int(rng.integers(n))])
        step_rad = pop.axes[0].step
        try:
            if p["settle_steps"]:
                pop.run(n_steps=p["settle_steps"])
            start = pop.decode()[0]
            if p["noise_kind"] == "velocity":
                decoded = pop.run(rng.normal(0.0, p["noise_std_cells"], T) * step_rad)
            else:
                energies = p["noise_energy"] * np.abs(rng.normal(size=(T, n)))
                cells = np.arange(n)
                decoded = pop.run(n_steps=T, injections=[(cells, e) for e in energies])
        except ZeroActivityError:
            collapsed += 1
            continue
        track = unwrap_cells(np.concatenate([[start], decoded[:, 0]]), n)
        disp.append(track - track[0])
    return (np.array(disp) if disp else np.zeros((0, T + 1))), collapsed


def run(params: dict, seed: int) -> dict:
    """Fit the diffusion constant of the packet under noise.

    Parameters
    ----------
    params : dict
        Any of :data:`DEFAULTS`: ``noise_kind`` ("velocity" or "injection"),
        ``noise_std_cells`` (cells per step, velocity noise), ``noise_energy`` (per cell
        per step, injection noise), ``n_trials``, ``duration_steps``, ``settle_steps``
        (steps at rest before the noise), the ring and kernel parameters, ``backend``.
    seed : int
        Start positions and noise.

    Returns
    -------
    dict
        The parameters and ``diffusion_cells2_per_step`` (D of ``MSD = a + 2 D t``),
        ``msd_r_squared``, ``drift_cells_per_step`` (slope of the mean displacement),
        ``msd_final_cells2``, ``input_diffusion_ratio`` (D / (noise_std_cells^2 / 2) for
        velocity noise, 0 otherwise), ``n_collapsed``.
    """
    seed = checked_seed(seed)
    p = check_params(params)
    disp, collapsed = msd(p, seed)
    out = dict(p)
    t = np.arange(p["duration_steps"] + 1, dtype=np.float64)
    if len(disp) < 2:
        out.update(diffusion_cells2_per_step=0.0, msd_r_squared=0.0, drift_cells_per_step=0.0, msd_final_cells2=0.0,
                   input_diffusion_ratio=0.0, n_collapsed=collapsed)
        return out
    m = (disp**2).mean(axis=0)
    fit = fit_line(t, m)
    drift = fit_line(t, disp.mean(axis=0)).slope
    d = fit.slope / 2.0
    s2 = p["noise_std_cells"] ** 2
    out.update(
        diffusion_cells2_per_step=float(d),
        msd_r_squared=float(fit.r_squared),
        drift_cells_per_step=float(drift),
        msd_final_cells2=float(m[-1]),
        input_diffusion_ratio=float(d / (s2 / 2.0)) if p["noise_kind"] == "velocity" and s2 > 0 else 0.0,
        n_collapsed=collapsed,
    )
    return out


def figure(results: Sequence[dict]):
    """Diffusion constant against the noise level, one line per ``noise_kind``, with the fits' R^2.

    ``results``: :func:`run` results; returns a matplotlib Figure.
    """
    import matplotlib.pyplot as plt

    fig, (ax_d, ax_r) = plt.subplots(1, 2, figsize=(9, 3.6))
    for kind, level in (("velocity", "noise_std_cells"), ("injection", "noise_energy")):
        rows = sorted((r for r in results if r["noise_kind"] == kind), key=lambda r: r[level])
        if not rows:
            continue
        xs = [r[level] for r in rows]
        ax_d.plot(xs, [r["diffusion_cells2_per_step"] for r in rows], "o-", label=f"{kind} ({level})")
        ax_r.plot(xs, [r["msd_r_squared"] for r in rows], "o-", label=f"{kind} ({level})")
        if kind == "velocity":
            ax_d.plot(xs, [x * x / 2 for x in xs], "k--", lw=0.8, label="input alone (s^2 / 2)")
    xlabel = "noise level (velocity: cells/step; injection: energy)"  # the std or the energy, see the legend
    ax_d.set(xlabel=xlabel, ylabel="D (cells^2 / step)", title="Packet diffusion")
    ax_r.set(xlabel=xlabel, ylabel="R^2 of MSD = a + 2 D t", ylim=(0, 1.05), title="Linearity of the variance")
    ax_d.legend(fontsize=8)
    fig.tight_layout()
    return fig
