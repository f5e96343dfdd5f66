"""Thesis Ch.3 end to end: simulated whisks in the maze -> tactile images -> RatSLAM (issue 14).

Covers the sensing chain (whisker_io.sim.planar_chain, whisker_io.sim.ch3_scene,
whisker_io.contact.contact_angle, whisker_io.features.whisk_tactile_image), its
replay from a recorded session, RatSLAM closing the loop on it, kidnapping, the
study's quick mode and the typed errors of every new entry point.
"""

from __future__ import annotations

import csv
import importlib.util
import math

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cansim.errors import CansimError, InvalidInputError, ShapeError
from cansim.frontends.tactile import TactileTemplateConfig
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from cansim.testing.worlds import make_run
from maps.metrics import absolute_trajectory_error, experience_metric
from maps.plot_maps import plot_experience_ids
from whisker_io.array.control import OpenLoop, WhiskPattern
from whisker_io.array.geometry import WhiskerArray
from whisker_io.contact.contact_angle import ContactAngleParams, contact_angle, contact_angles
from whisker_io.errors import CorruptFileError
from whisker_io.features.tactile_image import TactileImageParams, pixel_layout
from whisker_io.features.whisk_tactile_image import tactile_image_from_records, tactile_images_from_recording
from whisker_io.records.recording import RecordingWriter
from whisker_io.sim.ch3_scene import MazeRoute, ch3_terrain
from whisker_io.sim.planar_chain import PlanarChain, WhiskSchedule
from whisker_io.sim.signals import SignalParams, WhiskContact, simulate_whisk_cycle

ARRAY = WhiskerArray.thesis()
HYP = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _load_study():
    return importlib.import_module("cansim.studies.ch3_maze")


@pytest.fixture(scope="module")
def terrain() -> trimesh.Trimesh:
    return ch3_terrain()


