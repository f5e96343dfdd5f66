"""Warm-up runs of the models: every compiled kernel a configuration uses, once, on a scratch model.

A model's loop calls kernels on demand: the pose-cell step on the first whisk, the
region distances once a region is stored, the map relaxation at the first link, the
pose gate once enough experiences exist. Without a warm-up each of these compiles (or
loads from the disk cache) inside the loop, the first time its branch is taken.
:func:`warm_up_whisker` instead runs a short scripted exploration on a fresh model built
from the same configuration (same grid, storage dtype and backend, so the same kernel
signatures): two laps of a closed circle of distinct synthetic regions, one whisk
without contact, so that the second lap re-localises at every place and every branch
of the loop runs. The model being warmed is not touched (its results stay bit-identical
to a run without warm-up); only the process's compiled kernels and the disk cache are.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cansim.warm_up import WarmUp
from maps.odometry import SpatialOdometry

__all__ = ["WARM_UP_PLACES", "WARM_UP_LAPS", "warm_up_whisker"]

#: places around the scripted circle (enough experiences for the map's pose gate)
WARM_UP_PLACES = 12
#: laps of the circle: the second revisits every place (matches, re-localisations, links)
WARM_UP_LAPS = 2


def warm_up_whisker(model: Any, *, progress: bool = False) -> float:
    """Run the scripted exploration on a fresh copy of a WhiskerRatSLAM's configuration.

    Parameters
    ----------
    model : cansim.models.whisker_ratslam.WhiskerRatSLAM
        The model whose kernels are wanted; unchanged.
    progress : bool
        Show a progress line on stderr when this takes more than a second.

    Returns
    -------
    float
        Seconds taken (s).
    """
    cfg = model.config
    scratch = type(model)(cfg)
    scratch._warm = True  # its own first step must not warm up again
    fe = cfg.frontend
    rng = np.random.default_rng(0)  # the synthetic regions; a private generator
    pfh = rng.dirichlet(np.ones(fe.n_bins), WARM_UP_PLACES)
    sda = rng.normal(0.0, 1.0, (WARM_UP_PLACES, fe.n_whiskers))
    # one cell of translation per whisk around a circle of WARM_UP_PLACES whisks (Eq 5.7 odometry)
    odo = SpatialOdometry(np.array([cfg.cell_size_m, 0.0, 0.0]), np.array([0.0, 0.0, 2.0 * math.pi / WARM_UP_PLACES]), 1.0)
    with WarmUp(type(model).__name__, progress=progress) as w:
        for lap in range(WARM_UP_LAPS):
            w.stage(f"lap {lap + 1} of {WARM_UP_LAPS}")
            for k in range(WARM_UP_PLACES):
                obs = None if (lap, k) == (0, 1) else (pfh[k], sda[k])
                scratch.step(odo, obs)
    return w.elapsed_s
