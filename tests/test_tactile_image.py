"""Tactile image (Sec 3.1.1, Fig 3.2)."""

from __future__ import annotations

import numpy as np
import pytest

from whisker_io.errors import ConfigError, InvalidInputError
from whisker_io.array.geometry import WhiskerArray, WhiskerModule
from whisker_io.sim.objects import make_maze
from whisker_io.sim.sweep import sweep_array
from whisker_io.features.tactile_image import (
    TactileImageParams,
    pixel_layout,
    tactile_image,
    tactile_image_from_angles,
    tactile_image_from_contacts,
)


@pytest.fixture(scope="module")
def arr() -> WhiskerArray:
    return WhiskerArray.thesis()


def test_layout_is_three_rows_by_six_columns(arr):
    rows, cols, shape = pixel_layout(arr)
    assert shape == (3, 6)
    i = arr.index("C1")
    assert (rows[i], cols[i]) == (0, 2)
    i = arr.index("F3")
    assert (rows[i], cols[i]) == (2, 5)


def test_heights_scale_to_grey_levels(arr):
    """Range 0-0.3 m -> 1..255: h = 0.15 -> 1 + round(127) = 128; above/below clip; NaN -> 0."""
    pts = np.full((18, 3), np.nan)
    pts[arr.index("C1")] = [0.3, -2.0, 0.15]
    pts[arr.index("A3")] = [0.0, 0.0, 1.0]
    pts[arr.index("E2")] = [0.0, 0.0, -1.0]
    img = tactile_image(arr, pts)
    assert img.dtype == np.uint8 and img.shape == (3, 6)
    expected = np.zeros((3, 6), dtype=np.uint8)
    expected[0, 2] = 128
    expected[2, 0] = 255
    expected[1, 4] = 1
    np.testing.assert_array_equal(img, expected)
    # a custom range and vertical axis
    img = tactile_image(arr, pts, TactileImageParams(height_range_m=(-2.0, 0.0), up=(0, 1, 0)))
    assert img[0, 2] == 1  # y = -2 is the bottom of that range


def test_from_angles_by_hand(arr):
    """A1 at whisk angle 0 with the tip assumption: z = p_z + L * p_z / |(p_x, p_z)|;
    end effector 0.2 m up, so h = 0.2 - 0.023455 - 0.06 * 0.023455 / 0.054101."""
    pose = np.eye(4)
    pose[2, 3] = 0.2
    theta = np.full(18, np.nan)
    theta[arr.index("A1")] = 0.0
    img = tactile_image_from_angles(arr, pose, theta)
    norm = np.hypot(0.048752, 0.023455)
    h = 0.2 - 0.023455 - 0.06 * 0.023455 / norm
    assert img[0, 0] == 1 + round(254 * h / 0.3)
    assert np.count_nonzero(img) == 1


def test_from_contacts_in_maze(arr):
    """End to end in the Ch.3 maze: array axis horizontal (-y) at 77 mm, nose 2 cm from the
    20 cm wall along y = 0.25; the image has contacts exactly for the modules that touched,
    at their heights."""
    pose = np.eye(4)
    pose[:3, :3] = np.diag([-1.0, -1.0, 1.0])  # E's y -> world -y, E's z -> world z
    pose[:3, 3] = (0.78, 0.25 + 0.005 + 0.2019 + 0.02, 0.077)
    contacts = sweep_array(arr, make_maze(), pose)
    assert sum(c is not None for c in contacts) >= 3
    img = tactile_image_from_contacts(arr, contacts)
    rows, cols, _ = pixel_layout(arr)
    for i, c in enumerate(contacts):
        if c is None:
            assert img[rows[i], cols[i]] == 0
        else:
            assert img[rows[i], cols[i]] == 1 + round(254 * np.clip(c.point[2] / 0.3, 0, 1))


def test_bad_inputs(arr):
    with pytest.raises(InvalidInputError):
        tactile_image(arr, np.zeros((17, 3)))
    with pytest.raises(InvalidInputError):
        TactileImageParams(height_range_m=(1.0, 0.0))
    m = arr.modules
    clash = WhiskerArray((m[0], WhiskerModule("X", m[0].column, m[0].row, [0.05, 0.1, 0.0], 0.1)))
    with pytest.raises(ConfigError, match="share"):
        pixel_layout(clash)