# ----------------------------------------------------------------- the scene and the timing
def test_route_places_are_equally_spaced_counter_clockwise_and_clear_of_the_maze(terrain):
    route = MazeRoute()
    pts = route.places()
    assert pts.shape == (route.n_places, 2)
    gaps = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assert gaps.max() <= route.perimeter_m / route.n_places * (1 + 1e-9)  # chords never exceed the arc step
    assert gaps.min() > 0.99 * route.step_m
    x, y = pts[:, 0], pts[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0  # counter-clockwise
    # a rectangle with rounded corners, by hand: 2(a + b) - 8r + 2 pi r
    rect = MazeRoute(((0.0, 0.0), (1.0, 0.0), (1.0, 0.5), (0.0, 0.5)), corner_radius_m=0.1, step_m=0.01)
    assert rect.perimeter_m == pytest.approx(3.0 - 0.8 + 2 * math.pi * 0.1)
    # the array's axis stays 7 cm or more from the maze everywhere along the route
    dist = np.abs(trimesh.proximity.signed_distance(terrain, np.column_stack([pts, np.full(len(pts), 0.01)])))
    assert dist.min() > 0.07


def test_terrain_is_the_maze_below_the_array_plane(terrain):
    assert terrain.bounds[1, 2] == pytest.approx(0.07)
    assert terrain.bounds[1, 2] < 0.077
    np.testing.assert_allclose(terrain.bounds[:, :2], [[-0.005, -0.005], [1.355, 1.005]])


def test_schedule_pairs_1p5_hz_iterations_with_1_hz_whisks():
    sched = WhiskSchedule()
    idx = sched.image_index(10)
    # iteration k at k/1.5 s shows the latest cycle [j, j+1) s completed by then, by hand
    np.testing.assert_array_equal(idx, [-1, -1, 0, 1, 1, 2, 3, 3, 4, 5])
    path = np.column_stack([np.arange(10) * 0.015, np.zeros(10), np.zeros(10)])
    poses = sched.whisk_poses(path)
    # cycle j's middle is at (j + 0.5) s = iteration 1.5 (j + 0.5): x = 0.015 * 1.5 (j + 0.5)
    np.testing.assert_allclose(poses[:, 0], 0.015 * 1.5 * (np.arange(6) + 0.5))
    turn = np.column_stack([np.zeros(4), np.zeros(4), [3.0, -3.1, -2.9, -2.7]])  # across +-pi
    assert abs(sched.whisk_poses(turn)[0, 2]) > 3.0  # interpolated along the short arc


# ----------------------------------------------------------------- contact angles against the signal model's truth
def test_contact_angle_strategies_against_simulated_truth():
    contact = WhiskContact(angle_rad=math.radians(10.0), radial_distance_m=0.06, whisker_length_m=0.1)
    recs, truths = simulate_whisk_cycle([contact, None], OpenLoop(WhiskPattern()), seed=4, modules=["A1", "A2"])
    onset = contact_angle(recs[0], ContactAngleParams("onset"))
    assert onset == pytest.approx(math.radians(10.0), abs=math.radians(1.0))
    thr = contact_angle(recs[0], ContactAngleParams("threshold"))
    # the rate crosses its threshold within the centred span-100 window around the kink (no lead
    # compensation): at most half a window (25 ms) of the fastest whisking (100 deg * pi rad/s) early
    lead = 50 / 2000 * math.radians(100.0) * math.pi
    assert math.radians(10.0) - lead <= thr <= math.radians(11.0)
    assert contact_angle(recs[0], ContactAngleParams("max_angle")) == pytest.approx(float(recs[0].angle_rad.max()))
    for method in ("onset", "max_angle", "threshold"):
        angles = contact_angles(recs, ContactAngleParams(method))
        assert np.isfinite(angles[0]) and np.isnan(angles[1])  # free whisking: no contact
    # max angle needs the whisker to be in contact at the largest angle: a slip before it loses the contact
    slipped = WhiskContact(angle_rad=0.0, radial_distance_m=0.06, whisker_length_m=0.1, slip_rad=math.radians(20.0))
    (rec,), _ = simulate_whisk_cycle([slipped], seed=4)
    assert contact_angle(rec, ContactAngleParams("max_angle")) is None
    assert contact_angle(rec, ContactAngleParams("onset")) == pytest.approx(0.0, abs=math.radians(1.0))


# ----------------------------------------------------------------- the tactile image against a flat wall, by hand
def _flat_wall(x0: float) -> trimesh.Trimesh:
    wall = trimesh.creation.box(extents=(0.05, 1.0, 0.3))
    wall.apply_translation((x0 + 0.025, 0.5, 0.15))  # spans y 0-1 m
    return wall


def _hand_contacts(pose_xy: tuple[float, float], wall_x: float, rostral_height: float):
    """Which whiskers reach the plane x = wall_x, and at which angle, for the array pointing down at yaw 0.

    Mount at yaw 0: end-effector x -> world x, z -> world y, y (the array axis) -> world -z, the
    row-1 pivots (y_E = 201.86 mm) at ``rostral_height``. A whisker whose radial direction makes
    the angle alpha with +x first reaches the plane when L cos(theta) cos(alpha) = D, i.e. at
    theta_c = -arccos(D / (L cos alpha)), or at the -50 deg start if it already reaches it there.
    """
    out = {}
    for m in ARRAY.modules:
        bx, by_e, bz_e = m.base_position_m
        base = np.array([pose_xy[0] + bx, pose_xy[1] + bz_e, rostral_height + (0.20186 - by_e)])
        alpha = math.atan2(bz_e, bx)
        reach = m.length_m * math.cos(alpha)
        d = wall_x - base[0]
        if reach >= d > 0:
            theta = max(-math.acos(d / reach), math.radians(-50.0))
            out[m.name] = (theta, base[2])
    return out


def test_tactile_image_of_a_known_pose_against_a_flat_wall_equals_hand_computed_heights():
    x0, y0, wall_x = 0.3, 0.5, 0.42
    wall = _flat_wall(wall_x)
    noiseless = SignalParams(angle_noise_std_rad=0.0)
    chain = PlanarChain(wall, "open_loop", signal_params=noiseless, seed=3)
    whisk = chain.whisk(x0, y0, 0.0)
    hand = _hand_contacts((x0, y0), wall_x, 0.077)
    assert sorted(hand) == ["A2", "A3", "B2", "B3"]  # the four whiskers facing the wall that reach it
    assert sorted(c.module for c in whisk.sweep_contacts if c is not None) == sorted(hand)
    rows, cols, _ = pixel_layout(ARRAY)
    # max angle, open loop: every contacting whisker is at +50 deg at the top of its whisk, so
    # its tip (Eq 5.1-5.2, tip assumption) is at z = z_base - L sin 50 deg; 0-77 mm -> 1-255
    img = chain.tactile_images([whisk], ContactAngleParams("max_angle"))[0]
    expected = np.zeros((3, 6), dtype=np.uint8)
    for name, (_, z_base) in hand.items():
        i = ARRAY.index(name)
        h = z_base - ARRAY.lengths_m[i] * math.sin(math.radians(50.0))
        expected[rows[i], cols[i]] = 1 + round(254 * min(max(h / 0.077, 0.0), 1.0))
    np.testing.assert_array_equal(img, expected)
    assert expected[rows[ARRAY.index("A2")], cols[ARRAY.index("A2")]] == 1 + round(254 * (0.077 + 0.019957 - 0.1 * math.sin(math.radians(50))) / 0.077)
    # contact onset: the tip at the first-touch angle, z = z_base - L sin(theta_c) (above the base:
    # the whisker meets the wall while still retracted), on a 0-0.3 m scale; the onset estimate
    # of the detection pipeline is within a degree, so within 3 grey levels
    tall = TactileImageParams(height_range_m=(0.0, 0.3))
    img = chain.tactile_images([whisk], ContactAngleParams("onset"), tall)[0]
    assert np.count_nonzero(img) == len(hand)
    for name, (theta, z_base) in hand.items():
        i = ARRAY.index(name)
        h = z_base - ARRAY.lengths_m[i] * math.sin(theta)
        assert abs(int(img[rows[i], cols[i]]) - (1 + round(254 * h / 0.3))) <= 3, name


# ----------------------------------------------------------------- replay of a recorded session
def test_recorded_session_replays_to_identical_tactile_images(tmp_path, terrain):
    chain = PlanarChain(terrain, "rcp", seed=5)
    path = np.column_stack([np.linspace(0.6, 0.75, 6), np.full(6, 0.125), np.zeros(6)])
    whisks = chain.whisk_path(path)
    with RecordingWriter(tmp_path) as writer:
        for j, w in enumerate(whisks):
            w.write(writer, time_s=float(j))
    for method in ("onset", "max_angle", "threshold"):
        live = chain.tactile_images(whisks, ContactAngleParams(method))
        replayed = tactile_images_from_recording(tmp_path, angle_params=ContactAngleParams(method))
        assert replayed.images.dtype == np.uint8 and replayed.images.shape == (6, 3, 6)
        np.testing.assert_array_equal(replayed.images, live)
        assert [e.time_s for e in replayed.entries] == [float(j) for j in range(6)]
    assert np.count_nonzero(live) > 0  # the corridor walls are touched
    (tmp_path / "whisk_000002_C3.csv").unlink()
    with pytest.raises(CorruptFileError, match="C3"):
        tactile_images_from_recording(tmp_path)


# ----------------------------------------------------------------- RatSLAM on the chain
def _clean_run(terrain, seed: int, loops, control: str = "open_loop", method: str = "threshold"):
    sched = WhiskSchedule()
    route = MazeRoute()
    run = make_run(route, loops=loops, seed=seed, dt=sched.iteration_s)
    chain = PlanarChain(terrain, control, seed=seed)
    images = chain.tactile_images(chain.whisk_path(sched.whisk_poses(run.truth)), ContactAngleParams(method))
    return route, run, sched.image_index(len(run)), images


def _slam(run, image_index, images, threshold=3.0, energy=0.05):
    slam = RatSLAM(RatSLAMConfig.thesis_ch3(frontend=TactileTemplateConfig(match_threshold=threshold), inject_energy=energy))
    log = slam.run(run.vtrans, run.vrot, run.dt, [None if j < 0 else images[j] for j in image_index])
    valid = log.exp_ids >= 0
    return slam, log.exp_ids[valid], run.truth[valid], run.dead_reckoning[valid], int(np.count_nonzero(valid[: run.n_places + 1]))


@pytest.fixture(scope="module")
def anticlockwise_run(terrain):
    """A reduced Ch.3 path: eight anticlockwise loops (no reversals), open loop, contact angle by threshold."""
    return _clean_run(terrain, seed=1, loops=(1,) * 8)


def test_reduced_route_through_the_full_chain_closes_the_loop(anticlockwise_run):
    _, run, image_index, images = anticlockwise_run
    slam, ids, truth, dead_reckoning, base_end = _slam(run, image_index, images)
    map_error = absolute_trajectory_error(slam.experience_map.poses[ids], truth).rmse
    dr_error = absolute_trajectory_error(dead_reckoning, truth).rmse
    assert dr_error > 0.1  # the Ch.3 odometry noise has made dead reckoning useless
    assert map_error < 0.5 * dr_error
    exm = experience_metric(ids, truth, base_end)
    assert exm.n_relocalisations > 20 and exm.arcr > 0.8


def test_least_squares_relaxation_of_the_reduced_route_closes_the_loop(anticlockwise_run):
    """The study's ``least_squares`` relaxation moves the poses only (same map, gauge kept); an unknown relaxation
    is refused. On this route the views come from Table 3.1's one-image matcher, which aliases places, so tying
    the experiences of one view (the default, made for the sequence recognition's views) pulls different places
    together (measured 0.235 m against dead reckoning's 0.338 m), which is why ``thesis_ch3`` keeps Eq 2.25
    (0.059 m); without the ties, or with a robust loss, the least-squares map is within half of dead reckoning
    (measured 0.059 m and 0.033 m)."""
    from maps.least_squares_relaxation import LeastSquaresConfig, relax_least_squares

    study = _load_study()
    _, run, image_index, images = anticlockwise_run
    slam, ids, truth, dead_reckoning, _ = _slam(run, image_index, images)
    own = study.map_poses(slam, "eq2_25")
    relaxed = study.map_poses(slam, "least_squares")
    assert relaxed.shape == own.shape and not np.allclose(relaxed, own)
    np.testing.assert_array_equal(relaxed[0], own[0])  # the gauge: the first experience stays
    np.testing.assert_array_equal(slam.experience_map.poses, own)  # the map itself is not changed
    dr_error = absolute_trajectory_error(dead_reckoning, truth).rmse
    for cfg in (LeastSquaresConfig(tie_views=False), LeastSquaresConfig(loss="cauchy")):
        assert absolute_trajectory_error(relax_least_squares(slam.experience_map, cfg)[ids], truth).rmse < 0.5 * dr_error, cfg
    with pytest.raises(InvalidInputError):
        study.map_poses(slam, "gauss_seidel")


def test_kidnapping_lowers_arr(anticlockwise_run):
    route, run, image_index, images = anticlockwise_run
    n = run.n_places
    events = [(run.loop_starts[k] + n // 2, n // 4) for k in (1, 3, 5)]
    kid = make_run(route, loops=(1,) * 8, seed=1, dt=run.dt, kidnap=events)
    keep = np.ones(len(run), dtype=bool)
    for at, skip in events:
        keep[at : at + skip] = False
    np.testing.assert_array_equal(kid.truth, run.truth[keep])  # the same data set with stretches removed
    arr = {}
    for name, r, idx in (("normal", run, image_index), ("kidnapped", kid, image_index[keep])):
        _, ids, truth, _, base_end = _slam(r, idx, images)
        arr[name] = experience_metric(ids, truth, base_end).arr
    assert arr["kidnapped"] < arr["normal"]


def test_bad_tactile_images_raise_typed_errors_and_leave_the_model_unchanged(tmp_path):
    slam = RatSLAM(RatSLAMConfig.thesis_ch3(frontend=TactileTemplateConfig(match_threshold=3.0), inject_energy=0.05))
    good = np.zeros((3, 6), dtype=np.uint8)
    good[0, 2] = 120
    for _ in range(3):
        slam.step(0.0225, 0.0, 1 / 1.5, good)
    slam.save(tmp_path / "before.npz")
    before = dict(np.load(tmp_path / "before.npz", allow_pickle=False))
    bad = {
        "wrong shape": (np.zeros((6, 3), dtype=np.uint8), ShapeError),
        "flat": (np.zeros(18, dtype=np.uint8), ShapeError),
        "float dtype": (np.zeros((3, 6)), InvalidInputError),
        "NaN": (np.full((3, 6), np.nan), InvalidInputError),
        "above 255": (np.full((3, 6), 256, dtype=np.int64), InvalidInputError),
        "negative": (np.full((3, 6), -1, dtype=np.int64), InvalidInputError),
    }
    for label, (image, error) in bad.items():
        with pytest.raises(error):
            slam.step(0.0225, 0.0, 1 / 1.5, image)
        slam.save(tmp_path / "after.npz")
        after = dict(np.load(tmp_path / "after.npz", allow_pickle=False))
        assert after.keys() == before.keys(), label
        for key in before:
            assert np.array_equal(after[key], before[key]), (label, key)


# ----------------------------------------------------------------- the study
@pytest.fixture(scope="module")
def quick_study(tmp_path_factory):
    """``cansim study ch3 --quick`` through the installed entry point, as a user runs it; its output folder and rows."""
    from entry_point import run_cansim

    out = tmp_path_factory.mktemp("ch3_quick")
    done = run_cansim("study", "ch3", "--quick", "--out", str(out))
    assert done.returncode == 0, done.stderr[-3000:]
    with open(out / "ch3_metrics.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    return out, rows


@pytest.mark.slow
def test_study_quick_mode_writes_the_named_columns(quick_study):
    tmp_path, rows = quick_study
    study = _load_study()
    assert rows[0] == ["control", "contact_angle", "kidnapped", "ARR", "ARCR", "EM", "map_error_m", "dr_error_m", "seed"]
    body = rows[1:]
    assert len(body) == 2 * 2 * 3 * 2  # 2 repetitions x {open_loop, rcp} x {onset, max_angle, threshold} x {normal, kidnapped}
    assert [r[8] for r in body] == ["1"] * 12 + ["2"] * 12  # the summary's "seeds [1, 2]", by repetition
    assert {r[0] for r in body} == {"open_loop", "rcp"}
    assert {r[1] for r in body} == {"onset", "max_angle", "threshold"}
    assert {r[2] for r in body} == {"true", "false"}
    for r in body:
        arr, em, map_err, dr_err = float(r[3]), float(r[5]), float(r[6]), float(r[7])
        assert 0.0 <= arr <= 1.0 and em >= 0.0 and map_err > 0.0 and dr_err > 0.0
    for name in ("ch3_map.png", "ch3_experience_ids.png", "ch3_performance.png", "ch3_distances.png"):
        assert (tmp_path / name).stat().st_size > 20_000
    summary = (tmp_path / "ch3_summary.txt").read_text(encoding="utf-8")
    for figure in ("0.1765", "0.2257", "0.1916", "0.1568", "match_threshold", "inject_energy", "Why places alias", "seeds [1, 2]"):
        assert figure in summary
    assert study.main(["--repetitions", "0", "--out", str(tmp_path)]) == 2
    assert study.main(["--no-such-option"]) == 2
    assert study.main(["--recognition", "nothing", "--out", str(tmp_path)]) == 2
    assert study.main(["--relaxation", "nothing", "--out", str(tmp_path)]) == 2
    assert "relaxation 'least_squares'" in summary  # the default with sequence recognition


def _quick_rows(rows, control, angle, kidnapped):
    return [r for r in rows[1:] if r[0] == control and r[1] == angle and r[2] == ("true" if kidnapped else "false")]


def _reference_ratios(summary: str) -> list[float]:
    """Map / dead reckoning of the summary's perfect-recognition reference, one per repetition."""
    line = next(s for s in summary.splitlines() if "reference, perfect recognition" in s)
    return [float(v) for v in line.split("map / dr ")[1].split(" - ")[0].split(", ")]


@pytest.mark.slow
@pytest.mark.parametrize("control, angle", [(c, m) for c in ("open_loop", "rcp") for m in ("onset", "max_angle", "threshold")])
def test_quick_study_map_beats_dead_reckoning_with_correct_relocalisations(quick_study, control, angle):
    """Issue 24's acceptance in every condition and repetition (normal runs) of the run the user gets: ARCR >= 0.9
    and the relaxed map (least squares over every traversal, the default) at most half of dead reckoning's error
    (seeds 1-2 measured 0.19-0.30, ARCR 0.990-1.0; held-out seeds 5-12 of the same route: 0.15-0.53, 46 of 48
    condition runs within - see the ch3_maze docstring). Perfect recognition with the same RatSLAM (the summary's
    reference) is within the bound too: the route itself allows it."""
    tmp_path, rows = quick_study
    reference = _reference_ratios((tmp_path / "ch3_summary.txt").read_text(encoding="utf-8"))
    normal = _quick_rows(rows, control, angle, False)
    assert len(normal) == len(reference) == 2
    for r, ref in zip(normal, reference):
        assert float(r[4]) >= 0.9, r
        assert float(r[6]) <= 0.5 * float(r[7]), r
        assert ref <= 0.5, reference


@pytest.mark.slow
def test_quick_study_map_is_within_half_of_dead_reckoning_in_every_condition(quick_study):
    """Issue 24's bound over all conditions of the quick study's seeds 1-2 on the study's 8-loop route (measured
    0.19-0.30 with the least-squares relaxation; 0.19-0.34 with Eq 2.25). Held-out seeds 5-12: 7 of 8 within in
    every condition, seed 11 (dead reckoning 0.099 m) up to 0.53 - see the ch3_maze docstring."""
    _, rows = quick_study
    for c in ("open_loop", "rcp"):
        for m in ("onset", "max_angle", "threshold"):
            for r in _quick_rows(rows, c, m, False):
                assert float(r[6]) <= 0.5 * float(r[7]), r


@pytest.mark.slow
def test_quick_study_relocalises_as_often_as_the_thesis_and_kidnapping_lowers_arr(quick_study):
    tmp_path, rows = quick_study
    ol_max = [float(r[3]) for r in _quick_rows(rows, "open_loop", "max_angle", False)]
    assert min(ol_max) >= 0.18  # the thesis' ARR, open loop + max angle (Fig 3.7: 0.1765), in every repetition
    for c in ("open_loop", "rcp"):
        for m in ("onset", "max_angle", "threshold"):
            normal, kid = _quick_rows(rows, c, m, False), _quick_rows(rows, c, m, True)
            for a, b in zip(normal, kid):  # same repetition, same recording with stretches removed
                assert float(b[3]) < float(a[3]), (c, m)
                assert float(b[4]) >= 0.9, (c, m)  # the map recovers: re-localisations after kidnaps are correct
    summary = (tmp_path / "ch3_summary.txt").read_text(encoding="utf-8")
    assert "kidnapped runs a correct re-localisation follows each kidnap" in summary
    line = next(s for s in summary.splitlines() if s.startswith("4b."))
    got, total = line.split(" in ")[1].split(" ")[0].split("/")
    assert got == total == "12"


@pytest.mark.slow
def test_quick_study_explains_every_finding_it_does_not_reproduce(quick_study):
    """Issue 24: a thesis finding that stays unreproduced has a measured explanation in the summary."""
    tmp_path, _ = quick_study
    lines = (tmp_path / "ch3_summary.txt").read_text(encoding="utf-8").splitlines()
    six = next(s for s in lines if s.startswith("6. "))
    for key in ("ARR", "EM"):
        if f"NOT reproduced ({key})" in six:
            assert any(s.strip().startswith(f"6 ({key}) measured: rcp + threshold is ") and "spread" in s for s in lines), key
    assert any("ARR follows the matcher's recall" in s for s in lines)


# ----------------------------------------------------------------- typed errors of the new entry points (hypothesis)
finite = st.floats(-10.0, 10.0, allow_nan=False)
not_finite = st.sampled_from([math.nan, math.inf, -math.inf])


@HYP
@given(st.one_of(not_finite, st.floats(max_value=0.0, allow_nan=False)))
def test_route_and_terrain_refuse_bad_numbers(value):
    with pytest.raises(InvalidInputError):
        MazeRoute(corner_radius_m=value)
    with pytest.raises(InvalidInputError):
        MazeRoute(step_m=value)
    with pytest.raises(InvalidInputError):
        ch3_terrain(value)


@HYP
@given(st.floats(1e-300, 1e-6))
def test_route_refuses_a_step_giving_too_many_places(step):
    with pytest.raises(InvalidInputError, match="places"):
        MazeRoute(step_m=step)
    with pytest.raises(InvalidInputError, match="metres"):
        MazeRoute(((0.0, 0.0), (1e300, 0.0), (0.0, 1e300)), corner_radius_m=0.01)


@HYP
@given(st.lists(st.tuples(finite, finite), min_size=0, max_size=6), st.booleans())
def test_route_refuses_bad_waypoints(points, poison):
    wp = [list(p) for p in points]
    if poison and wp:
        wp[0][0] = math.nan
    try:
        route = MazeRoute(tuple(map(tuple, wp)), corner_radius_m=0.01, step_m=0.01)
    except InvalidInputError:
        return
    # accepted: a valid counter-clockwise loop with finite places
    assert len(wp) >= 3 and not poison
    assert np.all(np.isfinite(route.places()))
    with pytest.raises(InvalidInputError, match="counter-clockwise"):
        MazeRoute(tuple(map(tuple, wp[::-1])), corner_radius_m=0.01, step_m=0.01)


@HYP
@given(st.one_of(not_finite, st.floats(max_value=0.0, allow_nan=False), st.floats(min_value=1e3 + 1, allow_nan=False, allow_infinity=False)))
def test_schedule_refuses_bad_rates(rate):
    for kwargs in ({"odometry_rate_hz": rate}, {"whisk_rate_hz": rate}):
        with pytest.raises(InvalidInputError):
            WhiskSchedule(**kwargs)


@HYP
@given(st.one_of(st.integers(max_value=0), st.just(1.5), st.just(True), st.integers(min_value=10**7 + 1)))
def test_schedule_refuses_bad_iteration_counts(n):
    with pytest.raises(InvalidInputError):
        WhiskSchedule().image_index(n)


@HYP
@given(st.integers(1, 400), st.floats(0.2, 5.0), st.floats(0.2, 5.0))
def test_schedule_shows_each_completed_whisk_in_order(n, f_odo, f_whisk):
    sched = WhiskSchedule(f_odo, f_whisk)
    idx = sched.image_index(n)
    assert np.all(np.diff(idx) >= 0) and idx[0] == -1
    k = np.flatnonzero(idx >= 0)
    assert np.all((idx[k] + 1) / f_whisk <= k / f_odo + 1e-6)  # the shown cycle is complete
    assert np.all((idx[k] + 2) / f_whisk > k / f_odo - 1e-6)  # and the latest one


@pytest.fixture(scope="module")
def wall_chain():
    return PlanarChain(_flat_wall(0.42), "open_loop", seed=0)


bad_path = st.one_of(
    st.just(np.zeros((0, 3))),
    st.just(np.zeros((4, 2))),
    st.just(np.zeros(3)),
    st.builds(lambda r, c, v: _poke(r, c, v), st.integers(0, 3), st.integers(0, 2), not_finite),
    st.builds(lambda r, c, v: _poke(r, c, v), st.integers(0, 3), st.integers(0, 1), st.floats(1e3 + 1, 1e300)),
)


def _poke(row: int, col: int, value: float) -> np.ndarray:
    p = np.zeros((4, 3))
    p[:, 0] = 0.3
    p[row, col] = value
    return p


@HYP
@given(bad_path)
def test_chain_refuses_bad_paths_before_whisking(wall_chain, path):
    cycle = wall_chain.simulator.cycle
    with pytest.raises(CansimError):
        wall_chain.whisk_path(path)
    with pytest.raises(CansimError):
        WhiskSchedule().whisk_poses(path)
    assert wall_chain.simulator.cycle == cycle  # nothing ran


@HYP
@given(st.tuples(finite, finite, finite), st.integers(0, 2), st.one_of(not_finite, st.floats(1e3 + 1, 1e300)))
def test_chain_refuses_bad_poses(wall_chain, pose, which, value):
    p = list(pose)
    if which < 2 or not math.isfinite(value):
        p[which] = value
        with pytest.raises(InvalidInputError):
            wall_chain.pose(*p)
    else:  # a huge yaw is an angle like any other
        p[2] = value
        wall_chain.pose(*p)


@HYP
@given(st.one_of(st.text(max_size=8), st.integers(), st.none()), st.one_of(not_finite, st.floats(max_value=0.0), st.floats(min_value=10.01, max_value=1e9)))
def test_chain_refuses_bad_settings(control, height):
    if control not in ("open_loop", "rcp"):
        with pytest.raises(InvalidInputError):
            PlanarChain(_flat_wall(0.4), control)
    with pytest.raises(InvalidInputError):
        PlanarChain(_flat_wall(0.4), "rcp", height_m=height)


@HYP
@given(st.one_of(st.text(max_size=10).filter(lambda s: s not in ("onset", "max_angle", "threshold")),
                 st.integers()), st.one_of(not_finite, st.floats(max_value=0.0, allow_nan=False)))
def test_contact_angle_params_refuse_bad_values(method, value):
    with pytest.raises(InvalidInputError):
        ContactAngleParams(method)
    with pytest.raises(InvalidInputError):
        ContactAngleParams("threshold", threshold_counts_per_s=value)
    if not math.isfinite(value) or value < 0:
        with pytest.raises(InvalidInputError):
            ContactAngleParams("max_angle", contact_threshold_counts=value)


@HYP
@given(st.integers(0, 17), st.sampled_from(["drop", "swap", "type", "rename"]))
def test_tactile_image_from_records_refuses_bad_cycles(wall_chain, i, fault):
    whisk = wall_chain.whisk(0.3, 0.5, 0.0)
    recs = list(whisk.records)
    if fault == "drop":
        del recs[i]
    elif fault == "swap":
        j = (i + 1) % 18
        recs[i], recs[j] = recs[j], recs[i]
    elif fault == "type":
        recs[i] = "not a record"
    else:
        recs = {r.module: r for r in recs}
        del recs[ARRAY.names[i]]
    with pytest.raises(InvalidInputError):
        tactile_image_from_records(ARRAY, recs, whisk.pose)
    with pytest.raises(InvalidInputError):
        contact_angles([object()])


def test_empty_or_missing_sessions_raise_typed_errors(tmp_path):
    with pytest.raises(CorruptFileError):
        tactile_images_from_recording(tmp_path / "nothing here")
    (tmp_path / "pose_log.csv").write_text("time_s,x_m,y_m,z_m,qx,qy,qz,qw,whisk_file\n", encoding="utf-8")
    with pytest.raises(InvalidInputError, match="no whisk cycle"):
        tactile_images_from_recording(tmp_path)


@HYP
@given(st.one_of(st.just([-1]), st.just([99]), st.just([1.5]), st.just([[1, 2]])))
def test_experience_id_plot_refuses_bad_kidnap_indices(kidnaps):
    with pytest.raises(InvalidInputError):
        plot_experience_ids(np.arange(10), kidnap_indices=kidnaps)


def test_experience_id_plot_lists_kidnaps_in_the_legend():
    import matplotlib.pyplot as plt

    fig = plot_experience_ids(np.r_[np.arange(20), np.arange(5)], [20, 21], 10, kidnap_indices=[12, 16])
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert labels.count("kidnapped") == 1
    assert len([line for line in fig.axes[0].lines if line.get_color() == "tab:purple"]) == 2
    plt.close(fig)
