"""SPC (Alg 7-8) against hand-computed geometry."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from cansim.errors import CansimError, ConfigError
from cansim.explore.placement import (
    DEFAULT_CONE_HALF_ANGLE_RAD,
    PlacementParams,
    maintain_yaw,
    place,
    ring_half_angle_rad,
)
from whisker_io.pose import Pose

P = PlacementParams(mu=3, delta_theta_rad=math.radians(10), delta_l_m=0.21, delta_u_m=0.26, rotation_steps=2, translation_steps=2)
# the frame facing +x with z up: columns x = y cross z = (0,-1,0), y = (1,0,0), z = (0,0,1)
FACING_X = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _pose(p=(0.0, 0.0, 0.3)):
    return Pose.from_rotation(p, Rotation.from_matrix(FACING_X))


def _wall(distance_m, n=5, spread=0.02):
    """Contacts in the end-effector frame on a wall perpendicular to y at distance_m."""
    xs = np.linspace(-spread, spread, n)
    return np.stack([xs, np.full(n, distance_m), xs[::-1] * 0.5], axis=1)


def test_maintain_yaw_hand_frames():
    np.testing.assert_allclose(maintain_yaw([2.0, 0, 0]).as_matrix(), FACING_X, atol=1e-12)
    # y tilted down by 30 deg toward +x: z = up made perpendicular to y
    y = np.array([math.cos(math.radians(30)), 0.0, -math.sin(math.radians(30))])
    R = maintain_yaw(y).as_matrix()
    np.testing.assert_allclose(R[:, 1], y, atol=1e-12)
    np.testing.assert_allclose(R[:, 2], [math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))], atol=1e-12)
    np.testing.assert_allclose(R[:, 0], np.cross(R[:, 1], R[:, 2]), atol=1e-12)


def test_y_parallel_to_gravity_keeps_previous_z():
    R = maintain_yaw([0, 0, -1], previous_z=[0.0, 1.0, 0.0]).as_matrix()
    np.testing.assert_allclose(R[:, 2], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(R[:, 1], [0, 0, -1], atol=1e-12)
    # through place(): array looking down at a floor, current z = +y world stays
    start = Pose.from_rotation([0, 0, 0.5], Rotation.from_matrix(np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])))
    goal = place(start, _wall(0.40), P)  # too far: translation only
    np.testing.assert_allclose(goal.rotation.as_matrix()[:, 2], [0, 1, 0], atol=1e-9)


def test_flat_wall_in_cone_and_band_keeps_pose():
    pose = _pose()
    goal = place(pose, _wall(0.235), P)
    assert goal == pose


def test_fewer_than_mu_contacts_keeps_goal():
    pose = _pose()
    goal = place(pose, _wall(0.40, n=2), P)
    assert goal == pose
    assert place(pose, np.zeros((0, 3)), P) == pose


def test_flat_wall_too_far_translates_along_y():
    pose = _pose()
    goal = place(pose, _wall(0.335), P)
    # (0.335 - 0.235) / 2 = 0.05 m along y = +x world
    np.testing.assert_allclose(goal.position_m, [0.05, 0.0, 0.3], atol=1e-12)
    np.testing.assert_allclose(goal.rotation.as_matrix(), FACING_X, atol=1e-12)


def test_flat_wall_too_near_backs_off():
    goal = place(_pose(), _wall(0.135), P)
    np.testing.assert_allclose(goal.position_m, [-0.05, 0.0, 0.3], atol=1e-12)


def test_tilted_wall_rotates_toward_median_by_half_the_angle():
    # median contact 40 deg off the y-axis toward world +y (the frame's -x): outside the cone
    a = math.radians(40)
    c = np.array([[-0.25 * math.sin(a) + dx, 0.25 * math.cos(a) - dx * math.tan(a), 0.0] for dx in (-0.01, 0.0, 0.01)])
    goal = place(_pose(), c, P)
    y = goal.rotation.as_matrix()[:, 1]
    # hand value: y turned by 20 deg (40 / 2 steps)... capped at delta_theta = 10 deg
    np.testing.assert_allclose(y, [math.cos(math.radians(10)), math.sin(math.radians(10)), 0.0], atol=1e-9)
    np.testing.assert_allclose(goal.position_m, [0, 0, 0.3], atol=1e-12)
    uncapped = place(_pose(), c, PlacementParams(max_rotation_step_rad=math.pi / 2))
    np.testing.assert_allclose(uncapped.rotation.as_matrix()[:, 1], [math.cos(math.radians(20)), math.sin(math.radians(20)), 0.0], atol=1e-9)


def test_goal_z_in_plane_of_gravity_and_y():
    rng = np.random.default_rng(3)
    for _ in range(20):
        c = _wall(0.3) + rng.normal(0, 0.08, (5, 3))
        goal = place(_pose(), c, P)
        R = goal.rotation.as_matrix()
        # z lies in span(g, y): its component along x = y cross z, i.e. normal to that plane, is 0
        normal = np.cross([0, 0, 1.0], R[:, 1])
        if np.linalg.norm(normal) > 1e-6:
            assert abs(R[:, 2] @ normal / np.linalg.norm(normal)) < 1e-9
        assert R[:, 2] @ [0, 0, 1.0] >= -1e-12


def test_roll_is_reapplied():
    roll = PlacementParams(roll_rad=math.pi / 2)
    start = Pose.from_rotation([0, 0, 0.3], Rotation.from_matrix(FACING_X) * Rotation.from_rotvec([0, math.pi / 2, 0]))
    goal = place(start, _wall(0.335), roll)
    np.testing.assert_allclose(goal.rotation.as_matrix(), start.rotation.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(goal.rotation.as_matrix()[:, 0], [0, 0, -1], atol=1e-9)  # x down


@pytest.mark.parametrize("kw", [dict(mu=0), dict(delta_theta_rad=0.0), dict(delta_l_m=0.3, delta_u_m=0.2),
                                dict(rotation_steps=1.5), dict(up=(0, 0, 0)), dict(delta_l_m=float("nan"))])
def test_bad_params(kw):
    with pytest.raises(ConfigError):
        PlacementParams(**kw)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=3, max_size=3), min_size=0, max_size=8))
def test_place_any_contacts_typed_error_or_finite_pose(rows):
    c = np.array(rows, dtype=float).reshape(-1, 3)
    try:
        goal = place(_pose(), c, P)
    except CansimError:
        return
    assert np.isfinite(goal.position_m).all()
    assert np.linalg.norm(goal.position_m - [0, 0, 0.3]) <= 5.0  # at most half of a 10-m contact
    R = goal.rotation.as_matrix()
    assert R[:, 2] @ [0, 0, 1.0] >= -1e-9


@settings(max_examples=30, deadline=None)
@given(st.one_of(st.integers(), st.text(), st.lists(st.floats(), max_size=4)))
def test_place_bad_shapes(c):
    with pytest.raises(CansimError):
        place(_pose(), c, P)


# ---------------------------------------------------------------- reference point (decision)
REF = PlacementParams(delta_theta_rad=math.radians(10), delta_l_m=0.028, delta_u_m=0.078,
                      rotation_steps=2, translation_steps=2, reference_point_m=(0.0, 0.18, 0.0))


def test_reference_point_flat_wall_in_band_keeps_pose():
    # wall 0.23 m along y from the flange = 0.05 m from the reference: in [0.028, 0.078]
    pose = _pose()
    assert place(pose, _wall(0.23), REF) == pose


def test_reference_point_flat_wall_too_far_translates_from_reference():
    # 0.30 m from the flange = 0.12 m from the reference; band middle 0.053 -> (0.12 - 0.053) / 2
    pose = _pose()
    goal = place(pose, _wall(0.30), REF)
    np.testing.assert_allclose(goal.position_m, [0.0335, 0.0, 0.3], atol=1e-9)
    np.testing.assert_allclose(goal.rotation.as_matrix(), FACING_X, atol=1e-9)


def test_reference_point_tilted_wall_turns_where_the_origin_would_not():
    # median contact (0.02, 0.23, 0) in E: 4.97 deg off y from the flange (inside 10 deg),
    # atan(0.02 / 0.05) = 21.8 deg from the reference -> turn min(21.8 / 2, 10) = 10 deg toward +x_E
    c = np.array([[0.02, 0.23, 0.0], [0.01, 0.22, 0.0], [0.03, 0.24, 0.0]])
    pose = _pose()
    assert place(pose, c, P) == pose  # from the flange: in the cone, e_dy = 0.23 in [0.21, 0.26]
    goal = place(pose, c, REF)
    y_e = np.array([math.sin(math.radians(10)), math.cos(math.radians(10)), 0.0])
    np.testing.assert_allclose(goal.rotation.as_matrix()[:, 1], FACING_X @ y_e, atol=1e-9)
    np.testing.assert_allclose(goal.position_m, pose.position_m, atol=1e-12)  # turned about the flange


@settings(max_examples=40, deadline=None)
@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=2)), min_size=0, max_size=4))
@example([0.0, 0.0, "0"])  # np.asarray(dtype=float) parsed the text "0" as a number (--hypothesis-seed=109, 4x examples)
@example([0.0, 0.0, 10**400])  # an int too large for a float
def test_bad_reference_point_is_a_config_error(values):
    ok = len(values) == 3 and all(isinstance(v, float) and math.isfinite(v) and abs(v) <= 10 for v in values)
    if ok:
        assert PlacementParams(reference_point_m=tuple(values)).reference_point_m == tuple(values)
    else:
        with pytest.raises(ConfigError):
            PlacementParams(reference_point_m=tuple(values))
    # the up direction: any 3 finite numbers, not all zero
    up_ok = len(values) == 3 and all(isinstance(v, float) and math.isfinite(v) for v in values) and any(values)
    if not up_ok:
        with pytest.raises(ConfigError):
            PlacementParams(up=tuple(values))


# ------------------------------------------------------- cone calibrated on the array (decision)
def _wall_mesh(distance_m):
    """A 3 x 3 m wall whose face is the plane y = distance_m (world = end-effector frame at the identity)."""
    import trimesh

    wall = trimesh.creation.box(extents=(3.0, 0.2, 3.0))
    wall.apply_translation((0.0, distance_m + 0.1, 0.0))
    return wall


@pytest.mark.parametrize("distance_m", [0.205, 0.235])
def test_ring_half_angle_matches_the_simulated_sweep(distance_m):
    # reference: the ray-cast sweep of the whisk chain (an independent code path) against a wall
    from whisker_io.array.geometry import WhiskerArray
    from whisker_io.sim.whisk_chain import WhiskChain

    arr = WhiskerArray.thesis()
    whisk = WhiskChain(_wall_mesh(distance_m), contact_model="truth", contact_noise=None).whisk(
        Pose.identity(), np.random.default_rng(0))
    touched = [i for i, c in enumerate(whisk.sweep_contacts) if c is not None]
    pts = whisk.features.contact_points_m
    short = [k for k, i in enumerate(touched) if arr.lengths_m[i] == arr.lengths_m.min()]
    assert len(short) == 6
    sim = np.median(np.arctan2(np.hypot(pts[short, 0], pts[short, 2]), pts[short, 1]))
    assert ring_half_angle_rad(arr, distance_m) == pytest.approx(sim, abs=math.radians(0.1))
    # nothing lies inside the ring: every contact is at least the ring's angle off y
    every = np.arctan2(np.hypot(pts[:, 0], pts[:, 2]), pts[:, 1])
    assert every.min() >= ring_half_angle_rad(arr, distance_m) - math.radians(0.1)


def test_default_cone_is_the_innermost_ring_at_the_band_middle():
    mid = 0.5 * (PlacementParams().delta_l_m + PlacementParams().delta_u_m)
    assert abs(PlacementParams().delta_theta_rad - ring_half_angle_rad(None, mid)) <= math.radians(0.5)
    assert PlacementParams().delta_theta_rad == DEFAULT_CONE_HALF_ANGLE_RAD


def test_squarely_faced_flat_wall_settles_at_once_with_the_default_cone():
    # the full contact rings: median 9.9 deg off y at 0.235 m (inside 24 deg), e_dy in the band
    from whisker_io.sim.whisk_chain import WhiskChain

    chain = WhiskChain(_wall_mesh(0.235), contact_model="truth", contact_noise=None)
    pose = Pose.identity()
    c = chain.features(pose, np.random.default_rng(0)).contact_points_m
    assert len(c) == 18
    assert place(pose, c, PlacementParams()) == pose


def test_spc_settles_within_a_few_steps_on_the_box():
    # every pose of one loop of trajectory A around the Box, perturbed as noisy odometry would
    # (2 cm, 8 deg), with the Sec 6.1.3.1.2 contact noise: the goal equals the pose within 5 steps
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.sweep import ContactNoise
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    mesh = make_object("box")
    chain = WhiskChain(mesh, contact_model="tip", contact_noise=ContactNoise())
    params = PlacementParams(roll_rad=math.pi / 2)
    rng = np.random.default_rng(5)
    steps = []
    for p in object_trajectory(mesh, "A", 1):
        q = Pose.from_rotation(p.position_m + rng.normal(0, 0.02 / math.sqrt(3), 3),
                               Rotation.from_rotvec(rng.normal(0, math.radians(8) / math.sqrt(3), 3)) * p.rotation)
        k = 0
        while k < 10:
            goal = place(q, chain.features(q, rng).contact_points_m, params)
            if goal == q:
                break
            q, k = goal, k + 1
        steps.append(k)
    steps = np.array(steps)
    assert np.median(steps) <= 1
    assert np.mean(steps <= 5) >= 0.85, np.bincount(steps)


@settings(max_examples=30, deadline=None)
@given(d=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([True, "0.2", None, 0.0, -0.1, 0.4, 11.0])),
       step=st.sampled_from([math.radians(0.5), 0.0, -1.0, 1.0, math.nan]))
def test_ring_half_angle_bad_input_is_a_typed_error(d, step):
    ok = (isinstance(d, float) and math.isfinite(d) and 0.19 <= d <= 0.24 and 0 < step <= math.radians(1))
    if ok:
        assert 0 < ring_half_angle_rad(None, d, step) < math.pi / 2
    elif isinstance(d, float) and math.isfinite(d) and 0.0 < d <= 10 and 0 < step <= math.radians(1):
        try:  # in range but maybe beyond the shortest whiskers' reach: a value or a typed error
            assert 0 < ring_half_angle_rad(None, d, step) < math.pi / 2
        except CansimError:
            pass
    else:
        with pytest.raises(CansimError):
            ring_half_angle_rad(None, d, step)
    with pytest.raises(CansimError):
        ring_half_angle_rad("thesis", 0.235)
