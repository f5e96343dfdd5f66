"""Arm odometry between whisks (whisker_io.sim.odometry_noise): exact steps, the noise model of
Sec 6.1.3.1.1 (Eq 6.4-6.11), its guards, and the frame contract with the SE(3) object map."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from maps.odometry import SpatialOdometry
from maps.se3 import SE3Geometry
from whisker_io.errors import CansimError, InvalidInputError, ShapeError
from whisker_io.pose import Pose
from whisker_io.sim.odometry_noise import (
    OdometryNoise,
    exact_odometry,
    integrate_odometry,
    noisy_odometry,
    relative_motion,
)

S2 = math.sqrt(0.5)
finite = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
positions = st.lists(finite, min_size=3, max_size=3)
raw_quats = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.1)


def _pose(p, q) -> Pose:
    q = np.asarray(q, dtype=float)
    return Pose(p, q / np.linalg.norm(q))


def _close(a: Pose, b: Pose, atol: float = 1e-12) -> bool:
    dt, dr = a.distance_to(b)
    return dt <= atol and dr <= 1e-9


# ------------------------------------------------------------- hand-computed
def test_exact_odometry_hand_computed_body_frame():
    """Previous pose turned +90 deg about z: its body x-axis is the world y-axis. A step of
    +0.2 m along world y and a further +90 deg about z over dt = 2 s is v = (0.1, 0, 0) m/s
    and omega = (0, 0, pi/4) rad/s in the body frame."""
    prev = Pose([1.0, 2.0, 3.0], [0.0, 0.0, S2, S2])
    nxt = Pose([1.0, 2.2, 3.0], [0.0, 0.0, 1.0, 0.0])
    v, omega, dt = exact_odometry(prev, nxt, dt=2.0)
    np.testing.assert_allclose(v, [0.1, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(omega, [0.0, 0.0, math.pi / 4], atol=1e-15)
    assert dt == 2.0


def test_integrate_odometry_hand_computed():
    """Alg 6 / Eq 5.13 frame-correct: d <- d + R(q_before) v dt, q <- q * exp(omega dt)."""
    start = Pose([0.0, 0.0, 0.0], [0.0, 0.0, S2, S2])  # body x = world y
    out = integrate_odometry(start, [0.5, 0.0, 0.0], [0.0, 0.0, math.pi / 2], 1.0)
    np.testing.assert_allclose(out.position_m, [0.0, 0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(out.quaternion_xyzw, [0.0, 0.0, 1.0, 0.0], atol=1e-15)


def test_exact_round_trip_and_map_contract():
    """A random 6-step path: integrating the exact odometry reproduces every pose, and the SE(3)
    object map's accumulation (maps.se3, an independent implementation) from the first pose does
    too: the frame convention is the map's."""
    poses = [Pose.from_rotation(np.random.default_rng(i).uniform(-0.5, 0.5, 3), Rotation.random(random_state=i))
             for i in range(7)]
    geo = SE3Geometry()
    acc = geo.initial_accumulator()
    base = np.concatenate([poses[0].position_m, poses[0].quaternion_xyzw])
    pose = poses[0]
    for k, (a, b) in enumerate(zip(poses[:-1], poses[1:]), start=1):
        v, omega, dt = exact_odometry(a, b, dt=0.5 + 0.1 * k)
        pose = integrate_odometry(pose, v, omega, dt)
        assert _close(pose, b, 1e-12)
        geo.accumulate(acc, SpatialOdometry(v, omega, dt))
        mapped = geo.new_pose(base, acc)
        assert _close(Pose(mapped[:3], mapped[3:]), b, 1e-12)


