"""The one "draw into the given Axes, or make a new figure" helper of every plot module.

Every plotting function of the distribution (``whisker_io.plots``,
``whisker_io.radial.plots``, ``maps.plot_maps``) takes an optional matplotlib
Axes (or a sequence of Axes) and returns the Figure; these two functions make
that choice in one place. matplotlib is imported only when a new figure is made.
:func:`boxplot_handles` is the key every box plot of the project puts in its legend.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from whisker_io.errors import InvalidInputError, ShapeError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["figure_and_axes", "figure_and_axes_grid", "boxplot_handles"]


def figure_and_axes(
    ax: Axes | None, figsize: tuple[float, float], projection: str | None = None
) -> tuple[Figure, Axes]:
    """The figure of ``ax``, or a new figure with one Axes.

    Parameters
    ----------
    ax : matplotlib Axes or None
        Axes to draw into; ``None`` makes a new figure.
    figsize : (float, float)
        Size of a new figure, inches.
    projection : str, optional
        Projection of a new Axes (``"3d"`` for a 3-D scene).

    Returns
    -------
    (Figure, Axes)

    Raises
    ------
    InvalidInputError
        ``ax`` is neither None nor a matplotlib Axes.
    """
    if ax is not None:
        if not hasattr(ax, "figure") or not hasattr(ax, "plot"):
            raise InvalidInputError(f"ax must be a matplotlib Axes or None, got {type(ax).__name__}")
        return ax.figure, ax
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=figsize)
    return fig, fig.add_subplot(projection=projection)


def figure_and_axes_grid(
    n: int, axes: Sequence[Any] | None, ncols: int, size: tuple[float, float]
) -> tuple[Figure, list[Axes]]:
    """The figure of ``n`` given Axes, or a new grid of ``n`` panels.

    Parameters
    ----------
    n : int
        Number of panels needed.
    axes : sequence of Axes (any nesting) or None
        Axes to draw into (at least ``n``); ``None`` makes a new figure.
    ncols : int
        Columns of a new grid; unused panels are hidden.
    size : (float, float)
        Size of one panel of a new grid, inches.

    Returns
    -------
    (Figure, list of n Axes)

    Raises
    ------
    ShapeError
        Fewer than ``n`` Axes were given.
    """
    if axes is not None:
        given = list(np.ravel(np.asarray(axes, dtype=object)))
        if len(given) < n:
            raise ShapeError(f"need {n} axes, got {len(given)}; pass at least {n} or none")
        return given[0].figure, given[:n]
    import matplotlib.pyplot as plt

    nrows = max(1, int(np.ceil(n / ncols)))
    fig, grid = plt.subplots(nrows, ncols, figsize=(size[0] * ncols, size[1] * nrows), squeeze=False)
    flat = list(grid.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def boxplot_handles(parts: dict[str, list[Any]]) -> list[Any]:
    """Legend handles that say what the marks of a matplotlib box plot are.

    A box plot draws the median (a coloured line), the box (quartiles), the whiskers
    (the furthest data within 1.5 IQR of the box, matplotlib's default) and, when
    shown, the outliers beyond them; a reader of the figure needs that key.

    Parameters
    ----------
    parts : dict
        What ``Axes.boxplot`` returned (``"medians"``, ``"boxes"``, ``"fliers"`` ...).

    Returns
    -------
    list of matplotlib.lines.Line2D
        Handles for ``Axes.legend(handles=...)``; empty when nothing was drawn.
    """
    from matplotlib.lines import Line2D

    handles: list[Any] = []
    if not parts.get("boxes"):
        return handles
    notched = len(parts["boxes"][0].get_xdata()) > 5  # a notched box has 11 vertices, a plain one 5
    median = parts["medians"][0]
    handles.append(Line2D([], [], color=median.get_color(),
                          label="median" + (" (notch: ~95 % CI of the median)" if notched else "")))
    handles.append(Line2D([], [], color=parts["boxes"][0].get_color(), label="box: quartiles; whiskers: data within 1.5 IQR"))
    shown = [f for f in parts.get("fliers", []) if len(f.get_xdata())]
    if shown:
        f = shown[0]
        handles.append(Line2D([], [], ls="", marker=f.get_marker(), mec=f.get_markeredgecolor(), mfc=f.get_markerfacecolor(),
                              color=f.get_color(), label="outlier (beyond the whiskers)"))
    return handles
