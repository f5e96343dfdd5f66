"""Array geometry (Fig 2.15, Fig 2.15) and forward kinematics (Eq 5.1-5.2)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from whisker_io.errors import ConfigError, InvalidInputError, CansimError
from whisker_io.array.geometry import WhiskerArray, WhiskerModule
from whisker_io.array.kinematics import (
    contact_points,
    shaft_directions,
    whisker_coordinates,
    whisker_frames,
)


@pytest.fixture(scope="module")
def arr() -> WhiskerArray:
    return WhiskerArray.thesis()


def test_thesis_array_table(arr):
    assert len(arr) == 18
    assert set(arr.names) == {c + str(r) for c in "ABCDEF" for r in (1, 2, 3)}
    # positions converted from the mm table of Fig 2.15
    np.testing.assert_allclose(arr.modules[arr.index("A1")].base_position_m, [0.048752, 0.201860, -0.023455])
    np.testing.assert_allclose(arr.modules[arr.index("F3")].base_position_m, [-0.059144, 0.161946, -0.052095])
    for m in arr.modules:
        assert m.length_m == {1: 0.060, 2: 0.100, 3: 0.160}[m.row]
        assert m.column == m.name[0] and m.row == int(m.name[1])
    assert np.isclose(np.rad2deg(arr.retraction_rad), -50) and np.isclose(np.rad2deg(arr.protraction_rad), 50)


def test_base_frames_follow_spec(arr):
    Y = np.array([0.0, 1.0, 0.0])
    for m in arr.modules:
        R = m.base_rotation
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(R), 1.0)
        x, y, z = R.T
        radial = m.base_position_m * [1, 0, 1]
        np.testing.assert_allclose(y, radial / np.linalg.norm(radial), atol=1e-12)  # radially outward
        np.testing.assert_allclose(x, -Y, atol=1e-12)  # x = -array axis
        assert abs(z @ Y) < 1e-12 and abs(z @ radial) < 1e-12  # tangent to the ring


def test_protraction_points_rostral(arr):
    d = shaft_directions(arr, np.eye(4), np.deg2rad(50.0))
    np.testing.assert_allclose(d[:, 1], np.sin(np.deg2rad(50.0)), atol=1e-12)
    d = shaft_directions(arr, np.eye(4), np.deg2rad(-50.0))
    np.testing.assert_allclose(d[:, 1], -np.sin(np.deg2rad(50.0)), atol=1e-12)


def test_duplicate_modules_raise_typed_error(arr):
    mods = arr.modules + (arr.modules[4],)
    with pytest.raises(ConfigError, match="duplicate module name 'B2'"):
        WhiskerArray(mods)
    # catchable as the package base and as ValueError
    with pytest.raises(CansimError):
        WhiskerArray(mods)
    with pytest.raises(ValueError):
        WhiskerArray(mods)


@pytest.mark.parametrize(
    "kwargs, msg",
    [
        ({"length_m": 0.0}, "length_m"),
        ({"length_m": float("nan")}, "length_m"),
        ({"base_position_m": [0.0, 0.1]}, "base_position_m"),
        ({"base_rotation": np.diag([1.0, 1.0, -1.0])}, "proper rotation"),
        ({"base_position_m": [0.0, 0.2, 0.0]}, "array axis"),
        # were OverflowError / ValueError (CI-style fuzzing): an int too large for a float, text, inf
        ({"length_m": 10**400}, "length_m"),
        ({"length_m": "0.1"}, "length_m"),
        ({"row": math.inf}, "row"),
        ({"row": "1"}, "row"),
        ({"base_position_m": ["a", 0.2, 0.0]}, "base_position_m"),
        ({"base_rotation": [["a"] * 3] * 3}, "base_rotation"),
    ],
)
def test_bad_module_definitions(kwargs, msg):
    args = dict(name="X", column="A", row=1, base_position_m=[0.05, 0.2, 0.0], length_m=0.1)
    args.update(kwargs)
    with pytest.raises(ConfigError, match=msg):
        WhiskerModule(**args)


def test_empty_array_and_bad_range(arr):
    with pytest.raises(ConfigError):
        WhiskerArray(())
    with pytest.raises(ConfigError, match="whisk range"):
        WhiskerArray(arr.modules, retraction_rad=0.5, protraction_rad=0.2)


def test_with_lengths_replaces_only_named(arr):
    new = arr.with_lengths({"C3": 0.150})
    assert new.lengths_m[new.index("C3")] == 0.150
    changed = np.flatnonzero(new.lengths_m != arr.lengths_m)
    assert changed.tolist() == [arr.index("C3")]
    assert arr.lengths_m[arr.index("C3")] == 0.160  # original untouched
    with pytest.raises(ConfigError, match="unknown module"):
        arr.with_lengths({"Z9": 0.1})


def test_scipy_rotation_accepted():
    R = Rotation.from_euler("z", 30, degrees=True)
    m = WhiskerModule("X", "A", 1, [0.05, 0.2, 0.0], 0.1, R)
    np.testing.assert_allclose(m.base_rotation, R.as_matrix())


def test_forward_kinematics_hand_example():
    """Module at (50, 200, 0) mm: base frame x = -Y, y = +X, z = +Z.

    Whisk angle 30 deg, r = 0.1 m: in E the point is
    p + r (cos30 X + sin30 Y) = (0.05 + 0.0866025, 0.25, 0).
    End effector at (1, 2, 3) rotated 90 deg about z: (x, y) -> (-y, x), so the
    world point is (1 - 0.25, 2 + 0.1366025, 3).
    """
    one = WhiskerArray((WhiskerModule("X", "A", 1, [0.05, 0.2, 0.0], 0.12),))
    np.testing.assert_allclose(one.rotations[0], [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], atol=1e-15)
    expected = np.array([[0.75, 2.0 + 0.05 + 0.1 * np.cos(np.pi / 6), 3.0]])
    q = [0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]  # scalar last
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T[:3, 3] = [1, 2, 3]
    theta = np.deg2rad([30.0])
    for pose in (T, ((1.0, 2.0, 3.0), q)):
        np.testing.assert_allclose(contact_points(one, pose, theta, [0.1]), expected, atol=1e-12)
    # frame y-axis equals the shaft direction; tip assumption uses the length
    F = whisker_frames(one, T, theta)
    np.testing.assert_allclose(F[0, :3, 3], [1 - 0.2, 2 + 0.05, 3], atol=1e-12)
    tip = contact_points(one, T, theta)
    np.testing.assert_allclose(tip, F[:, :3, 3] + 0.12 * F[:, :3, 1], atol=1e-12)


def test_whisker_coordinates_inverts_fk(arr):
    rng = np.random.default_rng(3)
    pose = (rng.normal(size=3), Rotation.random(random_state=4).as_quat())
    theta = rng.uniform(arr.retraction_rad, arr.protraction_rad, len(arr))
    r = rng.uniform(0.0, 1.0, len(arr)) * arr.lengths_m
    pts = contact_points(arr, pose, theta, r)
    th, rr, z = whisker_coordinates(arr, pose, pts)
    np.testing.assert_allclose(th, theta, atol=1e-12)
    np.testing.assert_allclose(rr, r, atol=1e-12)
    np.testing.assert_allclose(z, 0.0, atol=1e-12)


def test_bad_pose_and_angles(arr):
    T = np.eye(4)
    T[0, 3] = np.nan
    with pytest.raises(InvalidInputError):
        contact_points(arr, T, 0.0)
    with pytest.raises(InvalidInputError, match="rigid"):
        contact_points(arr, np.diag([2.0, 1.0, 1.0, 1.0]), 0.0)
    with pytest.raises(InvalidInputError, match="reflection"):
        contact_points(arr, np.diag([1.0, 1.0, -1.0, 1.0]), 0.0)
    with pytest.raises(InvalidInputError, match="theta"):
        contact_points(arr, np.eye(4), np.zeros(5))
    with pytest.raises(InvalidInputError, match="quaternion"):
        contact_points(arr, ((0, 0, 0), (0, 0, 1)), 0.0)


def test_whisk_angles_grid(arr):
    a = np.rad2deg(arr.whisk_angles())
    assert a.size == 101 and np.isclose(a[0], -50) and np.isclose(a[-1], 50)
    np.testing.assert_allclose(np.diff(a), 1.0, atol=1e-9)