def test_zero_noise_equals_exact_odometry():
    prev = Pose([0.1, 0.0, 0.2], Rotation.from_euler("xyz", [10, -20, 30], degrees=True).as_quat())
    nxt = Pose([0.18, 0.05, 0.21], Rotation.from_euler("xyz", [14, -12, 41], degrees=True).as_quat())
    params = OdometryNoise().noise_free()
    v, omega, dt = noisy_odometry(prev, nxt, np.random.default_rng(0), params)
    _, R = relative_motion(prev, nxt)
    assert dt == pytest.approx(R.magnitude() / 0.03, rel=1e-12)  # Eq 6.8 with omega = its mean
    ve, oe, _ = exact_odometry(prev, nxt, dt)
    np.testing.assert_allclose(v, ve, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(omega, oe, rtol=1e-12, atol=1e-15)
    assert np.linalg.norm(omega) == pytest.approx(0.03, rel=1e-12)  # Eq 6.7: |omega_eta| = omega
    assert _close(integrate_odometry(prev, v, omega, dt), nxt, 1e-12)


# ------------------------------------------------------------- noise statistics
def test_noise_statistics_match_eq_6_4_to_6_11():
    """From n noisy samples of one step (11 cm, 12 deg: the thesis' step) recover the three
    noise sources through the model's definitions and compare with their parameters."""
    prev = Pose([0.0, 0.0, 0.3], Rotation.from_euler("xyz", [5, 10, 15], degrees=True).as_quat())
    step = Pose([0.06, -0.08, 0.045], Rotation.from_rotvec(np.deg2rad(12) * np.array([0.6, 0.0, 0.8])).as_quat())
    nxt = prev @ step
    delta, R = relative_motion(prev, nxt)
    rng = np.random.default_rng(123)
    n = 4000
    speeds, eulers, mags, cosines = [], [], [], []
    for _ in range(n):
        v, omega, dt = noisy_odometry(prev, nxt, rng)
        speeds.append(np.linalg.norm(omega))  # Eq 6.7: |omega e_eta| = omega (no floor at 12 deg)
        R_noise = R.inv() * Rotation.from_rotvec(omega * dt)  # Eq 6.6: R_eta = R R_noise
        eulers.append(R_noise.as_euler("xyz"))
        mags.append(np.linalg.norm(v * dt) - np.linalg.norm(delta))  # Eq 6.9
        cosines.append(float(v @ delta) / (np.linalg.norm(v) * np.linalg.norm(delta)))
    speeds, eulers, mags = np.array(speeds), np.array(eulers), np.array(mags)
    se = 1.0 / math.sqrt(n)
    assert abs(speeds.mean() - 0.03) < 4 * 0.0087 * se
    assert abs(speeds.std() - 0.0087) < 4 * 0.0087 * se * math.sqrt(0.5)
    sigma = math.radians(2.5)
    np.testing.assert_array_less(np.abs(eulers.mean(axis=0)), 4 * sigma * se)
    np.testing.assert_array_less(np.abs(eulers.std(axis=0) - sigma), 4 * sigma * se * math.sqrt(0.5))
    assert abs(mags.mean()) < 4 * 0.01 * se and abs(mags.std() - 0.01) < 4 * 0.01 * se * math.sqrt(0.5)
    np.testing.assert_allclose(cosines, 1.0, atol=1e-12)  # the direction of the step is kept


def test_same_seed_same_noise():
    prev, nxt = Pose([0, 0, 0]), Pose([0.1, 0, 0], Rotation.from_rotvec([0, 0, 0.2]).as_quat())
    g1, g2 = np.random.default_rng(7), np.random.default_rng(7)
    a = [noisy_odometry(prev, nxt, g1) for _ in range(3)]
    b = [noisy_odometry(prev, nxt, g2) for _ in range(3)]
    assert not np.array_equal(a[0][0], a[1][0])  # successive steps draw new noise
    for (v1, w1, t1), (v2, w2, t2) in zip(a, b):
        assert np.array_equal(v1, v2) and np.array_equal(w1, w2) and t1 == t2


# ------------------------------------------------------------- guards
def test_guard_zero_displacement_keeps_a_pure_rotation():
    prev = Pose([0.2, 0.1, 0.0])
    nxt = Pose([0.2, 0.1, 0.0], Rotation.from_rotvec([0.0, 0.3, 0.0]).as_quat())
    for seed in range(20):
        v, omega, dt = noisy_odometry(prev, nxt, np.random.default_rng(seed))
        assert np.array_equal(v, np.zeros(3)) and dt > 0 and np.all(np.isfinite(omega))


def test_guard_no_rotation_floors_dt_and_still_integrates_exactly():
    """A pure translation without rotation noise: theta_eta = 0, Eq 6.8 gives dt = 0; dt is
    floored at min_dt_s and the step integrates to the (noise-free) next pose."""
    prev = Pose([0.0, 0.0, 0.0], [0.0, 0.0, S2, S2])
    nxt = Pose([0.0, 0.11, 0.0], [0.0, 0.0, S2, S2])
    params = OdometryNoise(euler_std_rad=0.0, displacement_std_m=0.0, min_dt_s=0.02)
    v, omega, dt = noisy_odometry(prev, nxt, np.random.default_rng(0), params)
    assert dt == 0.02
    np.testing.assert_array_equal(omega, np.zeros(3))
    np.testing.assert_allclose(v, [0.11 / 0.02, 0.0, 0.0], rtol=1e-12)
    assert _close(integrate_odometry(prev, v, omega, dt), nxt, 1e-12)


def test_guard_non_positive_angular_speed_is_redrawn():
    """Mean 0.002 rad/s, deviation 0.01: most normal draws are <= 0; every returned speed is
    positive, and the speeds follow the normal truncated at 0 (median of N(0.002, 0.01) | > 0)."""
    prev, nxt = Pose([0, 0, 0]), Pose([0.05, 0, 0], Rotation.from_rotvec([0, 0, 0.5]).as_quat())
    params = OdometryNoise(angular_speed_mean_rad_s=0.002, angular_speed_std_rad_s=0.01, euler_std_rad=0.0)
    rng = np.random.default_rng(5)
    speeds = []
    for _ in range(2000):
        v, omega, dt = noisy_odometry(prev, nxt, rng, params)
        assert dt > 0 and np.all(np.isfinite(v))
        speeds.append(0.5 / dt)  # theta_eta = 0.5 rad exactly (no rotation noise)
    speeds = np.array(speeds)
    assert speeds.min() > 0
    from scipy.stats import truncnorm

    a = (0.0 - 0.002) / 0.01
    assert np.median(speeds) == pytest.approx(truncnorm.median(a, np.inf, loc=0.002, scale=0.01), rel=0.08)


def test_guard_negative_magnitude_is_clipped_not_reversed():
    prev, nxt = Pose([0, 0, 0]), Pose([0.01, 0, 0], Rotation.from_rotvec([0, 0.2, 0]).as_quat())
    params = OdometryNoise(displacement_std_m=0.05)  # |delta| = 1 cm, noise 5 cm: ~42 % negative
    rng = np.random.default_rng(9)
    zero = 0
    for _ in range(500):
        v, _, dt = noisy_odometry(prev, nxt, rng, params)
        assert v[0] >= 0.0 and v[1] == 0.0 and v[2] == 0.0
        zero += v[0] == 0.0
    assert 150 < zero < 270  # P(N(0.01, 0.05) < 0) = 0.42 -> 210 of 500


# ------------------------------------------------------------- bad input
def test_bad_input_raises_typed_errors():
    good = Pose([0, 0, 0])
    rng = np.random.default_rng(0)
    nan_pose = np.eye(4)
    nan_pose[0, 3] = np.nan
    with pytest.raises(InvalidInputError):
        noisy_odometry(nan_pose, good, rng)
    with pytest.raises(InvalidInputError, match="norm"):
        noisy_odometry(good, ([0, 0, 0], [0, 0, 0, 2.0]), rng)  # non-unit quaternion
    with pytest.raises(InvalidInputError, match="Generator"):
        noisy_odometry(good, good, 0)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="OdometryNoise"):
        noisy_odometry(good, good, rng, {"euler_std_rad": 0.0})  # type: ignore[arg-type]
    for bad_dt in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(InvalidInputError):
            exact_odometry(good, good, bad_dt)
    with pytest.raises(InvalidInputError, match="overflows"):
        exact_odometry(good, Pose([1.0, 0.0, 0.0]), 1e-320)
    with pytest.raises(InvalidInputError, match="longer than"):
        noisy_odometry(good, Pose([2e4, 0.0, 0.0]), rng)  # millimetres typed as metres
    with pytest.raises(ShapeError):
        integrate_odometry(good, [0.0, 0.0], [0.0, 0.0, 0.0], 1.0)
    with pytest.raises(InvalidInputError):
        integrate_odometry(good, [0.0, 0.0, np.nan], [0.0, 0.0, 0.0], 1.0)
    with pytest.raises(InvalidInputError):
        integrate_odometry(good, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], -1.0)
    with pytest.raises(InvalidInputError):
        OdometryNoise(angular_speed_mean_rad_s=0.0)
    with pytest.raises(InvalidInputError):
        OdometryNoise(displacement_std_m=-0.01)
    with pytest.raises(InvalidInputError):
        OdometryNoise(min_dt_s=0.0)
    with pytest.raises(InvalidInputError):
        OdometryNoise(euler_std_rad=np.nan)


