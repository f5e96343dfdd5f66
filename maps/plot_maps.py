"""Figures of 3-DoF RatSLAM runs: the experience map over ground truth and dead reckoning, and
the experience id over time with re-localisations marked (Fig 3.3-3.4 of the thesis).

matplotlib is imported inside the functions only. Each function draws into the
given Axes (or a new figure) and returns the Figure.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.plots.axes import figure_and_axes
from whisker_io.validation import finite_array
from maps.experience_map import ExperienceMap
from maps.metrics import absolute_trajectory_error

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_experience_ids", "plot_experience_map"]


def plot_experience_map(
    experience_map: ExperienceMap,
    truth: np.ndarray | None = None,
    dead_reckoning: np.ndarray | None = None,
    experience_log: Sequence[int] | np.ndarray | None = None,
    *,
    poses: np.ndarray | None = None,
    ax: "Axes | None" = None,
) -> "Figure":
    """Experience map (nodes and links) over the true path and dead reckoning.

    Parameters
    ----------
    experience_map : ExperienceMap
        The (relaxed) map.
    truth : array (n, 2+), optional
        True positions per iteration, metres.
    dead_reckoning : array (n, 2+), optional
        Odometry-only positions per iteration, metres.
    experience_log : sequence of int, optional
        Current experience per iteration. With ``truth`` given, the map and the
        dead reckoning are each rigidly aligned to the truth first (as for the
        absolute trajectory error) so the three can be compared by eye.
    poses : array (n_experiences, 2+), optional
        Where to draw the experiences, metres (default the map's own poses), e.g. the
        poses of :func:`maps.least_squares_relaxation.relax_least_squares`; the links are
        the map's.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    if poses is None:
        poses = experience_map.poses[:, :2]
    else:
        poses = finite_array(poses, (experience_map.n_experiences, None), "poses")
        if poses.shape[1] < 2:
            raise ShapeError(f"poses must have at least 2 columns (x, y m), got shape {poses.shape}")
        poses = poses[:, :2]
    fig, ax = figure_and_axes(ax, (6.0, 5.0))
    ends, _ = experience_map.links
    if truth is not None:
        truth = np.asarray(truth, dtype=float)[:, :2]
        ax.plot(truth[:, 0], truth[:, 1], color="0.6", lw=2.5, label="ground truth", zorder=1)
    if dead_reckoning is not None:
        dr = np.asarray(dead_reckoning, dtype=float)[:, :2]
        if truth is not None and experience_log is not None:
            dr = absolute_trajectory_error(dr, truth).aligned
        ax.plot(dr[:, 0], dr[:, 1], color="tab:orange", lw=1.0, ls="--", label="dead reckoning", zorder=2)
    if truth is not None and experience_log is not None and len(poses):
        log = np.asarray(experience_log, dtype=np.int64)
        if log.shape[0] != truth.shape[0] or log.min() < 0 or log.max() >= len(poses):
            raise InvalidInputError("experience_log must hold one valid experience id per truth row")
        res = absolute_trajectory_error(poses[log], truth)
        c, s = np.cos(res.rotation_rad), np.sin(res.rotation_rad)
        poses = poses @ np.array([[c, -s], [s, c]]).T + np.asarray(res.translation)
    if len(ends):
        segs = np.stack([poses[ends[:, 0]], poses[ends[:, 1]]], axis=1)
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(segs, colors="tab:blue", linewidths=0.8, zorder=3,
                                        label="links (odometry between experiences)"))
    if len(poses):
        ax.scatter(poses[:, 0], poses[:, 1], s=8, color="tab:blue", label="experiences", zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("Experience map")
    return fig


def plot_experience_ids(
    experience_log: Sequence[int] | np.ndarray,
    relocalisation_indices: Sequence[int] | None = None,
    base_end: int | None = None,
    *,
    correct_indices: Sequence[int] | None = None,
    kidnap_indices: Sequence[int] | None = None,
    ax: "Axes | None" = None,
) -> "Figure":
    """Experience id over iterations (Fig 3.4, 3.5): re-localisations marked, base set delimited.

    Parameters
    ----------
    experience_log : sequence of int
        Current experience per iteration.
    relocalisation_indices : sequence of int, optional
        Iterations counted as re-localisations (e.g. ``ExperienceMetricResult.relocalisation_indices``).
    base_end : int, optional
        Entries in the base set (drawn as a dotted vertical line).
    correct_indices : sequence of int, optional
        Re-localisations judged correct; the others are drawn as incorrect.
    kidnap_indices : sequence of int, optional
        Iterations at which the agent was kidnapped (moved without odometry, Fig 3.5),
        drawn as vertical lines with a legend entry.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    log = np.asarray(experience_log)
    if log.ndim != 1:
        raise InvalidInputError("experience_log must be one-dimensional")
    kidnaps = np.asarray([] if kidnap_indices is None else kidnap_indices)
    if kidnaps.size and (kidnaps.ndim != 1 or not np.issubdtype(kidnaps.dtype, np.integer)
                         or kidnaps.min() < 0 or kidnaps.max() >= log.shape[0]):
        raise InvalidInputError(f"kidnap_indices must be iteration numbers in [0, {log.shape[0]}), got {kidnap_indices!r}")
    fig, ax = figure_and_axes(ax, (8.0, 4.0))
    it = np.arange(log.shape[0])
    ax.plot(it, log, color="0.3", lw=0.8, label="current experience")
    if relocalisation_indices is not None and len(relocalisation_indices):
        r = np.asarray(relocalisation_indices, dtype=np.int64)
        if correct_indices is None:
            ax.scatter(r, log[r], s=6, color="tab:green", label="re-localisation", zorder=3)
        else:
            good = np.isin(r, np.asarray(correct_indices, dtype=np.int64))
            ax.scatter(r[good], log[r[good]], s=6, color="tab:green", label="correct re-localisation", zorder=3)
            if np.any(~good):
                ax.scatter(r[~good], log[r[~good]], s=14, marker="x", color="tab:red", label="incorrect re-localisation", zorder=4)
    if base_end is not None:
        ax.axvline(base_end - 0.5, color="tab:red", ls=":", label="end of base set")
    for j, k in enumerate(kidnaps.tolist()):
        ax.axvline(k - 0.5, color="tab:purple", lw=1.0, label="kidnapped" if j == 0 else None)
    ax.set_xlabel("iteration")
    ax.set_ylabel("experience id")
    ax.legend(loc="upper left", fontsize="small")
    ax.set_title("Experience id over time")
    return fig
