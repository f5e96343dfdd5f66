"""One whisk from an arm pose to RegionFeatures (whisker_io.sim.whisk_chain): a flat wall by hand,
the noise model, the no-observation whisk, the recorded path (record -> replay gives the direct
signal path's features bit for bit), the Ch.4 model from a skops file, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.distance import pdist
from scipy.spatial.transform import Rotation

from whisker_io.array.geometry import WhiskerArray
from whisker_io.contact.detection import DetectionParams
from whisker_io.errors import CansimError, ConfigError, CorruptFileError, InvalidInputError
from whisker_io.pose import Pose
from whisker_io.radial.features import RadialDataset
from whisker_io.radial.models import TABLE_4_1, SearchParams, fit_model
from whisker_io.radial.persistence import save_model
from whisker_io.records.recording import RecordingWriter
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.sim.objects import make_object
from whisker_io.sim.signals import SignalParams
from whisker_io.sim.sweep import ContactNoise
from whisker_io.sim.trajectories import object_trajectory
from whisker_io.hw.recorder import Recorder, replay_session
from whisker_io.sim.whisk_chain import RecordedChain, WhiskChain

ARRAY = WhiskerArray.thesis()
Y0 = 0.22  # wall plane, 18 mm in front of the rostral whisker bases (y = 0.2019 m, Fig 2.15)


def _wall(y0: float = Y0) -> trimesh.Trimesh:
    """A 2 m x 1 m x 2 m slab occupying y >= y0 in the end-effector frame at the identity pose."""
    m = trimesh.creation.box(extents=(2.0, 1.0, 2.0))
    m.apply_translation((0.0, y0 + 0.5, 0.0))
    return m


def _wall_contact_angles(y0: float = Y0) -> np.ndarray:
    """The tip is the most rostral point of a shaft, so it meets the wall first:
    p_y + L sin(theta_c) = y0 (base frames of Sec 4.1: protraction turns the shaft toward +y)."""
    return np.arcsin((y0 - ARRAY.positions_m[:, 1]) / ARRAY.lengths_m)


@pytest.fixture(scope="module")
def mug_poses(mug):
    return object_trajectory(mug, "A", n_loops=1)


# ------------------------------------------------------------- hand-computed: a flat wall
def test_flat_wall_sweep_path_by_hand():
    """All 18 tips touch the wall. Points: on the plane y = y0, a whisker length from their
    bases. PFH: coplanar pairs only, bins 13 + 27 b_d (see test_region_features). SDA:
    Eq 6.12-6.14 with the face normal (0, -1, 0) on the shaft frame at theta_c gives
    slope = -tan(theta_c): one value per row, hand-computed from the contact angle."""
    f = WhiskChain(_wall(), contact_noise=None).features(Pose.identity(), np.random.default_rng(0))
    assert f.n_contacts == 18 and f.is_observation and f.sda_mask.all()
    pts = f.contact_points_m
    np.testing.assert_allclose(pts[:, 1], Y0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(pts - ARRAY.positions_m, axis=1), ARRAY.lengths_m, atol=1e-3)
    d = pdist(pts)
    d = d[d <= 0.3]  # pairs within the PFH radius r = 0.3 m; the fanned-out caudal tips lie wider apart
    expected = np.zeros(81)
    expected[13], expected[40], expected[67] = np.mean(d < 0.1), np.mean((d >= 0.1) & (d < 0.2)), np.mean(d >= 0.2)
    np.testing.assert_allclose(f.pfh, expected, atol=1e-12)
    theta = _wall_contact_angles()
    np.testing.assert_allclose(f.sda, -np.tan(theta), atol=3e-3)  # contact angle to 1e-3 rad
    for row in (1, 2, 3):  # identical slopes within a row (same base height, same length)
        s = f.sda[[m.row == row for m in ARRAY.modules]]
        assert np.ptp(s) < 1e-6


def test_features_do_not_depend_on_where_the_scene_is():
    """Contact points are in the end-effector frame and the PFH viewpoint is its origin: moving
    the wall and the array together by any rigid motion leaves the features unchanged."""
    ref = WhiskChain(_wall(), contact_noise=None).features(Pose.identity(), np.random.default_rng(0))
    for seed in (1, 2):
        M = Pose.from_rotation(np.random.default_rng(seed).uniform(-1, 1, 3), Rotation.random(random_state=seed))
        mesh = _wall()
        mesh.apply_transform(M.matrix)
        f = WhiskChain(mesh, contact_noise=None).features(M, np.random.default_rng(0))
        np.testing.assert_allclose(f.contact_points_m, ref.contact_points_m, atol=1e-7)
        np.testing.assert_allclose(f.sda, ref.sda, atol=1e-4)
        np.testing.assert_array_equal(f.pfh, ref.pfh)


def test_tip_model_puts_contacts_at_the_tips():
    f = WhiskChain(_wall(), contact_model="tip", contact_noise=None).features(Pose.identity(),
                                                                              np.random.default_rng(0))
    np.testing.assert_allclose(np.linalg.norm(f.contact_points_m - ARRAY.positions_m, axis=1), ARRAY.lengths_m,
                               atol=1e-12)


def _wall_peak_counts() -> np.ndarray:
    """Hand-computed y-deflection peak of each wall contact (whisker_io.sim.signals): a tip
    contact (a = L) turned on to full protraction, D = G k(L) (theta_max - theta_c) with
    k(L) = 3 E I_b (1/L - 1/L'), clipped at the ADC limit; pure y since n_x = 0."""
    p = SignalParams()
    L = ARRAY.lengths_m
    k = 3.0 * p.youngs_modulus_pa * math.pi * p.base_radius_m**4 / 4.0 * (1.0 / L - (p.base_radius_m - p.tip_radius_m) / (p.base_radius_m * L))
    return np.minimum(p.adc_max_counts / p.full_scale_moment_nm * k * (ARRAY.protraction_rad - _wall_contact_angles()),
                      p.adc_max_counts)


def test_flat_wall_signal_path_by_hand():
    """Signal path, same wall: the detected onset angles are the sweep's contact angles (to
    the detector's few samples of a 1-Hz whisk), so the tip contacts sit on the wall. The wall's
    normal lies along the array axis, perpendicular to every whisk axis z (the sensor x-axis):
    n_x = 0, the deflection is pure y (see whisker_io.sim.signals) and no x-y gradient exists,
    so the SDA is all masked. The detector's thresholds are calibrated to the simulated sensor,
    20 x the 4-count noise std (about 80 counts): every tip contact (hand-computed peaks 425-1279
    counts) is detected."""
    chain = WhiskChain(_wall(), signals=True, contact_model="tip", contact_noise=None)
    assert chain.contact_threshold_counts == pytest.approx(20 * SignalParams().noise_std_counts, rel=0.05)
    cw = chain.whisk(Pose.identity(), np.random.default_rng(0))
    f = cw.features
    detected = np.array([d is not None for d in cw.detections])
    assert _wall_peak_counts().min() > 4 * chain.contact_threshold_counts and detected.all()
    assert f.n_contacts == 18 and not f.sda_mask.any() and not f.sda.any()
    onset = np.array([d.contact_angle_rad for d in cw.detections])
    np.testing.assert_allclose(onset, _wall_contact_angles(), atol=math.radians(1.0))
    np.testing.assert_allclose(f.contact_points_m[:, 1], Y0, atol=2e-3)


def test_thesis_500_count_detection_misses_the_soft_tip_contacts():
    """With the thesis' 500-count prominence (DetectionParams(), the real sensor's) a whisker is
    detected exactly when its hand-computed peak exceeds 500 counts: the 160-mm tips (425
    counts) are missed, the 60- and 100-mm ones (1279, 654) found."""
    cw = WhiskChain(_wall(), signals=True, contact_model="tip", contact_noise=None,
                    detection_params=DetectionParams()).whisk(Pose.identity(), np.random.default_rng(0))
    detected = np.array([d is not None for d in cw.detections])
    peak = _wall_peak_counts()
    assert np.all(np.abs(peak - 500.0) > 50.0)  # no whisker near the threshold
    np.testing.assert_array_equal(detected, peak > 500.0)
    assert not detected.all() and detected.any()


# ------------------------------------------------------------- noise
def test_noise_model_statistics_on_the_wall():
    """Registration probability 0.98 and slope noise N(0, 0.33) (Sec 6.1.3.1.2), recovered
    against the noise-free wall; the radial noise keeps every point on its shaft."""
    chain = WhiskChain(_wall(), contact_noise=ContactNoise())
    rng = np.random.default_rng(42)
    truth = -np.tan(_wall_contact_angles())
    kept, slope_err, n = 0, [], 300
    for _ in range(n):
        f = chain.features(Pose.identity(), rng)
        kept += f.n_contacts
        slope_err.extend((f.sda - truth)[f.sda_mask])
        r = np.linalg.norm(f.contact_points_m[:, None, :] - ARRAY.positions_m[None], axis=2)
        assert np.all(r.min(axis=1) <= ARRAY.lengths_m.max() + 1e-9)
    p = kept / (18 * n)
    assert abs(p - 0.98) < 3 * math.sqrt(0.98 * 0.02 / (18 * n))
    assert np.std(slope_err) == pytest.approx(0.33, rel=0.05) and abs(np.mean(slope_err)) < 0.02


def test_seeded_and_reproducible(mug, mug_poses):
    chain = WhiskChain(mug)
    a = [chain.features(p, np.random.default_rng(3)) for p in mug_poses[:4]]
    b = [chain.features(p, np.random.default_rng(3)) for p in mug_poses[:4]]
    assert a == b
    c = [chain.features(p, np.random.default_rng(4)) for p in mug_poses[:4]]
    assert a != c


# ------------------------------------------------------------- no observation
@pytest.mark.parametrize("signals", [False, True])
def test_far_from_the_object_is_no_observation(mug, signals):
    far = Pose([2.0, 2.0, 2.0])
    f = WhiskChain(mug, signals=signals, contact_model="tip").features(far, np.random.default_rng(0))
    assert f.n_contacts == 0 and not f.is_observation and not f.pfh.any() and not f.sda_mask.any()


def test_a_trajectory_gives_mostly_observations(mug, mug_poses):
    chain = WhiskChain(mug)
    rng = np.random.default_rng(0)
    obs = [chain.features(p, rng).is_observation for p in mug_poses]
    assert np.mean(obs) > 0.8


# ------------------------------------------------------------- the recorded path
def test_recorded_session_replays_to_the_same_features(tmp_path, mug, mug_poses):
    chain = WhiskChain(mug, signals=True, contact_model="tip", contact_noise=None)
    rng = np.random.default_rng(11)
    direct = []
    with RecordingWriter(tmp_path) as writer:
        for i, pose in enumerate(mug_poses[4:10]):
            cw = chain.whisk(pose, rng)
            cw.write(writer, time_s=float(i))
            direct.append(cw)
    # the hardware recorder's replay, with the detector the simulated sensor was calibrated for
    replayed = replay_session(tmp_path, RecordedChain(detection_params=chain.detection_params))
    assert len(replayed) == len(direct)
    assert sum(cw.features.is_observation for cw in direct) >= 2  # the check is not vacuous
    for cw, (pose, feats) in zip(direct, replayed):
        assert pose == cw.pose
        assert feats == cw.features
        assert feats == RecordedChain(detection_params=chain.detection_params).features(cw.records)


def test_live_recorder_pipeline_gives_the_direct_features(tmp_path, mug, mug_poses):
    """The chain as the pipeline of a live Recorder: each cycle's features once it is on disk."""
    chain = WhiskChain(mug, signals=True, contact_model="tip", contact_noise=None)
    rng = np.random.default_rng(2)
    from whisker_io.hw.arm import ArmState

    with Recorder(tmp_path, pipeline=RecordedChain(detection_params=chain.detection_params)) as rec:
        direct = []
        for i, pose in enumerate(mug_poses[5:8]):
            cw = chain.whisk(pose, rng)
            rec.record(ArmState(float(i), pose, np.zeros(6), np.zeros(6)), list(cw.records))
            direct.append(cw)
    assert [f for _, f in rec.results] == [cw.features for cw in direct]
    assert [p for p, _ in rec.results] == [cw.pose for cw in direct]


@pytest.fixture(scope="module")
def svr_file(tmp_path_factory):
    """A small SVR on the Table 4.1 svr10 features, fitted on toy data and saved with skops."""
    rng = np.random.default_rng(0)
    X = rng.uniform(0.1, 1.0, (120, 7))
    X[:, 6] = rng.choice([0.06, 0.1, 0.16], 120)
    model = fit_model("svr10", *TABLE_4_1["svr10"], RadialDataset(X, X[:, 6] * X[:, 0], name="toy"),
                      SearchParams().quick())
    return save_model(model, tmp_path_factory.mktemp("models") / "svr10.skops")


def test_svr_model_from_a_skops_file(tmp_path, mug, mug_poses, svr_file):
    chain = WhiskChain(mug, signals=True, contact_model="svr", radial_model=svr_file, contact_noise=None)
    rng = np.random.default_rng(5)
    direct = []
    with RecordingWriter(tmp_path) as writer:
        for i, pose in enumerate(mug_poses[5:9]):
            cw = chain.whisk(pose, rng)
            cw.write(writer, float(i))
            direct.append(cw.features)
    for f in direct:  # estimates clipped to the shaft: every point within its whisker's reach
        r = np.linalg.norm(f.contact_points_m[:, None, :] - ARRAY.positions_m[None], axis=2)
        assert np.all(r.min(axis=1) <= ARRAY.lengths_m.max() + 1e-9)
    det = chain.detection_params
    replayed = [feats for _, feats in replay_session(tmp_path, RecordedChain(contact_model="svr", radial_model=svr_file,
                                                                             detection_params=det))]
    assert replayed == direct
    tip = [feats for _, feats in replay_session(tmp_path, RecordedChain(detection_params=det))]
    assert any(a != b for a, b in zip(tip, direct) if a.n_contacts)  # the model changes the points


# ------------------------------------------------------------- bad input
def test_bad_input_raises_typed_errors(tmp_path, mug, svr_file):
    chain = WhiskChain(mug)
    rng = np.random.default_rng(0)
    nan_pose = np.eye(4)
    nan_pose[1, 3] = np.nan
    with pytest.raises(InvalidInputError):
        chain.features(nan_pose, rng)
    with pytest.raises(InvalidInputError, match="norm"):
        chain.features(([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 3.0]), rng)
    with pytest.raises(InvalidInputError, match="Generator"):
        chain.features(Pose.identity(), 0)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="signals"):
        WhiskChain(mug, contact_model="svr", radial_model=svr_file)
    with pytest.raises(ConfigError, match="radial_model"):
        WhiskChain(mug, signals=True, contact_model="svr")
    with pytest.raises(ConfigError, match="only used"):
        WhiskChain(mug, contact_model="tip", radial_model=svr_file)
    with pytest.raises(ConfigError, match="unknown"):
        WhiskChain(mug, contact_model="middle")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        WhiskChain("mug")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        WhiskChain(mug, contact_noise=0.25)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        WhiskChain(mug, signals=True, contact_model="svr", radial_model=tmp_path / "missing.skops")
    with pytest.raises(InvalidInputError, match="sweep-path"):
        chain.whisk(Pose.identity(), rng).write(None, 0.0)  # type: ignore[arg-type]
    recs = [WhiskRecord(name, np.zeros(10), np.zeros(10), np.zeros(10)) for name in ARRAY.names]
    recorded = RecordedChain()
    with pytest.raises(InvalidInputError, match="array order"):
        recorded.features(recs[::-1])
    with pytest.raises(InvalidInputError, match="array order"):
        recorded.features(recs[:17])
    with pytest.raises(ConfigError, match="not available"):
        RecordedChain(contact_model="truth")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="radial_model"):
        RecordedChain(contact_model="svr")
    with pytest.raises(InvalidInputError, match="Generator"):
        RecordedChain(contact_noise=ContactNoise()).features(recs)
    with pytest.raises(InvalidInputError, match="ReplayedCycle"):
        recorded(recs)  # type: ignore[arg-type]
    with pytest.raises(CorruptFileError):
        replay_session(tmp_path / "no-session", recorded)


