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

from cansim.errors import ZeroActivityError
from cansim.warm_up import WarmUp
from maps.odometry import SpatialOdometry

__all__ = ["WARM_UP_PLACES", "WARM_UP_LAPS", "RATSLAM_WARM_UP_PLACES", "warm_up_ratslam", "warm_up_whisker"]

#: places around the scripted circle (enough experiences for the map's pose gate)
WARM_UP_PLACES = 12
#: laps of the circle: the second revisits every place (matches, re-localisations, links)
WARM_UP_LAPS = 2
#: places of RatSLAM's scripted circle (its map has no pose gate; few steps keep the
#: spiking pose cells' warm-up, ~70 ms per step, short)
RATSLAM_WARM_UP_PLACES = 4


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
    fe = cfg.frontend
    rng = np.random.default_rng(0)  # the synthetic regions; a private generator
    pfh = rng.dirichlet(np.ones(fe.n_bins), WARM_UP_PLACES)
    sda = rng.normal(0.0, 1.0, (WARM_UP_PLACES, fe.n_whiskers))
    # one cell of translation per whisk around a circle of WARM_UP_PLACES whisks (Eq 5.7 odometry)
    odo = SpatialOdometry(np.array([cfg.cell_size_m, 0.0, 0.0]), np.array([0.0, 0.0, 2.0 * math.pi / WARM_UP_PLACES]), 1.0)
    return _scripted_laps(model, WARM_UP_PLACES, lambda scratch, k, view: scratch.step(odo, view),
                          [(pfh[k], sda[k]) for k in range(WARM_UP_PLACES)], progress)


def _scripted_laps(model: Any, places: int, step: Any, views: list, progress: bool) -> float:
    """:data:`WARM_UP_LAPS` laps of ``places`` steps on a fresh model of ``model``'s configuration,
    ``step(scratch, k, view)`` at place ``k`` with its view (none at the second place of the first
    lap: a step without contact); timed and announced by :class:`~cansim.warm_up.WarmUp`."""
    scratch = type(model)(model.config)
    scratch._warm = True  # its own first step must not warm up again
    with WarmUp(type(model).__name__, progress=progress) as w:
        for lap in range(WARM_UP_LAPS):
            w.stage(f"lap {lap + 1} of {WARM_UP_LAPS}")
            for k in range(places):
                step(scratch, k, None if (lap, k) == (0, 1) else views[k])
    return w.elapsed_s


def _ratslam_views(model: Any, observation: Any, n: int) -> list[Any]:
    """``n`` distinct observations of the kind the model's front end reads (module docstring)."""
    from cansim.frontends.tactile import TactileTemplateConfig
    from cansim.frontends.visual import VisualTemplateConfig

    fe = model.config.frontend
    rng = np.random.default_rng(0)  # the synthetic views; a private generator
    if isinstance(fe, (VisualTemplateConfig, TactileTemplateConfig)):
        if observation is not None:  # the user's own image: same dtype and shape, hence the same kernels
            base = np.asarray(observation)
        elif isinstance(fe, TactileTemplateConfig):
            base = np.zeros((3, 6), dtype=np.uint8)
        else:
            h = max(fe.crop_y_max_px or 0, fe.crop_y_min_px + 4 * fe.template_height_blocks)
            w = max(fe.crop_x_max_px or 0, fe.crop_x_min_px + 4 * fe.template_width_blocks)
            base = np.zeros((h, w), dtype=np.uint8)
        top = 255 if base.dtype.kind in "ui" else 1.0
        return [rng.integers(0, int(top) + 1, size=base.shape).astype(base.dtype) if top == 255
                else rng.uniform(0.0, 1.0, size=base.shape).astype(base.dtype) for _ in range(n)]
    return list(range(n))


def warm_up_ratslam(model: Any, observation: Any = None, *, progress: bool = False) -> float:
    """Run a scripted circle on a fresh copy of a RatSLAM's configuration (as :func:`warm_up_whisker`).

    Two laps of :data:`RATSLAM_WARM_UP_PLACES` places, one cell of translation and a
    quarter turn per step, one distinct view per place (view ids, or images of the
    shape and dtype of ``observation`` - the model's first image when the first
    :meth:`~cansim.models.ratslam.RatSLAM.step` warms up - or of the configured crop),
    one step without a view: the pose cells, the front end's matching, the experience
    map's links and relaxation all run once.

    Parameters
    ----------
    model : cansim.models.ratslam.RatSLAM
        The model whose kernels are wanted; unchanged.
    observation : optional
        An observation of the kind the model will get (its images' shape and dtype).
    progress : bool
        Show a progress line on stderr when this takes more than a second.

    Returns
    -------
    float
        Seconds taken (s).
    """
    cfg = model.config
    turn = 2.0 * math.pi / RATSLAM_WARM_UP_PLACES

    def step(scratch: Any, k: int, view: Any) -> None:
        try:
            scratch.step(cfg.cell_size_m, turn, 1.0, view)
        except ZeroActivityError:
            if cfg.pose_cells != "spiking":
                raise
            # a quarter turn an iteration outruns a spiking packet (its speeds are calibrated up to 80 cells/s; this is
            # 90 deg in 0.1 s of network time): for some seeds it dies. The scratch's state does not matter, only that
            # every kernel runs: its packets start again and the script goes on
            scratch.pose_cells.reset()

    return _scripted_laps(model, RATSLAM_WARM_UP_PLACES, step, _ratslam_views(model, observation, RATSLAM_WARM_UP_PLACES),
                          progress)
