"""Figures of the radial study draw what they are given and return the Figure."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from whisker_io.radial.evaluation import PCAResult  # noqa: E402
from whisker_io.radial.plots import plot_boxplots, plot_histograms, plot_pca_loadings  # noqa: E402


def test_pca_loadings_bars_have_the_coefficients() -> None:
    comps = np.eye(3, 7)
    fig = plot_pca_loadings(PCAResult(("CP", "CA", "DV", "DA", "AV", "AA", "WL"), comps, np.array([0.5, 0.3, 0.2])))
    axes = fig.axes
    assert len(axes) == 3
    heights = [p.get_height() for p in axes[1].patches]
    np.testing.assert_allclose(heights, comps[1])
    assert "30%" in axes[1].get_title()
    plt.close(fig)


def test_histograms_and_boxplots_into_given_axes() -> None:
    fig, axs = plt.subplots(1, 2)
    out = plot_histograms({"a": np.zeros(10), "b": np.ones(10)}, "err", axes=axs, value_range=(-1, 2))
    assert out is fig
    assert "median 1" in axs[1].get_title()
    fig2, ax = plt.subplots()
    assert plot_boxplots({"x": np.arange(10.0), "y": np.arange(5.0)}, "e", ax=ax, ymax=30) is fig2
    assert [t.get_text() for t in ax.get_xticklabels()] == ["x", "y"]
    assert ax.get_ylim() == (0.0, 30.0)
    plt.close("all")


def test_histogram_outliers_are_counted_not_clipped_into_the_edge_bins() -> None:
    v = np.concatenate([np.linspace(0.0, 1.0, 20), [-5.0, -7.0, 9.0]])  # 2 below, 1 above (0, 1)
    fig = plot_histograms({"m": v}, "error (fraction of WL)", value_range=(0.0, 1.0), bins=10)
    ax = fig.axes[0]
    heights = [p.get_height() for p in ax.patches]
    assert sum(heights) == 20  # only the 20 values inside the axis are drawn
    assert heights[0] == 2 and heights[-1] == 2  # 0.0, 0.05 and 0.95, 1.0: no outliers added at the edges
    texts = " ".join(t.get_text() for t in ax.texts)
    assert "2 below, 1 above" in texts and "of 23" in texts
    assert ax.get_xlim() == (0.0, 1.0)
    plt.close(fig)


def test_histogram_without_outliers_has_no_note() -> None:
    fig = plot_histograms({"m": np.linspace(0.0, 1.0, 11)}, "e", value_range=(0.0, 1.0))
    assert not fig.axes[0].texts
    plt.close(fig)


def test_the_histogram_titles_carry_the_unit_given() -> None:
    fig = plot_histograms({"m": np.array([1.0, 2.0, 3.0])}, "point-to-mesh distance (mm)", unit="mm")
    assert fig.axes[0].get_title() == "m\nmedian 2 mm, std 0.816 mm"  # std of 1, 2, 3: sqrt(2/3)
    plt.close(fig)


def test_a_box_reaching_above_ymax_is_named_with_its_median_and_quartile() -> None:
    inside, tall = np.linspace(0.0, 10.0, 11), np.linspace(0.0, 100.0, 11)  # quartiles 2.5/7.5 and 25/75
    fig = plot_boxplots({"low": inside, "high": tall}, "e", ymax=60)
    ax = fig.axes[0]
    texts = " ".join(t.get_text() for t in ax.texts)
    assert "high: median 50, upper quartile 75" in texts and "low" not in texts
    assert [tuple(line.get_xydata()[0]) for line in ax.lines if line.get_marker() == "^"] == [(2.0, 60.0)]
    plt.close(fig)
    fig = plot_boxplots({"low": inside}, "e", ymax=60)  # nothing above: no note, no mark
    assert not fig.axes[0].texts and not [line for line in fig.axes[0].lines if line.get_marker() == "^"]
    plt.close(fig)
