"""Bump (packet) width and amplitude vs excitation/inhibition widths and global inhibition.

On a 1-D ring (thesis Alg 3-5: excitation, inhibition ``e - e (*) I``, global inhibition
``phi``, normalisation) a packet started as a Gaussian of random width and position
settles to the attractor's own shape. The experiment measures that shape after
``duration_steps`` iterations without motion: the peak activity (``amplitude``, a
fraction of the normalised total), the full width at half maximum and the standard
deviation in cells, the number of active cells, and whether the shape has stopped
changing. Wider excitation widens the packet; stronger global inhibition narrows it
until, past a threshold, no cell survives (``collapsed``).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from cansim.errors import ZeroActivityError
from cansim.experiments._ring import KERNEL_DEFAULTS, check_ring, packet_fwhm_cells, packet_std_cells, ring
from cansim.experiments.params import checked_seed, require, resolve

__all__ = ["check_params", "DEFAULTS", "run", "figure"]

DEFAULTS: dict = {
    "n_cells": 120,
    **KERNEL_DEFAULTS,
    "duration_steps": 200,
    "backend": "numba",
}


def check_params(params) -> dict:
    """The cell's parameters, completed with :data:`DEFAULTS` and checked (a sweep calls it before starting)."""
    p = resolve(params, DEFAULTS, name="bump")
    check_ring(p, "bump")
    require(1 <= p["duration_steps"] <= 1_000_000, f"bump: duration_steps must lie in [1, 1e6], got {p['duration_steps']}")
    return p


def run(params: dict, seed: int) -> dict:
    """Settle a packet and measure it.

    Parameters
    ----------
    params : dict
        Any of :data:`DEFAULTS` (others are an error): ring size ``n_cells``, kernel taps
        ``exc_width_cells`` / ``inh_width_cells`` (odd), standard deviations
        ``exc_sigma_cells`` / ``inh_sigma_cells`` (cells), ``global_inhibition`` (phi of
        Alg 5), ``duration_steps`` and the ``backend``.
    seed : int
        Picks the initial packet's position and width (0.5-3 cells).

    Returns
    -------
    dict
        The parameters used and ``amplitude`` (peak activity, total 1), ``fwhm_cells``,
        ``width_std_cells``, ``n_active_cells``, ``settled`` (relative change of the
        activity over the last step < 1e-6), ``collapsed`` (every cell fell below phi;
        the shape metrics are then 0).

    Raises
    ------
    ConfigError, InvalidInputError
        An unknown parameter or a bad value.
    """
    seed = checked_seed(seed)
    p = check_params(params)
    rng = np.random.default_rng(seed)
    pop = ring(p)
    pop.reset_gaussian([rng.uniform(0, p["n_cells"])], rng.uniform(0.5, 3.0))
    out = dict(p)
    try:
        decoded, activity = pop.run(n_steps=p["duration_steps"], record_activity=True)
    except ZeroActivityError:
        out.update(amplitude=0.0, fwhm_cells=0.0, width_std_cells=0.0, n_active_cells=0, settled=False,
                   collapsed=True)
        return out
    final = activity[-1].astype(np.float64)
    prev = activity[-2].astype(np.float64) if len(activity) > 1 else final
    change = float(np.abs(final - prev).sum())
    out.update(
        amplitude=float(final.max()),
        fwhm_cells=packet_fwhm_cells(final),
        width_std_cells=packet_std_cells(final, float(decoded[-1, 0])),
        n_active_cells=int((final > 0).sum()),
        settled=bool(change < 1e-6),
        collapsed=False,
    )
    return out


def figure(results: Sequence[dict]):
    """Packet FWHM and amplitude against ``exc_sigma_cells``, one line per ``global_inhibition``.

    ``results``: :func:`run` results (collapsed ones are drawn as crosses at 0); returns a matplotlib Figure.
    """
    import matplotlib.pyplot as plt

    fig, (ax_w, ax_a) = plt.subplots(1, 2, figsize=(9, 3.6))
    collapsed_labelled = False
    for phi in sorted({r["global_inhibition"] for r in results}):
        rows = sorted((r for r in results if r["global_inhibition"] == phi), key=lambda r: r["exc_sigma_cells"])
        xs = [r["exc_sigma_cells"] for r in rows]
        ax_w.plot(xs, [r["fwhm_cells"] for r in rows], "o-", label=f"phi = {phi:g}")
        ax_a.plot(xs, [r["amplitude"] for r in rows], "o-", label=f"phi = {phi:g}")
        dead = [r for r in rows if r["collapsed"]]
        ax_w.plot([r["exc_sigma_cells"] for r in dead], [0] * len(dead), "kx",
                  label="collapsed (no packet, drawn at 0)" if dead and not collapsed_labelled else None)
        collapsed_labelled = collapsed_labelled or bool(dead)
    ax_w.set(xlabel="excitation sigma (cells)", ylabel="packet FWHM (cells)", title="Packet width")
    ax_a.set(xlabel="excitation sigma (cells)", ylabel="peak activity (of total 1)", title="Packet amplitude")
    ax_w.legend(fontsize=8)
    fig.tight_layout()
    return fig
