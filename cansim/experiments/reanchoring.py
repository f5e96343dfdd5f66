"""Re-anchoring time after a view injection, vs the injection's energy and offset.

A packet settles at a random position on a 1-D ring; then a local view whose stored
pose lies ``offset_cells`` away is seen on every step and injects
``injection_energy`` into that cell before the dynamics (stored mode, Eq 5.8, at a
constant decay). The experiment records how many steps pass until the decoded
position (Eq 5.11-5.12) reaches the view's cell (within ``tolerance_cells``) and stays
there, and how it got there: a ``"jump"`` (a new packet grew at the view while the old
one died, one decoded step of more than half the offset) or a ``"drift"`` (the packet
slid over). Weak injections far away never win (``reanchored`` False).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from cansim.experiments._ring import KERNEL_DEFAULTS, check_ring, ring
from cansim.experiments.fitting import circular_distance_cells, unwrap_cells
from cansim.experiments.params import checked_seed, require, resolve

__all__ = ["check_params", "DEFAULTS", "run", "figure"]

DEFAULTS: dict = {
    "n_cells": 120,
    "offset_cells": 20.0,
    "injection_energy": 0.1,
    "duration_steps": 300,
    "settle_steps": 30,
    "tolerance_cells": 1.0,
    **KERNEL_DEFAULTS,
    "backend": "numba",
}


def check_params(params) -> dict:
    """The cell's parameters, completed with :data:`DEFAULTS` and checked (a sweep calls it before starting)."""
    p = resolve(params, DEFAULTS, name="reanchoring")
    check_ring(p, "reanchoring")
    n = p["n_cells"]
    require(abs(p["offset_cells"]) <= n / 2, f"reanchoring: |offset_cells| must be <= n_cells / 2 = {n / 2}, got {p['offset_cells']}")
    require(p["injection_energy"] >= 0, f"reanchoring: injection_energy must be >= 0, got {p['injection_energy']}")
    require(1 <= p["duration_steps"] <= 1_000_000, f"reanchoring: duration_steps must lie in [1, 1e6], got {p['duration_steps']}")
    require(0 <= p["settle_steps"] <= 100_000, f"reanchoring: settle_steps must lie in [0, 1e5], got {p['settle_steps']}")
    require(0 < p["tolerance_cells"] <= n / 4, f"reanchoring: tolerance_cells must lie in (0, n_cells / 4], got {p['tolerance_cells']}")
    return p


def run(params: dict, seed: int) -> dict:
    """Inject a view's energy every step and time the packet's arrival there.

    Parameters
    ----------
    params : dict
        Any of :data:`DEFAULTS`: ``offset_cells`` (view cell minus packet position,
        rounded to a cell), ``injection_energy`` (per step; the packet's total is 1),
        ``duration_steps``, ``settle_steps`` (steps at rest first), ``tolerance_cells``,
        ring and kernel parameters, ``backend``.
    seed : int
        The packet's start cell.

    Returns
    -------
    dict
        The parameters and ``reanchor_steps`` (first step from which the decoded position
        stays within tolerance of the view's cell; -1 if it never does), ``reanchored``,
        ``final_error_cells``, ``max_step_cells`` (largest decoded move in one step) and
        ``mode`` (``"jump"``, ``"drift"`` or ``"none"``).
    """
    seed = checked_seed(seed)
    p = check_params(params)
    rng = np.random.default_rng(seed)
    n = p["n_cells"]
    pop = ring(p)
    pop.reset_cell([int(rng.integers(n))])
    if p["settle_steps"]:
        pop.run(n_steps=p["settle_steps"])
    start = float(pop.decode()[0])
    target = int(np.round(start + p["offset_cells"])) % n
    T = p["duration_steps"]
    injection = (np.array([target]), np.array([p["injection_energy"]]))
    decoded = pop.run(n_steps=T, injections=[injection] * T)[:, 0]
    err = circular_distance_cells(decoded, target, n)
    inside = err <= p["tolerance_cells"]
    outside = np.flatnonzero(~inside)
    first = 0 if len(outside) == 0 else int(outside[-1]) + 1
    reanchored = first < T
    steps = np.abs(np.diff(unwrap_cells(np.concatenate([[start], decoded]), n)))
    max_step = float(steps.max())
    mode = "none"
    if reanchored:
        distance = float(circular_distance_cells(start, target, n))
        mode = "jump" if distance > p["tolerance_cells"] and max_step > 0.5 * distance else "drift"
    out = dict(p)
    out.update(reanchor_steps=first + 1 if reanchored else -1, reanchored=bool(reanchored),
               final_error_cells=float(err[-1]), max_step_cells=max_step, mode=mode)
    return out


def figure(results: Sequence[dict]):
    """Re-anchoring steps against the view's offset, one line per injection energy (never: not drawn).

    ``results``: :func:`run` results; returns a matplotlib Figure.
    """
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    jump_labelled = False
    for energy in sorted({r["injection_energy"] for r in results}):
        rows = sorted((r for r in results if r["injection_energy"] == energy and r["reanchored"]),
                      key=lambda r: r["offset_cells"])
        ax.plot([abs(r["offset_cells"]) for r in rows], [r["reanchor_steps"] for r in rows], "o-",
                label=f"energy {energy:g}")
        for r in rows:
            if r["mode"] == "jump":
                ax.plot(abs(r["offset_cells"]), r["reanchor_steps"], "k^", ms=4,
                        label=None if jump_labelled else "jump (a new packet grew at the view)")
                jump_labelled = True
    ax.set(xlabel="|view offset| (cells)", ylabel="time to re-anchor (steps)", title="Re-anchoring (triangles: jumps)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
