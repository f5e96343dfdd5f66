"""Figures of the radial-distance study (thesis Fig 4.6, 4.8-4.11).

matplotlib is imported inside the functions only. Every function takes optional
Axes to draw into and returns the Figure.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from whisker_io.plots.axes import boxplot_handles, figure_and_axes, figure_and_axes_grid
from whisker_io.radial.evaluation import PCAResult

__all__ = ["plot_pca_loadings", "plot_histograms", "plot_boxplots"]


def plot_pca_loadings(pca: PCAResult, axes: Sequence[Any] | None = None) -> Any:
    """Bar plots of the loadings of the leading principal components (Fig 4.6 style).

    Parameters
    ----------
    pca : PCAResult
        From :func:`whisker_io.radial.evaluation.pca_loadings`.
    axes : sequence of Axes, optional
        One per component; created side by side if omitted.
    """
    k = pca.components.shape[0]
    fig, axs = figure_and_axes_grid(k, axes, ncols=k, size=(3.2, 3.0))
    x = np.arange(len(pca.feature_names))
    for i, ax in enumerate(axs):
        ax.bar(x, pca.components[i], color="tab:blue")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xticks(x, pca.feature_names)
        ax.set_ylim(-1, 1)
        ax.set_title(f"PC{i + 1} ({100 * pca.explained_variance_ratio[i]:.0f}% var.)")
        ax.set_xlabel("feature")
        ax.set_ylabel("coefficient (standardised features)" if i == 0 else "coefficient")
    fig.tight_layout()
    return fig


def plot_histograms(
    samples: Mapping[str, Any],
    xlabel: str,
    axes: Sequence[Any] | None = None,
    bins: int = 40,
    value_range: tuple[float, float] | None = None,
    ncols: int = 4,
    title: str | None = None,
    unit: str = "",
) -> Any:
    """One histogram per model with its median and standard deviation (Fig 4.8/4.9 style).

    Values outside ``value_range`` are not drawn (nothing is clipped into the edge
    bins); each panel says how many fell below and above its axis, and a triangle at
    that edge marks the side. The median and standard deviation in the title are of
    all values.

    Parameters
    ----------
    samples : mapping label -> array (n,)
        For example Eq 4.1 errors or point-to-mesh distances per model.
    xlabel : str
        Label of the value axis, with its unit.
    axes : sequence of Axes, optional
    bins : int
    value_range : (lo, hi), optional
        Common histogram range; default the pooled 1st-99th percentile.
    ncols : int
    title : str, optional
        Figure title (what the panels show), above the per-model panels.
    unit : str
        The values' unit, written after the median and standard deviation in each panel's title
        (e.g. ``"mm"``; default none, for a ratio).

    Returns
    -------
    matplotlib.figure.Figure
    """
    labels = list(samples)
    fig, axs = figure_and_axes_grid(len(labels), axes, ncols=min(ncols, max(1, len(labels))), size=(3.0, 2.4))
    if value_range is None:
        pooled = np.concatenate([np.asarray(samples[k], dtype=float) for k in labels])
        lo, hi = np.percentile(pooled, [1, 99]) if pooled.size else (-1.0, 1.0)
        value_range = (float(lo), float(hi) if hi > lo else float(lo) + 1.0)
    lo, hi = value_range
    for ax, lab in zip(axs, labels):
        v = np.asarray(samples[lab], dtype=float)
        below, above = int(np.sum(v < lo)), int(np.sum(v > hi))
        ax.hist(v[(v >= lo) & (v <= hi)], bins=bins, range=value_range, color="tab:gray")
        ax.set_xlim(lo, hi)
        ax.axvline(0.0, color="k", lw=0.6)
        if v.size:
            u = f" {unit}" if unit else ""
            ax.set_title(f"{lab}\nmedian {np.median(v):.3g}{u}, std {np.std(v):.3g}{u}", fontsize=8)
        if below or above:
            ax.text(
                0.98, 0.97, f"outside the axis: {below} below, {above} above\n(of {v.size}; not drawn)",
                transform=ax.transAxes, ha="right", va="top", fontsize=6, color="tab:red",
            )
            for side, n in ((0.0, below), (1.0, above)):
                if n:
                    ax.plot([side], [0.0], marker="<" if side == 0.0 else ">", color="tab:red", ms=6,
                            transform=ax.transAxes, clip_on=False)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("count (contacts)", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def plot_boxplots(
    groups: Mapping[str, Any],
    ylabel: str,
    ax: Any = None,
    title: str | None = None,
    ymax: float | None = None,
    xlabel: str = "model",
) -> Any:
    """Notched box plots, one box per group (Fig 4.10/4.11 style).

    Non-overlapping notches mark medians different at about the 5 % level; a legend
    says what the box, whiskers and median line are.

    Parameters
    ----------
    groups : mapping label -> array (n,)
    ylabel : str
    ax : Axes, optional
    title : str, optional
    ymax : float, optional
        Upper y-limit (the thesis caps at 30 % of whisker length). A box or whisker that
        reaches above it is named in a note at the top of the axes, with its median and
        upper quartile, and marked by a triangle at the top edge.
    xlabel : str
        What the groups are (default "model").
    """
    fig, ax = figure_and_axes(ax, (1.4 * max(3, len(groups)) + 1.5, 4.0))
    labels = list(groups)
    parts = ax.boxplot([np.asarray(groups[k], dtype=float) for k in labels], notch=True, showfliers=False)
    ax.set_xticks(np.arange(1, len(labels) + 1), labels, rotation=30, ha="right", fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if parts["boxes"]:
        ax.legend(handles=boxplot_handles(parts), fontsize=7, loc="best")
    if ymax is not None:
        ax.set_ylim(bottom=0.0, top=ymax)
        above = []
        for i, k in enumerate(labels):
            v = np.asarray(groups[k], dtype=float)
            v = v[np.isfinite(v)]
            if v.size and max(float(np.max(parts["whiskers"][2 * i + 1].get_ydata())), float(np.percentile(v, 75))) > ymax:
                above.append(f"{k}: median {np.median(v):.3g}, upper quartile {np.percentile(v, 75):.3g}")
                ax.plot([i + 1], [ymax], marker="^", color="tab:red", ms=7, clip_on=False)
        if above:
            ax.text(0.02, 0.98, "beyond the axis (not all drawn):\n" + "\n".join(above), transform=ax.transAxes,
                    ha="left", va="top", fontsize=6, color="tab:red")
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig
