"""The shared SLAM loop: package order, a 6-D composition with an SE(3) map, both local-view modes, backends."""

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cansim import Population
from cansim.errors import InvalidInputError
from cansim.frontends.ids import IdsFrontEnd
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from cansim.models.slam_loop import SlamLoop
from cansim.testing.worlds import LoopRoute, make_run
from maps.experience_map import ExperienceMap, MapConfig
from maps.metrics import absolute_trajectory_error
from maps.odometry import PlanarOdometry, SpatialOdometry
from maps.se3 import SE3Geometry


def test_maps_does_not_import_the_can_engine():
    code = "import sys, maps.experience_map, maps.se3; assert 'cansim.population' not in sys.modules and 'cansim' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_attractor_engine_does_not_import_the_map_package():
    # the attractor stage comes before the map stage: its modules load no ``maps``
    code = ("import sys, cansim.population, cansim.models.posecell_network, cansim.local_view, cansim.path_integration; "
            "bad = [m for m in sys.modules if m == 'maps' or m.startswith('maps.')]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_every_error_derives_from_the_one_root():
    import cansim.errors
    import whisker_io.errors
    import whisker_io.radial.errors

    root = whisker_io.errors.CansimError
    assert cansim.errors.CansimError is root and cansim.CansimError is root
    for mod in (cansim.errors, whisker_io.errors, whisker_io.radial.errors):
        for name in mod.__all__:
            cls = getattr(mod, name)
            if issubclass(cls, Warning):  # a warning category (ExtrapolationWarning) is no error: never raised
                continue
            assert issubclass(cls, root), name
    assert issubclass(whisker_io.radial.errors.ExtrapolationWarning, UserWarning)


# ------------------------------------------------------------ 6-D skeleton
STEPS, PLACES, STEP_M, CELL_M = 200, 20, 0.01, 0.05
V_TRUE = np.array([STEP_M, 0.0, 0.0])
W_TRUE = np.array([0.0, 0.0, 2 * math.pi / PLACES])


def skeleton(relax_passes):
    pc = Population.whisker6d(5, CELL_M, backend="numpy", dtype=np.float64)
    lv = LocalViewCells(pc.shape, LocalViewParams(mode="stored", inject_energy=0.3, recent_exclusion=0, rounding="round"))
    em = ExperienceMap(MapConfig(pc_shape=pc.shape, offset_axes=(), match_distance_cells=1.5, relax_passes=relax_passes,
                                 relax_budget=None), SE3Geometry())
    return SlamLoop(pc, lv, IdsFrontEnd(6), em, SpatialOdometry)


def drive(loop):
    """A circle of 20 places driven 10 times with odometry that over-reads speed by 8 % and turn rate by 3 %."""
    truth_p, truth_q = [np.zeros(3)], [Rotation.identity()]
    created, states = {}, []
    for k in range(STEPS):
        s = loop.step(SpatialOdometry(V_TRUE * 1.08, W_TRUE * 1.03, 1.0), k % PLACES)
        truth_p.append(truth_p[-1] + truth_q[-1].apply(V_TRUE))
        truth_q.append(truth_q[-1] * Rotation.from_rotvec(W_TRUE))
        created.setdefault(s.exp_id, k + 1)
        states.append(s)
    return truth_p, truth_q, created, states


def map_errors(loop, truth_p, truth_q, created):
    poses = loop.experience_map.poses
    q0 = Rotation.from_quat(poses[0, 3:])
    k0 = created[0]
    pe, re = [], []
    for e, k in created.items():
        est_p = q0.inv().apply(poses[e, :3] - poses[0, :3])
        true_p = truth_q[k0].inv().apply(truth_p[k] - truth_p[k0])
        pe.append(np.linalg.norm(est_p - true_p))
        est_q = q0.inv() * Rotation.from_quat(poses[e, 3:])
        re.append(((truth_q[k0].inv() * truth_q[k]).inv() * est_q).magnitude())
    return float(np.mean(pe)), float(np.mean(re))


@pytest.mark.slow
def test_six_dof_skeleton_closes_loops_and_relaxation_reduces_both_errors():
    raw = skeleton(0)
    out = drive(raw)
    relaxed = skeleton(10)
    out_r = drive(relaxed)
    assert sum(s.relocalised for s in out_r[3]) >= 20  # loop closures on the later laps
    assert relaxed.experience_map.n_experiences < STEPS / 2
    p0, r0 = map_errors(raw, *out[:3])
    p1, r1 = map_errors(relaxed, *out_r[:3])
    assert p0 > 0.01 and r0 > 0.05  # the biased odometry is visible in the unrelaxed map
    assert p1 < 0.7 * p0 and r1 < 0.7 * r0


def test_loop_rejects_the_wrong_odometry_kind_and_leaves_state():
    loop = skeleton(1)
    loop.step(SpatialOdometry(V_TRUE, W_TRUE, 1.0), 0)
    before = (loop.pose_cells.activity.tobytes(), loop.iteration, loop.n_views)
    with pytest.raises(InvalidInputError):
        loop.step(PlanarOdometry(0.1, 0.0, 1.0), 1)
    with pytest.raises(InvalidInputError):
        loop.step([math.nan, 0, 0], [0, 0, 0], 1.0, 1)
    with pytest.raises(InvalidInputError):
        loop.step(SpatialOdometry(V_TRUE, W_TRUE, 1.0), -3)
    assert (loop.pose_cells.activity.tobytes(), loop.iteration, loop.n_views) == before


@pytest.fixture
def validated_names(monkeypatch):
    """Names passed to the finite-value validators, from every module that holds them."""
    import whisker_io.validation as validation

    names: list[str] = []
    for fname in ("finite_scalar", "finite_vector"):
        original = getattr(validation, fname)

        def counting(value, *args, _original=original):
            names.append(args[-1])  # (value, name) or (value, n, name)
            return _original(value, *args)

        for module in list(sys.modules.values()):
            if getattr(module, fname, None) is original:
                monkeypatch.setattr(module, fname, counting)
    return names


@pytest.mark.parametrize("model", ["ratslam", "whisker", "skeleton"])
def test_a_loop_step_validates_its_odometry_once(validated_names, model):
    """v, omega and dt are checked once per step, when the odometry object is built
    (maps.odometry); the population's motion model trusts them (Population._step_validated),
    for the RatSLAM and WhiskerRatSLAM wiring as for a bare loop; with the same result
    as the public, checking ``step``. The public ``step`` still checks them itself."""
    from cansim.models.whisker_ratslam import WhiskerRatSLAM

    once = ["odometry v", "odometry omega", "odometry dt"]
    if model == "ratslam":
        loop = RatSLAM(pose_cells="population", frontend="ids", backend="numpy")
        args = [(0.3, 0.1, 1.0), (0.2, -0.05, 0.5)]
    else:
        loop = WhiskerRatSLAM(backend="numpy") if model == "whisker" else skeleton(1)
        args = [([0.01, 0.0, 0.002], [0.0, 0.05, 0.3], 1.0), ([0.0, 0.01, 0.0], [0.0, 0.0, 0.0], 0.5)]
    if hasattr(loop, "warm_up"):
        loop.warm_up()  # once, before the loop (it builds a scratch model); the steps are what is counted
    twin = Population(loop.pose_cells.axes, loop.pose_cells.params, dtype=loop.pose_cells.dtype, backend="numpy",
                      motion=loop.pose_cells.motion)
    twin.activity = loop.pose_cells.activity
    for k, a in enumerate(args):
        validated_names.clear()
        loop.step(*a, None)
        assert sorted(validated_names) == sorted(once), validated_names
        validated_names.clear()
        twin.step(*a)  # the public step checks v, omega, dt itself
        assert len(validated_names) >= 2 and not set(validated_names) & set(once)
        np.testing.assert_array_equal(loop.pose_cells.activity, twin.activity)


def test_the_parity_engine_takes_the_trusted_path_with_the_public_result(monkeypatch):
    """RatSLAM's C++-parity pose cells (PosecellNetwork) check odometry in their public
    ``step``; the loop, whose odometry is validated already, calls the trusted path."""
    import copy

    from cansim.models.posecell_network import PosecellNetwork

    loop = RatSLAM(RatSLAMConfig.openratslam(cell_size_m=0.25, frontend="ids"))
    twin = copy.deepcopy(loop.pose_cells)
    public_calls: list[tuple] = []
    original = PosecellNetwork.step

    def spy(self, *a, **k):
        public_calls.append(a)
        return original(self, *a, **k)

    monkeypatch.setattr(PosecellNetwork, "step", spy)
    for a in [(0.2, 0.05, 1.0), (0.1, -0.1, 0.5), (0.0, 0.3, 1.0)]:
        loop.step(*a, None)
        assert public_calls == []
        original(twin, *a)
        np.testing.assert_array_equal(loop.pose_cells.activity, twin.activity)
    with pytest.raises(InvalidInputError):
        twin.step(math.nan, 0.0, 1.0)  # the public step still checks


def test_a_bare_loop_cannot_be_saved(tmp_path):
    with pytest.raises(InvalidInputError, match="model class"):
        skeleton(1).save(tmp_path / "x.npz")


def test_uniform_population_rejects_omega():
    ring = Population.head_direction(36)
    with pytest.raises(InvalidInputError, match="omega"):
        ring.step(velocity=0.1, omega=0.2, dt=1.0)


# ------------------------------------------------------ RatSLAM LV modes
ROUTE = LoopRoute()


@pytest.mark.slow
@pytest.mark.parametrize("lv_mode,gain,ratio", [("stored", 0.05, 0.5), ("learnt", 0.5, 0.8)])
def test_both_local_view_modes_relocalise_the_synthetic_loop(lv_mode, gain, ratio):
    run = make_run(ROUTE, loops=(1,) * 4, seed=0)
    slam = RatSLAM(RatSLAMConfig(cell_size_m=0.05, xy_cells=21, inject_energy=gain, lv_mode=lv_mode))
    log = slam.run(run.vtrans, run.vrot, run.dt, run.view_ids)
    est = slam.experience_map.poses[log.exp_ids]
    assert log.relocalised.sum() > run.n_places  # re-localised on the later loops
    # map error below dead reckoning's (stored location: below half of it)
    assert absolute_trajectory_error(est, run.truth).rmse < ratio * absolute_trajectory_error(run.dead_reckoning, run.truth).rmse
    if lv_mode == "learnt":
        assert slam.local_view.weights.nnz > 0  # the explicit LV->PC weights were learnt


def test_learnt_mode_save_resume_equals_uninterrupted(tmp_path):
    run = make_run(ROUTE, loops=(1, 1), seed=2)
    cfg = RatSLAMConfig(cell_size_m=0.05, inject_energy=0.5, lv_mode="learnt")
    full = RatSLAM(cfg)
    full_log = full.run(run.vtrans, run.vrot, run.dt, run.view_ids)
    half = len(run) // 2
    first = RatSLAM(cfg)
    first.run(run.vtrans[:half], run.vrot[:half], run.dt, run.view_ids[:half])
    first.save(tmp_path / "m.npz")
    resumed = RatSLAM.load(tmp_path / "m.npz")
    log_b = resumed.run(run.vtrans[half:], run.vrot[half:], run.dt, run.view_ids[half:])
    assert np.array_equal(log_b.exp_ids, full_log.exp_ids[half:])
    assert resumed.experience_map.poses.tobytes() == full.experience_map.poses.tobytes()
    assert (resumed.local_view.weights != full.local_view.weights).nnz == 0


@pytest.mark.slow
def test_ratslam_numpy_and_numba_backends_build_the_same_map():
    run = make_run(ROUTE, loops=(1, 1, 1), seed=4)
    logs, maps_ = [], []
    for backend in ("numpy", "numba"):
        slam = RatSLAM(RatSLAMConfig(cell_size_m=0.05, inject_energy=0.05, backend=backend))
        logs.append(slam.run(run.vtrans, run.vrot, run.dt, run.view_ids))
        maps_.append(slam.experience_map)
    assert np.array_equal(logs[0].exp_ids, logs[1].exp_ids)
    assert np.array_equal(maps_[0].links[0], maps_[1].links[0])
    np.testing.assert_allclose(logs[0].best_pc, logs[1].best_pc, atol=1e-9)
    np.testing.assert_allclose(maps_[0].poses, maps_[1].poses, atol=1e-9)
