"""The one pose type (whisker_io.pose): hand-computed conversions, the quaternion
rule, the determinant check, and property-based round trips and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from whisker_io.errors import CansimError, InvalidInputError, ShapeError
from whisker_io.pose import QUAT_NORM_TOL, Pose, as_pose

S2 = math.sqrt(0.5)

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
positions = st.lists(finite, min_size=3, max_size=3)
# unit quaternions from a non-degenerate 4-vector (normalised by the test, not by Pose)
raw_quats = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.1)


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


# ------------------------------------------------------------- hand-computed
def test_pose_from_ur_hand_computed():
    p = Pose.from_ur([0.1, 0.2, 0.3, 0.0, 0.0, math.pi / 2])
    assert np.allclose(p.quaternion_xyzw, [0.0, 0.0, S2, S2])  # scalar last
    T = p.matrix
    assert np.allclose(T[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    assert np.allclose(T[:3, 3], [0.1, 0.2, 0.3])
    assert np.allclose(p.as_ur(), [0.1, 0.2, 0.3, 0.0, 0.0, math.pi / 2])


def test_pose_tool_down_axis_and_round_trips():
    down = Pose.from_ur([0.4, 0.0, 0.4, 0.0, math.pi, 0.0])  # 180 deg about y
    assert np.allclose(down.tool_axis(), [0, 0, -1])
    assert as_pose(down.matrix).distance_to(down) == pytest.approx((0.0, 0.0), abs=1e-12)
    ident = down @ down.inverse()
    assert np.allclose(ident.position_m, 0, atol=1e-15)
    assert np.allclose(ident.quaternion_xyzw, [0, 0, 0, 1])


def test_compose_hand_computed():
    # A: translate 1 m along x, rotate 90 deg about z; B: translate 1 m along x.
    a = Pose([1.0, 0.0, 0.0], [0.0, 0.0, S2, S2])
    b = Pose([1.0, 0.0, 0.0])
    ab = a @ b  # B's x-axis is A's y-axis: the origin of B lands at (1, 1, 0)
    assert np.allclose(ab.position_m, [1.0, 1.0, 0.0])
    assert np.allclose(ab.quaternion_xyzw, [0.0, 0.0, S2, S2])
    assert np.allclose(a.apply([[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]]), [[1.0, 1.0, 0.0], [1.0, 0.0, 2.0]])


def test_from_rotvec_and_identity():
    p = Pose.from_rotvec([0, 0, 1], [math.pi / 2, 0, 0])  # 90 deg about x: y -> z
    assert np.allclose(p.rotation.apply([0, 1, 0]), [0, 0, 1])
    assert np.allclose(p.rotvec_rad, [math.pi / 2, 0, 0])
    assert Pose.identity() == Pose([0, 0, 0], [0, 0, 0, 1])


def test_canonical_sign_and_normalisation_within_tolerance():
    p = Pose([0, 0, 0], [0.0, 0.0, 0.0, -1.0 - 0.5 * QUAT_NORM_TOL])
    assert np.array_equal(p.quaternion_xyzw, [0.0, 0.0, 0.0, 1.0])
    assert p == Pose([0, 0, 0], [0, 0, 0, 1])
    # w = 0: the first non-zero vector component is made positive
    assert np.array_equal(Pose([0, 0, 0], [0, -1, 0, 0]).quaternion_xyzw, [0, 1, 0, 0])


def test_logged_unit_quaternion_is_kept_bit_for_bit():
    q = np.array([0.1, -0.2, 0.3, 0.9])
    q = q / np.linalg.norm(q)
    assert np.array_equal(Pose([0, 0, 0], q).quaternion_xyzw, q)


@pytest.mark.parametrize("q", [
    [0, 0, 0, 0],                     # zero
    [0, 0, 0, 2.0],                   # far from unit norm
    [0, 0, 0, 1.0 + 2 * QUAT_NORM_TOL],
    [1e300, 1e300, 0, 0],             # the norm overflows: issue 17 stored a zero quaternion
    [1e200, 0, 0, 0],
    [0, 0, math.nan, 1],
    [0, 0, math.inf, 1],
])
def test_quaternion_rule_rejects(q):
    with pytest.raises(InvalidInputError, match="quaternion"):
        Pose([0, 0, 0], q)


@pytest.mark.parametrize("bad", [
    [0, 0, 0], np.eye(3), [0, 0, 0, 0, 0, math.nan],
    np.diag([1.0, 1.0, -1.0, 1.0]),    # reflection
    np.diag([2.0, 1.0, 1.0, 1.0]),     # not orthonormal
    "pose", None, ((0, 0, 0),),
])
def test_as_pose_rejects_bad_input(bad):
    with pytest.raises(InvalidInputError):
        as_pose(bad)


def test_from_matrix_names_the_fault():
    with pytest.raises(InvalidInputError, match="reflection"):
        Pose.from_matrix(np.diag([1.0, -1.0, 1.0, 1.0]))
    with pytest.raises(InvalidInputError, match="orthonormal"):
        Pose.from_matrix(np.diag([1.0, 1.0, 1.001, 1.0]))
    T = np.eye(4)
    T[3, 0] = 1.0
    with pytest.raises(InvalidInputError, match="last row"):
        Pose.from_matrix(T)
    with pytest.raises(ShapeError):
        Pose.from_matrix(np.eye(3))


def test_pose_is_immutable():
    p = Pose([1, 2, 3])
    with pytest.raises(ValueError):
        p.position_m[0] = 5.0
    with pytest.raises(AttributeError):
        p.position_m = np.zeros(3)
    T = p.matrix
    T[0, 3] = 99.0  # a caller's copy: the pose keeps its own
    assert p.matrix[0, 3] == 1.0


# ------------------------------------------------------------- properties
@settings(max_examples=60, deadline=None)
@given(positions, raw_quats)
def test_matrix_round_trip(p, q):
    pose = Pose(p, _unit(q))
    back = Pose.from_matrix(pose.matrix)
    assert np.allclose(back.position_m, pose.position_m, atol=1e-12)
    assert np.allclose(back.matrix, pose.matrix, atol=1e-9)
    # the same rotation; the quaternion up to the sign ambiguity at w = 0
    dq = min(np.abs(back.quaternion_xyzw - pose.quaternion_xyzw).max(),
             np.abs(back.quaternion_xyzw + pose.quaternion_xyzw).max())
    assert dq < 1e-9
    T = pose.matrix  # a proper rotation: orthonormal, det +1
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    assert pose.quaternion_xyzw[3] >= 0 and np.linalg.norm(pose.quaternion_xyzw) == pytest.approx(1.0)


@settings(max_examples=60, deadline=None)
@given(positions, raw_quats, positions, raw_quats, positions)
def test_compose_matches_matrix_product_and_inverse(p1, q1, p2, q2, x):
    a, b = Pose(p1, _unit(q1)), Pose(p2, _unit(q2))
    assert np.allclose((a @ b).matrix, a.matrix @ b.matrix, atol=1e-9)
    assert np.allclose((a @ a.inverse()).matrix, np.eye(4), atol=1e-9)
    xh = np.append(x, 1.0)
    assert np.allclose(a.apply(x), (a.matrix @ xh)[:3], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(positions, raw_quats)
def test_pose_like_forms_agree(p, q):
    pose = Pose(p, _unit(q))
    assert as_pose(pose) is pose
    assert as_pose((p, _unit(q))) == pose
    assert np.allclose(as_pose(pose.as_ur()).matrix, pose.matrix, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, st.sampled_from([(3,), (4,), (2,), (5,)]),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
       arrays(np.float64, st.sampled_from([(3,), (4,), (2,)]),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)))
def test_bad_input_is_typed_or_a_valid_pose(p, q):
    try:
        pose = Pose(p, q)
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    # accepted only under the documented rule
    assert p.shape == (3,) and q.shape == (4,) and np.all(np.isfinite(p)) and np.all(np.isfinite(q))
    assert abs(np.linalg.norm(q) - 1.0) <= QUAT_NORM_TOL
    assert np.linalg.norm(pose.quaternion_xyzw) == pytest.approx(1.0)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, (4, 4), elements=st.floats(-2, 2, width=64)))
def test_random_matrix_is_refused_or_proper(T):
    try:
        pose = Pose.from_matrix(T)
    except InvalidInputError:
        return
    R = T[:3, :3]
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0
    assert np.allclose(pose.matrix[:3, 3], T[:3, 3])
