"""Figures of whisker_io.plots.scene: they draw what they are given."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

from whisker_io.array.geometry import WhiskerArray  # noqa: E402
from whisker_io.sim.objects import make_object  # noqa: E402
from whisker_io.features.pfh import point_feature_histogram  # noqa: E402
from whisker_io.plots.scene import draw_pfh, plot_pfh, plot_scene, plot_tactile_image  # noqa: E402
from whisker_io.sim.sweep import sweep_array  # noqa: E402


def test_scene_shows_every_contact(tmp_path):
    import matplotlib.pyplot as plt

    arr = WhiskerArray.thesis()
    mesh = make_object("box")
    pose = np.eye(4)
    pose[1, 3] = -0.1 - 0.2019 - 0.01  # nose 1 cm in front of the box's -y face
    pose[2, 3] = 0.175
    contacts = sweep_array(arr, mesh, pose)
    n = sum(c is not None for c in contacts)
    assert n > 0
    fig = plot_scene(mesh, arr, pose, contacts)
    ax = fig.axes[0]
    red = [c for c in ax.collections if getattr(c, "get_label", lambda: "")() == "contacts"]
    assert len(red) == 1 and len(red[0]._offsets3d[0]) == n
    assert len(ax.lines) == 18  # one shaft per whisker
    fig.savefig(tmp_path / "scene.png")
    plt.close(fig)


def test_pfh_figure_bars_match_histogram():
    import matplotlib.pyplot as plt

    h = point_feature_histogram(np.random.default_rng(0).uniform(-0.1, 0.1, (18, 3)) + [0, 0.3, 0]).histogram
    fig = plot_pfh(h)
    heights = [p.get_height() for p in fig.axes[0].patches]
    np.testing.assert_allclose(heights, h)
    fig2, (a, b) = plt.subplots(1, 2)
    assert draw_pfh(a, h) is a  # reusable in a composite figure
    plt.close(fig)
    plt.close(fig2)


def test_tactile_image_figure():
    import matplotlib.pyplot as plt

    img = np.arange(18, dtype=np.uint8).reshape(3, 6) * 10
    fig = plot_tactile_image(img)
    np.testing.assert_array_equal(fig.axes[0].images[0].get_array(), img)
    plt.close(fig)
