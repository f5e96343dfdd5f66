"""Angle wrapping (whisker_io.angles): named ranges, the C++ loop's results, constant time."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whisker_io.angles import LOOP_TURNS, TWO_PI, wrap_scalar, wrap_to_2pi, wrap_to_pi, wrap_to_pi_closed_above
from whisker_io.errors import InvalidInputError

PI = math.pi
any_angle = st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False)
near_angle = st.floats(-LOOP_TURNS * TWO_PI, LOOP_TURNS * TWO_PI, allow_nan=False)


def clip_rad_180(a):  # OpenRatSLAM's loop, written out independently
    while a > PI:
        a -= TWO_PI
    while a <= -PI:
        a += TWO_PI
    return a


def clip_rad_360(a):
    while a < 0:
        a += TWO_PI
    while a >= TWO_PI:
        a -= TWO_PI
    return a


@pytest.mark.parametrize(("a", "pi_open", "pi_closed", "two_pi"), [
    (0.0, 0.0, 0.0, 0.0),
    (PI, -PI, PI, PI),
    (-PI, -PI, PI, PI),
    (1.5 * PI, -0.5 * PI, -0.5 * PI, 1.5 * PI),
    (-0.5 * PI, -0.5 * PI, -0.5 * PI, 1.5 * PI),
    (TWO_PI, 0.0, 0.0, 0.0),
    (7.0, 7.0 - TWO_PI, 7.0 - TWO_PI, 7.0 - TWO_PI),
])
def test_hand_computed_boundaries(a, pi_open, pi_closed, two_pi):
    assert wrap_to_pi(a) == pytest.approx(pi_open, abs=1e-15)
    assert wrap_to_pi_closed_above(a) == pytest.approx(pi_closed, abs=1e-15)
    assert wrap_to_2pi(a) == pytest.approx(two_pi, abs=1e-15)


def test_huge_angle_returns_at_once():
    # a subtraction loop would run ~1e16 times here (issue 10: ExperienceMap.on_odo hung)
    for f, lo, hi in ((wrap_to_pi, -PI, PI), (wrap_to_pi_closed_above, -PI, PI), (wrap_to_2pi, 0.0, TWO_PI)):
        r = f(1e17)
        assert lo <= r <= hi
        assert f(np.array([1e17, -1e300])).shape == (2,)
    # beyond LOOP_TURNS the angle is reduced modulo the double TWO_PI exactly;
    # the exact remainder computed with rationals is the independent truth
    for a in (1e17, -3.0e12, 123456789.125):
        expect = float(Fraction(a) % Fraction(TWO_PI))
        assert wrap_to_2pi(a) == expect


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, [0.0, math.nan], "1.0", None])
def test_non_finite_or_non_numeric_raises(bad):
    for f in (wrap_to_pi, wrap_to_pi_closed_above, wrap_to_2pi):
        with pytest.raises(InvalidInputError):
            f(bad)


def test_scalar_and_array_forms():
    assert isinstance(wrap_to_pi(4.0), float)
    out = wrap_to_pi(np.array([[4.0, -4.0], [0.5, 10.0]]))
    assert out.shape == (2, 2)
    np.testing.assert_allclose(out, [[4.0 - TWO_PI, TWO_PI - 4.0], [0.5, 10.0 - 2 * TWO_PI]])


@settings(max_examples=300, deadline=None)
@given(any_angle)
def test_ranges_and_idempotence(a):
    r1, r2, r3 = wrap_to_pi(a), wrap_to_pi_closed_above(a), wrap_to_2pi(a)
    assert -PI <= r1 < PI
    assert -PI < r2 <= PI
    assert 0.0 <= r3 < TWO_PI
    assert wrap_to_pi(r1) == r1 and wrap_to_pi_closed_above(r2) == r2 and wrap_to_2pi(r3) == r3


@settings(max_examples=300, deadline=None)
@given(near_angle)
def test_equals_the_reference_loops_within_loop_turns(a):
    assert wrap_to_pi_closed_above(a) == clip_rad_180(a)
    assert wrap_to_2pi(a) == clip_rad_360(a)
    # [-pi, pi) differs from (-pi, pi] only at the boundary
    r = wrap_to_pi(a)
    assert r == clip_rad_180(a) or (r == -PI and clip_rad_180(a) == PI)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e6, 1e6, allow_nan=False))
def test_result_differs_from_input_by_whole_turns(a):
    for f in (wrap_to_pi, wrap_to_pi_closed_above, wrap_to_2pi):
        turns = (a - f(a)) / TWO_PI
        assert abs(turns - round(turns)) < 1e-6


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(near_angle, any_angle), min_size=1, max_size=8))
def test_scalar_kernel_array_path_and_compiled_kernel_agree(angles):
    # one algorithm, three callers: the scalar kernel (SE(2) map), the vectorised
    # array path, and the numba copy compiled from the same source (relaxation kernel)
    from maps import _relax_numba

    arr = np.asarray(angles, dtype=np.float64)
    for lower, closed, public in ((-PI, True, wrap_to_pi_closed_above), (0.0, False, wrap_to_2pi), (-PI, False, wrap_to_pi)):
        kernel = [wrap_scalar(a, lower, closed) for a in angles]
        assert [float(v) for v in public(arr)] == kernel
        assert kernel == [public(a) for a in angles]
        assert kernel == [_relax_numba._wrap(a, lower, closed) for a in angles]
    assert [_relax_numba._clip180(a) for a in angles if abs(a) <= LOOP_TURNS * TWO_PI] == [
        clip_rad_180(a) for a in angles if abs(a) <= LOOP_TURNS * TWO_PI]


_EDGES = [0.0, -0.0, PI, -PI, TWO_PI, -TWO_PI, 3 * PI, -3 * PI, 1e-300, -1e-300]
_EDGES += [math.nextafter(a, d) for a in (PI, -PI, TWO_PI, 0.0, -TWO_PI) for d in (-math.inf, math.inf)]


@settings(max_examples=300, deadline=None)
@given(st.lists(near_angle, min_size=1, max_size=8))
def test_relaxation_clips_equal_the_cpp_loops_bit_for_bit(angles):
    # the relaxation kernel's clips return an angle already in range unchanged and wrap
    # the others; both must give the C++ loops' bits, at the range ends and inside
    from maps import _relax_numba

    for a in _EDGES + angles:
        assert math.copysign(1.0, _relax_numba._clip180(a)) == math.copysign(1.0, clip_rad_180(a))
        assert _relax_numba._clip180(a) == clip_rad_180(a), a
        assert _relax_numba._clip360(a) == clip_rad_360(a), a
        assert math.copysign(1.0, _relax_numba._clip360(a)) == math.copysign(1.0, clip_rad_360(a))


def _cpp_iterate(order, ends, ldata, pose, c, n_updates):
    """OpenRatSLAM's ``ExperienceMap::iterate`` body for the link ids in ``order``, in plain Python."""
    for j in range(n_updates):
        k = order[j % len(order)]
        f, t = ends[k]
        d, heading, facing = ldata[k, 0], ldata[k, 1], ldata[k, 2]
        lx = pose[f][0] + d * math.cos(pose[f][2] + heading)
        ly = pose[f][1] + d * math.sin(pose[f][2] + heading)
        pose[f][0] += (pose[t][0] - lx) * c
        pose[f][1] += (pose[t][1] - ly) * c
        pose[t][0] -= (pose[t][0] - lx) * c
        pose[t][1] -= (pose[t][1] - ly) * c
        a1, a2 = pose[f][2] + facing, pose[t][2]  # get_signed_delta_rad(a1, a2)
        direction = clip_rad_180(a2 - a1)
        delta = abs(clip_rad_360(a1) - clip_rad_360(a2))
        if delta < TWO_PI - delta:
            df = delta if direction > 0 else -delta
        else:
            df = TWO_PI - delta if direction > 0 else -(TWO_PI - delta)
        pose[f][2] = clip_rad_180(pose[f][2] + df * c)
        pose[t][2] = clip_rad_180(pose[t][2] - df * c)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 12), st.integers(1, 30))
