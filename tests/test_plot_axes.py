"""The shared axes helper (whisker_io.plots.axes): reuse a given Axes or make a figure."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from whisker_io.errors import InvalidInputError, ShapeError  # noqa: E402
from whisker_io.plots.axes import figure_and_axes, figure_and_axes_grid  # noqa: E402


def test_given_axes_is_reused_and_new_one_has_the_size():
    fig, ax = plt.subplots()
    assert figure_and_axes(ax, (1.0, 1.0)) == (fig, ax)
    new_fig, new_ax = figure_and_axes(None, (3.0, 2.0))
    assert new_fig is not fig and new_ax.figure is new_fig
    assert tuple(new_fig.get_size_inches()) == (3.0, 2.0)
    _, ax3 = figure_and_axes(None, (3.0, 3.0), projection="3d")
    assert ax3.name == "3d"
    plt.close("all")


def test_bad_axes_are_typed_errors():
    with pytest.raises(InvalidInputError, match="matplotlib Axes"):
        figure_and_axes("not an axes", (1.0, 1.0))
    fig, axs = plt.subplots(1, 2)
    with pytest.raises(ShapeError, match="need 3 axes, got 2"):
        figure_and_axes_grid(3, axs, ncols=3, size=(1.0, 1.0))
    assert figure_and_axes_grid(2, axs, ncols=3, size=(1.0, 1.0)) == (fig, list(axs))
    plt.close("all")


@settings(max_examples=15, deadline=None)
@given(st.integers(1, 7), st.integers(1, 4))
def test_new_grid_has_n_visible_panels(n, ncols):
    fig, axs = figure_and_axes_grid(n, None, ncols=ncols, size=(1.0, 1.0))
    assert len(axs) == n and all(a.figure is fig for a in axs)
    rows = -(-n // ncols)  # ceil
    assert len(fig.axes) == rows * ncols
    assert sum(a.get_visible() for a in fig.axes) == n
    plt.close(fig)