# ------------------------------------------------------------- properties
@settings(max_examples=80, deadline=None)
@given(positions, raw_quats, positions, raw_quats, st.floats(0.01, 100.0))
def test_exact_round_trip_property(p1, q1, p2, q2, dt):
    a, b = _pose(p1, q1), _pose(p2, q2)
    v, omega, t = exact_odometry(a, b, dt)
    assert t == dt and np.linalg.norm(omega) * dt <= math.pi + 1e-12
    assert _close(integrate_odometry(a, v, omega, t), b, 1e-9)


@settings(max_examples=80, deadline=None)
@given(positions, raw_quats, positions, raw_quats, st.integers(0, 2**32 - 1))
def test_noisy_odometry_is_finite_and_keeps_the_direction(p1, q1, p2, q2, seed):
    a, b = _pose(p1, q1), _pose(p2, q2)
    params = OdometryNoise()
    v, omega, dt = noisy_odometry(a, b, np.random.default_rng(seed), params)
    assert np.all(np.isfinite(v)) and np.all(np.isfinite(omega)) and math.isfinite(dt)
    assert dt >= params.min_dt_s and np.linalg.norm(omega) * dt <= math.pi + 1e-9
    delta, _ = relative_motion(a, b)
    if np.linalg.norm(delta) > 1e-9 and np.linalg.norm(v) > 0:
        cos = float(v @ delta) / (np.linalg.norm(v) * np.linalg.norm(delta))
        assert cos == pytest.approx(1.0, abs=1e-9)  # Eq 6.9 scales, never turns, the step


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, st.sampled_from([(4, 4), (3, 3), (6,), (7,)]),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)))
def test_bad_poses_are_typed_errors(value):
    try:
        v, omega, dt = noisy_odometry(value, Pose([0, 0, 0]), np.random.default_rng(0))
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    assert np.all(np.isfinite(v)) and np.all(np.isfinite(omega)) and dt > 0


@settings(max_examples=50, deadline=None)
@given(st.floats(0.0, 100.0))
@example(1.0)
def test_scaled_odometry_noise_multiplies_the_rotation_and_displacement_deviations(k):
    q = OdometryNoise().scaled(k)
    assert q.euler_std_rad == pytest.approx(k * math.radians(2.5)) and q.displacement_std_m == pytest.approx(k * 0.01)
    assert (q.angular_speed_mean_rad_s, q.angular_speed_std_rad_s, q.min_dt_s) == (0.03, 0.0087, 0.01)  # kept
    if k == 1.0:
        assert q == OdometryNoise()


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), True, "1", None])
def test_scaled_odometry_noise_refuses_a_bad_scale(bad):
    with pytest.raises(InvalidInputError, match="scale"):
        OdometryNoise().scaled(bad)