def test_relax_links_equals_openratslam_iterate_bit_for_bit(seed, n_exp, n_links):
    # random maps whose facings and link angles sit near +-pi and 0 / 2 pi (both the
    # in-range shortcut and the wrap of the clips are taken), against the C++ transcription
    from maps._relax_numba import relax_links

    rng = np.random.default_rng(seed)
    ends = np.stack([rng.integers(0, n_exp, n_links), rng.integers(0, n_exp - 1, n_links)], axis=1)
    ends[:, 1] += ends[:, 1] >= ends[:, 0]  # no self-links (the map never makes one)
    angle = lambda n: rng.choice([-PI, PI, 0.0, TWO_PI], n) + rng.normal(0, 1e-3, n) * rng.integers(0, 2, n)  # noqa: E731
    ldata = np.stack([rng.uniform(0, 5, n_links), angle(n_links), angle(n_links), rng.uniform(0, 3, n_links)], axis=1)
    pose = np.stack([rng.normal(0, 10, n_exp), rng.normal(0, 10, n_exp), np.clip(angle(n_exp), -PI + 1e-12, PI)], axis=1)
    order = np.argsort(ends[:, 0] * (1 << 32) + np.arange(n_links), kind="stable").astype(np.int64)
    n_updates = 10 * n_links
    want = pose.tolist()
    _cpp_iterate(order.tolist(), ends.tolist(), ldata, want, 0.5, n_updates)
    got = pose.copy()
    assert relax_links(order, ends.astype(np.int64), ldata, got, 0.5, n_updates, 0) == n_updates % n_links
    assert got.tobytes() == np.array(want).tobytes()
