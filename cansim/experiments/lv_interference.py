"""Interference of learnt LV -> pose-cell weights as the number of stored views grows.

``n_views`` views are learnt along a route of random positions on a 1-D ring (learnt
mode, Eq 2.18: ``beta_i <- max(beta_i, lambda V_i P)``): at each position the packet
settles, the view is observed and the weights of every *active* view learn the current
packet. With ``trace_decay > 0`` earlier views are still active (their ``V`` decays by
that factor per observation), so each view's weights also hold the packets of the
views seen after it - the interference. Recall presents one view at a time (its trace
alone, Eq 2.17: ``dP = delta / eta_act * sum_i beta_i V_i``) to a packet started at a
random cell for ``recall_steps`` steps and compares the decoded position with the
view's own. As the route crowds the ring, neighbouring views' packets overlap and
their cross-talk pulls the recalled position away.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from cansim._renamed import take_renamed
from cansim.errors import ZeroActivityError
from cansim.experiments._ring import KERNEL_DEFAULTS, check_ring, ring
from cansim.experiments.fitting import circular_distance_cells
from cansim.experiments.params import checked_seed, require, resolve
from cansim.local_view import LocalViewCells, LocalViewParams

__all__ = ["check_params", "DEFAULTS", "run", "figure"]

DEFAULTS: dict = {
    "n_cells": 120,
    "n_views": 8,
    "trace_decay": 0.5,
    "inject_energy": 0.3,
    "learning_rate": 1.0,
    "settle_steps": 20,
    "recall_steps": 60,
    "tolerance_cells": 2.0,
    **KERNEL_DEFAULTS,
    "backend": "numba",
}


def check_params(params) -> dict:
    """The cell's parameters, completed with :data:`DEFAULTS` and checked (a sweep calls it before starting)."""
    if isinstance(params, Mapping) and "inject_gain" in params:  # 0.1's name, until 0.3
        params = take_renamed(params, {"inject_gain": "inject_energy"}, "lv_interference", stacklevel=4)
    p = resolve(params, DEFAULTS, name="lv_interference")
    check_ring(p, "lv_interference")
    n = p["n_cells"]
    require(1 <= p["n_views"] <= 10 * n, f"lv_interference: n_views must lie in [1, 10 n_cells], got {p['n_views']}")
    require(0 <= p["trace_decay"] < 1, f"lv_interference: trace_decay must lie in [0, 1), got {p['trace_decay']}")
    require(p["inject_energy"] >= 0 and p["learning_rate"] >= 0, "lv_interference: inject_energy and learning_rate must be >= 0")
    require(0 <= p["settle_steps"] <= 10_000 and 1 <= p["recall_steps"] <= 100_000,
            "lv_interference: settle_steps must lie in [0, 1e4] and recall_steps in [1, 1e5]")
    require(0 < p["tolerance_cells"] <= n / 4, f"lv_interference: tolerance_cells must lie in (0, n_cells / 4], got {p['tolerance_cells']}")
    return p


def _settled(pop, p, cell: int) -> None:
    pop.reset_cell([cell])
    if p["settle_steps"]:
        pop.run(n_steps=p["settle_steps"])


def run(params: dict, seed: int) -> dict:
    """Learn ``n_views`` views along a route, recall each, and measure the cross-talk.

    Parameters
    ----------
    params : dict
        Any of :data:`DEFAULTS`: ``n_views``, ``trace_decay`` (V's decay per
        observation), ``inject_energy`` (delta of Eq 2.17; 0.1's ``inject_gain`` still
        works until 0.3), ``learning_rate`` (lambda of Eq 2.18), ``settle_steps``,
        ``recall_steps``, ``tolerance_cells``, ring and kernel parameters, ``backend``.
    seed : int
        The route's positions and the recall start cells.

    Returns
    -------
    dict
        The parameters and ``recall_error_mean_cells`` / ``recall_error_max_cells`` (over
        the views), ``recall_rate`` (fraction recalled within tolerance),
        ``crosstalk_fraction`` (mean share of a view's learnt weight farther than
        ``tolerance_cells`` from its own position), ``min_spacing_cells`` (closest two
        views) and ``n_collapsed`` (recalls whose packet collapsed; counted as failures).
    """
    seed = checked_seed(seed)
    p = check_params(params)
    rng = np.random.default_rng(seed)
    n, k = p["n_cells"], p["n_views"]
    pop = ring(p)
    lv = LocalViewCells(pop.shape, LocalViewParams(mode="learnt", trace_decay=p["trace_decay"],
                                                   inject_energy=p["inject_energy"], learning_rate=p["learning_rate"]))
    route = rng.integers(0, n, k)
    places = np.empty(k)
    for i, cell in enumerate(route):  # learning: the route, in order
        _settled(pop, p, int(cell))
        places[i] = pop.decode()[0]
        lv.observe(i, places[i])
        lv.learn(pop.activity)
    weights = lv.weights.toarray().astype(np.float64)  # float32 would round the 1e-300 guard below to 0 (0/0 warnings)
    cells = np.arange(n)
    far = circular_distance_cells(cells[None, :], places[:, None], n) > p["tolerance_cells"]
    totals = weights.sum(axis=1)
    crosstalk = float(np.mean(np.where(totals > 0, (weights * far).sum(axis=1) / np.maximum(totals, 1e-300), 0.0)))
    errors, collapsed = np.empty(k), 0
    for i in range(k):  # recall: each view alone
        _settled(pop, p, int(rng.integers(n)))
        for _ in range(64):  # until the other views' traces have decayed away
            lv.observe(i, pop.decode())
        injection = lv.injection()
        try:
            decoded = pop.run(n_steps=p["recall_steps"], injections=[injection] * p["recall_steps"])
            errors[i] = float(circular_distance_cells(decoded[-1, 0], places[i], n))
        except ZeroActivityError:
            errors[i] = n / 2
            collapsed += 1
    spacing = np.sort(places)
    gaps = np.diff(np.concatenate([spacing, [spacing[0] + n]])) if k > 1 else np.array([float(n)])
    out = dict(p)
    out.update(
        recall_error_mean_cells=float(errors.mean()),
        recall_error_max_cells=float(errors.max()),
        recall_rate=float(np.mean(errors <= p["tolerance_cells"])),
        crosstalk_fraction=crosstalk,
        min_spacing_cells=float(gaps.min()),
        n_collapsed=collapsed,
    )
    return out


def figure(results: Sequence[dict]):
    """Recall rate and cross-talk against the number of stored views, one line per ``trace_decay``.

    ``results``: :func:`run` results; returns a matplotlib Figure.
    """
    import matplotlib.pyplot as plt

    fig, (ax_r, ax_c) = plt.subplots(1, 2, figsize=(9, 3.6))
    for decay in sorted({r["trace_decay"] for r in results}):
        by_k: dict = {}
        for r in results:
            if r["trace_decay"] == decay:
                by_k.setdefault(r["n_views"], []).append(r)
        ks = sorted(by_k)
        ax_r.plot(ks, [np.mean([r["recall_rate"] for r in by_k[k]]) for k in ks], "o-", label=f"trace decay {decay:g}")
        ax_c.plot(ks, [np.mean([r["crosstalk_fraction"] for r in by_k[k]]) for k in ks], "o-", label=f"trace decay {decay:g}")
    ax_r.set(xlabel="stored views", ylabel="recall rate", ylim=(-0.05, 1.05), title="Recall")
    ax_c.set(xlabel="stored views", ylabel="weight share off the view's place", title="Cross-talk")
    ax_r.legend(fontsize=8)
    fig.tight_layout()
    return fig
