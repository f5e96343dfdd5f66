"""Tests of cansim.testing.worlds: synthetic routes, Ch.3 odometry noise, kidnapping, rendered views."""

import math

import numpy as np
import pytest

from cansim.errors import InvalidInputError
from cansim.testing.worlds import LoopRoute, Ch3OdometryNoise, ch3_loops, make_run, render_view, scatter_landmarks


def test_route_geometry():
    route = LoopRoute(width_m=2.0, height_m=1.0, corner_radius_m=0.25, step_m=0.05)
    assert route.perimeter == pytest.approx(2 * 1.5 + 2 * 0.5 + 2 * math.pi * 0.25)
    pts = route.places()
    assert pts.shape == (route.n_places, 2)
    gaps = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assert np.all(gaps < route.perimeter / route.n_places * 1.0001)  # chords <= arc steps
    assert np.all(np.abs(pts[:, 0]) <= 1.0 + 1e-12) and np.all(np.abs(pts[:, 1]) <= 0.5 + 1e-12)


def test_noiseless_run_dead_reckoning_equals_truth_and_views_repeat():
    run = make_run(loops=(1, 1, -1, -1), noise=None)
    n = run.n_places
    assert len(run) == 1 + 4 * n + 6  # start + 4 loops + one 180 deg turn of 6 steps
    np.testing.assert_allclose(run.dead_reckoning[:, :2], run.truth[:, :2], atol=1e-9)
    dth = (run.dead_reckoning[:, 2] - run.truth[:, 2] + math.pi) % (2 * math.pi) - math.pi
    assert np.abs(dth).max() < 1e-9
    # the same place in the same direction gives the same view; directions differ
    first, second = run.view_ids[1 : n + 1], run.view_ids[n + 1 : 2 * n + 1]
    np.testing.assert_array_equal(first, second)
    cw = run.view_ids[run.directions == -1]
    assert set(cw.tolist()).isdisjoint(first.tolist())
    # the turn happens on the spot and sums to pi
    turn = run.places == -1
    assert turn.sum() == 6 and np.allclose(run.vtrans[turn], 0.0)
    assert run.vrot[turn].sum() * run.dt == pytest.approx(math.pi)
    assert ch3_loops() == (-1, -1, -1, 1, 1, 1, -1, 1)


def test_odometry_noise_statistics_match_ch3_model():
    route = LoopRoute(step_m=0.05)
    noisy = make_run(route, loops=(1,) * 40, seed=3)
    clean = make_run(route, loops=(1,) * 40, noise=None)
    lin_err = (noisy.vtrans - clean.vtrans)[1:] * noisy.dt
    ang_err = np.degrees((noisy.vrot - clean.vrot)[1:] * noisy.dt)
    log_mag = np.log(np.abs(lin_err))
    assert log_mag.mean() == pytest.approx(-4.3, abs=0.03)
    assert log_mag.std() == pytest.approx(0.45, abs=0.03)
    assert abs(np.mean(np.sign(lin_err))) < 0.05  # random sign
    assert ang_err.std() == pytest.approx(0.3, abs=0.02)
    assert abs(ang_err.mean()) < 0.02
    pos = make_run(route, loops=(1,) * 5, seed=3, noise=Ch3OdometryNoise(linear_sign="positive"))
    assert np.all((pos.vtrans - make_run(route, loops=(1,) * 5, noise=None).vtrans)[1:] > 0)


def test_seeded_and_deterministic():
    a, b = make_run(seed=11), make_run(seed=11)
    assert a.vtrans.tobytes() == b.vtrans.tobytes() and a.vrot.tobytes() == b.vrot.tobytes()
    assert make_run(seed=12).vtrans.tobytes() != a.vtrans.tobytes()


def test_kidnapped_run_skips_forward_without_odometry():
    clean = make_run(loops=(1, 1), noise=None)
    kid = make_run(loops=(1, 1), noise=None, kidnap=(100, 20))
    assert len(kid) == len(clean) - 20 and kid.kidnap_indices == (100,)
    np.testing.assert_array_equal(kid.truth[100], clean.truth[120])
    np.testing.assert_array_equal(kid.view_ids[100:], clean.view_ids[120:])
    assert kid.vtrans[100] == clean.vtrans[100]  # an ordinary step as far as odometry knows
    jump = np.hypot(*(kid.dead_reckoning[100, :2] - kid.truth[100, :2]))
    assert jump > 0.5  # dead reckoning misses the 1 m jump
    with pytest.raises(InvalidInputError):
        make_run(loops=(1,), kidnap=(10, 10**6))


def test_aliasing_replaces_a_fraction_of_views():
    clean = make_run(noise=None)
    alias = make_run(noise=None, aliasing=0.2, seed=4)
    frac = np.mean(clean.view_ids != alias.view_ids)
    assert 0.12 < frac < 0.25


def test_panoramic_render_rotates_columns():
    route = LoopRoute()
    lm = scatter_landmarks(route, seed=2)
    w = 64
    img = render_view((0.1, 0.2, 0.3), lm, shape=(10, w))
    assert img.dtype == np.uint8 and img.shape == (10, w) and img.max() > img.min()
    turned = render_view((0.1, 0.2, 0.3 + 5 * 2 * math.pi / w), lm, shape=(10, w))
    assert np.abs(turned.astype(int) - np.roll(img, 5, axis=1).astype(int)).max() <= 1


def test_bad_arguments():
    with pytest.raises(InvalidInputError):
        make_run(loops=(2,))
    with pytest.raises(InvalidInputError):
        make_run(aliasing=1.5)
    with pytest.raises(InvalidInputError):
        LoopRoute(corner_radius_m=5.0)
