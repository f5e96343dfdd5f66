"""The one "draw into the given Axes, or make a new figure" helper of every plot module.

Every plotting function of the distribution (``whisker_io.plots``,
``whisker_io.radial.plots``, ``maps.plot_maps``) takes an optional matplotlib
Axes (or a sequence of Axes) and returns the Figure; these two functions make
that choice in one place. matplotlib is imported only when a new figure is made.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from whisker_io.errors import InvalidInputError, ShapeError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["figure_and_axes", "figure_and_axes_grid"]


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