# ------------------------------------------------------------- properties
@settings(max_examples=40, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-0.5, 0.5), st.floats(0.0, 0.15), st.integers(0, 2**32 - 1))
def test_any_pose_around_the_mug_gives_valid_features(azimuth, tilt, gap, seed):
    """Poses facing the mug's axis from every side and height: always valid features (never an
    error), points within reach of the array, observation exactly when >= 3 contacts."""
    mug = make_object("mug")
    axis = np.array([math.cos(azimuth) * math.cos(tilt), math.sin(azimuth) * math.cos(tilt), math.sin(tilt)])
    target = np.array([0.0, 0.0, 0.175])
    y = -axis
    z = np.cross(np.cross(y, [0.0, 0.0, 1.0]), y)
    z /= np.linalg.norm(z)
    R = np.column_stack([np.cross(y, z), y, z])
    pose = Pose.from_rotation(target + axis * (0.085 + 0.217 + gap), Rotation.from_matrix(R))
    f = WhiskChain(mug).features(pose, np.random.default_rng(seed))
    assert f.is_observation == (f.n_contacts >= 3)
    total = f.pfh.sum()
    assert (total == pytest.approx(1.0)) if f.is_observation else total == 0.0
    reach = np.linalg.norm(ARRAY.positions_m, axis=1).max() + ARRAY.lengths_m.max()
    assert np.all(np.linalg.norm(f.contact_points_m, axis=1) <= reach)


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, st.sampled_from([(4, 4), (7,), (6,), (3,)]),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)))
def test_bad_poses_are_typed_errors_or_valid(value):
    chain = _WALL_CHAIN
    try:
        f = chain.features(value, np.random.default_rng(0))
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    assert np.all(np.isfinite(f.contact_points_m)) and np.all(np.isfinite(f.pfh))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 3000.0), st.floats(-3000.0, 3000.0))
def test_records_with_arbitrary_deflections_give_valid_features(seed, y_amp, x_amp):
    """A cycle of 18 records with random ramps of deflection (any amplitude, either sign): the
    recorded path returns valid features, never an error."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000)
    angle = np.deg2rad(-50 + 50 * (1 - np.cos(2 * np.pi * t / 2000)))
    recs = []
    for name in ARRAY.names:
        on = int(rng.integers(100, 900))
        ramp = np.clip((t - on) / 300.0, 0.0, 1.0) * (t < 1500)
        recs.append(WhiskRecord(name, angle, np.rint(x_amp * ramp + rng.normal(0, 4, 2000)),
                                np.rint(y_amp * ramp + rng.normal(0, 4, 2000))))
    f = RecordedChain().features(recs)
    assert f.is_observation == (f.n_contacts >= 3)
    assert np.all(np.isfinite(f.sda)) and not f.sda[~f.sda_mask].any()


_WALL_CHAIN = WhiskChain(_wall(), contact_noise=None)


def test_a_session_of_another_array_says_which_modules_it_holds_and_what_to_do():
    from types import MappingProxyType

    from whisker_io.records.recording import ReplayedCycle
    from whisker_io.records.whisk_record import PoseEntry, WhiskRecord

    records = {f"W{k:02d}": WhiskRecord(f"W{k:02d}", np.zeros(4), np.zeros(4), np.zeros(4), cycle=0) for k in range(12)}
    cycle = ReplayedCycle(entry=PoseEntry(0.0, ([0.4, 0.0, 0.2], [0, 0, 0, 1]), "whisk_000000"),
                          records=MappingProxyType(records))
    with pytest.raises(InvalidInputError) as exc:
        RecordedChain()(cycle)
    text = str(exc.value)
    assert "holds modules ['W00'," in text and "the chain's array has 18" in text and "another array" in text
