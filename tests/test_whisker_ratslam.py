"""WhiskerRatSLAM (Ch.5, Alg 2) on synthetic regions: 6-D path integration, loop closure, persistence, backends, bad input."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from cansim import Population
from cansim.errors import ConfigError, InvalidInputError, ShapeError, UnknownFieldError
from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig
from maps.localisation import map_pose_errors, relocalisation_errors
from maps.odometry import SpatialOdometry

PLACES = 12
STEP_M = 0.1


def places(seed=0, aliased=False):
    """One distinct (pfh, sda) region per place around a loop, plus whisk noise.

    ``aliased``: the places of the second half repeat those of the first (a symmetric object:
    place k and k + PLACES/2 are opposite on the circle, 180 deg and 2 r apart, and feel the same).
    """
    rng = np.random.default_rng(seed)
    pfh = rng.dirichlet(np.full(81, 0.3), PLACES)
    sda = rng.normal(0, 1, (PLACES, 18))
    if aliased:
        pfh[PLACES // 2:], sda[PLACES // 2:] = pfh[: PLACES // 2], sda[: PLACES // 2]
    return pfh, sda


def observe(pfh, sda, k, rng, noise=0.02):
    f = np.abs(pfh[k] + rng.normal(0, noise / 81, 81))
    return (f / f.sum(), sda[k] + rng.normal(0, noise, 18))


def loop_run(slam, laps=4, seed=1, bias=(1.06, 1.04), aliased=False):
    """A planar circle of PLACES whisks (body x forward, yaw turning), odometry over-reading by ``bias``."""
    pfh, sda = places(aliased=aliased)
    rng = np.random.default_rng(seed)
    v, w = np.array([STEP_M, 0, 0]), np.array([0, 0, 2 * math.pi / PLACES])
    p, q = [np.zeros(3)], [Rotation.identity()]
    states = []
    for k in range(laps * PLACES):
        states.append(slam.step(SpatialOdometry(v * bias[0], w * bias[1], 1.0), observe(pfh, sda, k % PLACES, rng)))
        p.append(p[-1] + q[-1].apply(v))
        q.append(q[-1] * Rotation.from_rotvec(w))
    truth_p = np.array(p[1:])
    truth_q = np.array([r.as_quat() for r in q[1:]])
    return states, truth_p, truth_q


def test_six_dof_closed_translation_loop_returns_within_a_quarter_cell():
    pop = Population.whisker6d(backend="numpy", dtype=np.float64)
    for _ in range(5):
        pop.step()
    start = pop.decode()
    cell = pop.axes[0].step
    for axis in range(3):
        v = np.zeros(3)
        v[axis] = 0.3 * cell
        for sign in (1, -1):
            for _ in range(5):
                pop.step(sign * v, np.zeros(3), 1.0)
    d = (pop.decode() - start + 2.5) % 5 - 2.5
    assert np.all(np.abs(d) < 0.25)


@pytest.mark.parametrize("axis", [3, 4, 5])
def test_a_whole_cell_of_rotation_is_an_exact_roll(axis):
    pop = Population.whisker6d(backend="numpy", dtype=np.float64)
    rng = np.random.default_rng(axis)
    pop.activity = rng.random(pop.shape)
    before = pop.activity
    w = np.zeros(3)
    w[axis - 3] = pop.axes[axis].step  # one cell per second
    pop.integrate(np.zeros(3), w, 1.0)
    np.testing.assert_array_equal(pop.activity, np.roll(before, 1, axis=axis))


def test_decoding_on_five_cells_counts_no_cell_twice():
    pop = Population.whisker6d(backend="numpy", dtype=np.float64)
    a = np.zeros(pop.shape)
    a[0, 0, 0, 0, 0, 0] = 1.0
    a[4, 0, 0, 0, 0, 0] = 1.0  # the neighbour across the wrap; a window of +-3 would count cells twice
    pop.activity = a
    x = pop.decode()[0]
    assert x == pytest.approx(4.5, abs=1e-9) or x == pytest.approx(-0.5 % 5, abs=1e-9)


@pytest.mark.slow
def test_loop_closure_relocalises_and_map_beats_dead_reckoning():
    slam = WhiskerRatSLAM(backend="numba", cell_size_m=STEP_M)
    states, tp, tq = loop_run(slam)
    exp_ids = np.array([s.exp_id for s in states])
    reloc = np.array([s.relocalised for s in states])
    assert reloc[PLACES:].sum() >= PLACES  # re-localises on the later laps
    assert slam.object_map.n_experiences <= 2 * PLACES
    b = relocalisation_errors(exp_ids, reloc, tp, tq)
    assert b.median_position_m < STEP_M and b.median_rotation_deg < 30.0
    # the map (relaxed, loop closures) against dead reckoning of the same odometry
    a = map_pose_errors(exp_ids, slam.object_map.poses, tp, tq)
    dr = WhiskerRatSLAM(backend="numba", cell_size_m=STEP_M, relax_passes=0)
    states_dr, _, _ = loop_run(dr)
    a_dr = map_pose_errors(np.array([s.exp_id for s in states_dr]), dr.object_map.poses, tp, tq)
    assert np.mean(a.position_m) < np.mean(a_dr.position_m)
    assert np.array_equal(slam.object_map.history, exp_ids)


def test_save_resume_equals_uninterrupted(tmp_path):
    cfg = WhiskerRatSLAMConfig(backend="numpy", cell_size_m=STEP_M)
    full = WhiskerRatSLAM(cfg)
    all_states, _, _ = loop_run(full, laps=2)
    first = WhiskerRatSLAM(cfg)
    pfh, sda = places()
    rng = np.random.default_rng(1)
    v, w = np.array([STEP_M, 0, 0]) * 1.06, np.array([0, 0, 2 * math.pi / PLACES]) * 1.04
    obs = [observe(pfh, sda, k % PLACES, rng) for k in range(2 * PLACES)]
    half = PLACES + 3
    for k in range(half):
        first.step(SpatialOdometry(v, w, 1.0), obs[k])
    first.save(tmp_path / "w.npz")
    resumed = WhiskerRatSLAM.load(tmp_path / "w.npz")
    rest = [resumed.step(SpatialOdometry(v, w, 1.0), obs[k]) for k in range(half, 2 * PLACES)]
    assert [s.exp_id for s in rest] == [s.exp_id for s in all_states[half:]]
    assert resumed.object_map.poses.tobytes() == full.object_map.poses.tobytes()
    assert resumed.pose_cells.activity.tobytes() == full.pose_cells.activity.tobytes()
    assert np.array_equal(resumed.object_map.history, full.object_map.history)


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["thesis", "mapping"])
def test_numpy_and_numba_give_the_same_experiences_and_links(preset):
    runs = []
    for backend in ("numpy", "numba"):
        slam = WhiskerRatSLAM(getattr(WhiskerRatSLAMConfig, preset)(backend=backend, cell_size_m=STEP_M))
        states, _, _ = loop_run(slam, laps=9, aliased=preset == "mapping")  # 108 whisks
        runs.append(([s.exp_id for s in states], slam.object_map.links[0]))
    assert runs[0][0] == runs[1][0]
    assert np.array_equal(runs[0][1], runs[1][1])


def test_whisk_without_observation_is_odometry_only():
    slam = WhiskerRatSLAM(backend="numpy")
    s = slam.step(SpatialOdometry([0.05, 0, 0], [0, 0, 0.1], 1.0), None)
    assert s.exp_id == -1 and s.view_id == -1 and slam.n_views == 0

    class FewContacts:
        pfh = np.full(81, 1 / 81)
        sda = np.zeros(18)
        is_observation = False

    s = slam.step(SpatialOdometry([0.05, 0, 0], [0, 0, 0.1], 1.0), FewContacts())
    assert s.view_id == -1 and slam.n_views == 0


def test_bad_config_is_named():
    for kw, key in (({"grid_cells": 2}, "grid_cells"), ({"cell_size_m": 0.0}, "cell_size_m"), ({"lv_mode": "x"}, "lv_mode")):
        with pytest.raises(ConfigError, match=key):
            WhiskerRatSLAMConfig(**kw)
    with pytest.raises(UnknownFieldError, match="WhiskerRatSLAMConfig has no field .pc_dim_xy."):
        WhiskerRatSLAM(pc_dim_xy=3)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["nan_v", "inf_w", "zero_dt", "neg_dt", "short_v", "pfh_shape", "sda_len", "nan_sda", "arity"]))
def test_bad_input_raises_typed_error_and_leaves_state_unchanged(kind):
    slam = WhiskerRatSLAM(backend="numpy", cell_size_m=STEP_M)
    pfh, sda = places()
    slam.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.5], 1.0), (pfh[0], sda[0]))
    before = (slam.pose_cells.activity.tobytes(), slam.iteration, slam.n_views, slam.object_map.poses.tobytes(),
              slam.local_view.decay.tobytes(), len(slam.object_map.history))
    good_o, good_f = ([0.1, 0, 0], [0, 0, 0.5], 1.0), (pfh[1], sda[1])
    args = {
        "nan_v": ([math.nan, 0, 0], [0, 0, 0.5], 1.0, good_f),
        "inf_w": ([0.1, 0, 0], [0, math.inf, 0.5], 1.0, good_f),
        "zero_dt": ([0.1, 0, 0], [0, 0, 0.5], 0.0, good_f),
        "neg_dt": ([0.1, 0, 0], [0, 0, 0.5], -1.0, good_f),
        "short_v": ([0.1, 0], [0, 0, 0.5], 1.0, good_f),
        "pfh_shape": (*good_o, (pfh[1][:80], sda[1])),
        "sda_len": (*good_o, (pfh[1], sda[1][:17])),
        "nan_sda": (*good_o, (pfh[1], np.full(18, math.nan))),
        "arity": good_o,
    }[kind]
    with pytest.raises((InvalidInputError, ShapeError)):
        slam.step(*args)
    after = (slam.pose_cells.activity.tobytes(), slam.iteration, slam.n_views, slam.object_map.poses.tobytes(),
             slam.local_view.decay.tobytes(), len(slam.object_map.history))
    assert after == before


def test_library_joins_models_and_relocalises_to_the_right_object():
    def model_for(seed):
        m = WhiskerRatSLAM(backend="numpy", cell_size_m=STEP_M)
        pfh, sda = places(seed)
        rng = np.random.default_rng(seed)
        v, w = np.array([STEP_M, 0, 0]), np.array([0, 0, 2 * math.pi / PLACES])
        for k in range(PLACES):
            m.step(SpatialOdometry(v, w, 1.0), observe(pfh, sda, k, rng))
        return m, pfh, sda

    (a, _pa, _sa), (b, pb, sb) = model_for(3), model_for(4)
    lib_model, lib = WhiskerRatSLAM.library([a, b], ["a", "b"])
    assert lib_model.n_views == a.n_views + b.n_views
    assert lib_model.object_map.n_experiences == a.object_map.n_experiences + b.object_map.n_experiences
    assert lib.exp_object.tolist() == [0] * a.object_map.n_experiences + [1] * b.object_map.n_experiences
    np.testing.assert_array_equal(lib_model.frontend.pfh[a.n_views:], b.frontend.pfh)
    # exploring object b from scratch: its regions match b's stored ones
    rng = np.random.default_rng(9)
    v, w = np.array([STEP_M, 0, 0]), np.array([0, 0, 2 * math.pi / PLACES])
    hits = []
    for k in range(PLACES):
        s = lib_model.step(SpatialOdometry(v, w, 1.0), observe(pb, sb, k, rng))
        if not s.new_view:
            hits.append(s.view_id >= a.n_views)
    assert len(hits) >= PLACES // 2 and all(hits)
    with pytest.raises(InvalidInputError):
        WhiskerRatSLAM.library([a], ["a", "b"])
    # maps of another grid or region matching mean other things: refused, naming the field
    other_grid = WhiskerRatSLAM(replace(a.config, angle_cells=a.config.grid_cells + 2))
    with pytest.raises(InvalidInputError, match="'c' differs from the first configuration in angle_cells"):
        WhiskerRatSLAM.library([a, other_grid], ["a", "c"])
    other_front = WhiskerRatSLAM(replace(a.config, frontend=replace(a.config.frontend, pfh_threshold=5.0)))
    with pytest.raises(InvalidInputError, match="in frontend"):
        WhiskerRatSLAM.library([a, other_front], ["a", "c"])
    with pytest.raises(InvalidInputError, match="given configuration in frontend"):
        WhiskerRatSLAM.library([a, b], ["a", "b"], replace(a.config, frontend=replace(a.config.frontend, pfh_threshold=5.0)))
    # another cell size is allowed: the Ch.5 study maps each object at its own step
    WhiskerRatSLAM.library([a, b], ["a", "b"], replace(a.config, cell_size_m=2 * a.config.cell_size_m))
    with pytest.raises(InvalidInputError, match="two names"):
        WhiskerRatSLAM.library([a, a], ["a", "b"])


# ------------------------------------------------------------------ pose-consistent matching
def test_pose_prior_rejects_aliased_places_the_thesis_model_relocalises_to():
    """Opposite places of a symmetric loop feel the same: Eq 5.5 alone re-localises half a turn away."""
    errors = {}
    for preset in ("thesis", "mapping"):
        slam = WhiskerRatSLAM(getattr(WhiskerRatSLAMConfig, preset)(backend="numba", cell_size_m=STEP_M))
        states, tp, tq = loop_run(slam, aliased=True)
        reloc = np.array([s.relocalised for s in states])
        assert reloc[PLACES:].sum() >= PLACES  # both re-localise on the later laps
        errors[preset] = relocalisation_errors(np.array([s.exp_id for s in states]), reloc, tp, tq).position_m
    diameter = STEP_M / math.sin(math.pi / PLACES)  # 2 r of the 12-gon with 0.1-m sides: 0.386 m
    assert np.isclose(errors["thesis"].max(), diameter, atol=1e-9)
    assert errors["mapping"].max() < 1e-9  # every re-localisation is the exact revisit


def test_object_map_pose_queries_by_hand():
    om = WhiskerRatSLAM(backend="numpy").object_map
    p = om.predicted_pose(SpatialOdometry([0.1, 0, 0], [0, 0, math.pi / 2], 1.0))  # empty map: from the identity
    np.testing.assert_allclose(p, [0.1, 0, 0, 0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)], atol=1e-12)
    slam = WhiskerRatSLAM(backend="numpy", cell_size_m=STEP_M)
    pfh, sda = places()
    slam.step(SpatialOdometry([0, 0, 0], [0, 0, 0], 1.0), (pfh[0], sda[0]))  # experience 0 at the identity
    om = slam.object_map
    acc = om.accumulator
    p = om.predicted_pose(SpatialOdometry([0.1, 0, 0], [0, 0, math.pi / 2], 1.0))
    assert om.accumulator == acc  # the map is unchanged
    np.testing.assert_allclose(p[:3], [0.1, 0, 0], atol=1e-12)
    dp, dr = om.pose_distances([0.3, 0.4, 0, 0, 0, math.sin(math.pi / 6), math.cos(math.pi / 6)])
    np.testing.assert_allclose(dp, [0.5])
    np.testing.assert_allclose(dr, [math.pi / 3])


def test_creation_iterations_and_last_relocalisation_follow_the_run_and_survive_save_load(tmp_path):
    slam = WhiskerRatSLAM(backend="numba", cell_size_m=STEP_M)
    states, _, _ = loop_run(slam, laps=2)
    exp_ids = [s.exp_id for s in states]
    first = {e: exp_ids.index(e) for e in set(exp_ids)}
    om = slam.object_map
    assert om.creation_iterations.tolist() == [first[e] for e in range(om.n_experiences)]
    reloc = [k for k, s in enumerate(states) if s.relocalised]
    assert reloc and om.last_relocalisation == reloc[-1] and om.n_recorded == len(states)
    slam.save(tmp_path / "m.npz")
    back = WhiskerRatSLAM.load(tmp_path / "m.npz").object_map
    assert back.creation_iterations.tolist() == om.creation_iterations.tolist()
    assert back.last_relocalisation == om.last_relocalisation


def test_save_resume_with_the_pose_prior_equals_uninterrupted(tmp_path):
    cfg = WhiskerRatSLAMConfig.mapping(backend="numpy", cell_size_m=STEP_M)
    full = WhiskerRatSLAM(cfg)
    all_states, _, _ = loop_run(full, laps=2, aliased=True)
    pfh, sda = places(aliased=True)
    rng = np.random.default_rng(1)
    v, w = np.array([STEP_M, 0, 0]) * 1.06, np.array([0, 0, 2 * math.pi / PLACES]) * 1.04
    obs = [observe(pfh, sda, k % PLACES, rng) for k in range(2 * PLACES)]
    first = WhiskerRatSLAM(cfg)
    half = PLACES + 3
    for k in range(half):
        first.step(SpatialOdometry(v, w, 1.0), obs[k])
    first.save(tmp_path / "w.npz")
    resumed = WhiskerRatSLAM.load(tmp_path / "w.npz")
    assert resumed.config == cfg
    rest = [resumed.step(SpatialOdometry(v, w, 1.0), obs[k]) for k in range(half, 2 * PLACES)]
    assert [(s.exp_id, s.view_id, s.relocalised) for s in rest] == [(s.exp_id, s.view_id, s.relocalised) for s in all_states[half:]]
    assert resumed.object_map.poses.tobytes() == full.object_map.poses.tobytes()


def test_the_library_has_no_pose_prior():
    m = WhiskerRatSLAM(WhiskerRatSLAMConfig.mapping(backend="numpy", cell_size_m=STEP_M))
    pfh, sda = places()
    m.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.5], 1.0), (pfh[0], sda[0]))
    lib_model, _ = WhiskerRatSLAM.library([m], ["a"])
    assert not lib_model.config.pose_prior and lib_model.frontend.pose_prior is None
    assert WhiskerRatSLAMConfig.thesis() == WhiskerRatSLAMConfig() and not WhiskerRatSLAMConfig().pose_prior


_BAD_POSE_CONFIG = [
    {"pose_gate_m": 0.3}, {"pose_gate_deg": 60.0}, {"pose_gate_m": 0.0, "pose_gate_deg": 60.0},
    {"pose_gate_m": 0.3, "pose_gate_deg": 200.0}, {"pose_gate_m": math.nan, "pose_gate_deg": 60.0},
    {"pose_gate_m": True, "pose_gate_deg": 60.0}, {"pose_gate_growth_m": 0.04, "pose_gate_growth_deg": 12.0},
    {"pose_gate_m": 0.3, "pose_gate_deg": 60.0, "pose_gate_growth_m": 0.04},
    {"pose_weight": -1.0}, {"pose_weight": math.inf}, {"pose_weight": "2"},
]


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(_BAD_POSE_CONFIG))
def test_bad_pose_prior_config_is_named(kw):
    with pytest.raises(ConfigError, match="pose_"):
        WhiskerRatSLAMConfig(**kw)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["nan", "short", "non_unit", "text", "inf"]))
def test_bad_pose_queries_raise_typed_errors(kind):
    slam = WhiskerRatSLAM(backend="numpy", cell_size_m=STEP_M)
    pfh, sda = places()
    slam.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.5], 1.0), (pfh[0], sda[0]))
    om = slam.object_map
    pose = {"nan": [math.nan, 0, 0, 0, 0, 0, 1], "short": [0, 0, 0, 0, 0, 1], "non_unit": [0, 0, 0, 0, 0, 0, 2],
            "text": ["a"] * 7, "inf": [0, 0, math.inf, 0, 0, 0, 1]}[kind]
    with pytest.raises((InvalidInputError, ShapeError)):
        om.pose_distances(pose)
    with pytest.raises((InvalidInputError, ShapeError)):
        om.predicted_pose(pose[:3], [0, 0, 0], 1.0) if kind in ("nan", "text", "inf") else om.predicted_pose(pose)


def test_library_map_takes_the_exploring_configuration():
    """The appended map runs with the exploring model's map parameters (its match distance), the grid checked."""
    m = WhiskerRatSLAM(backend="numpy", cell_size_m=STEP_M)
    pfh, sda = places(5)
    rng = np.random.default_rng(5)
    for k in range(PLACES):
        m.step(SpatialOdometry(np.array([STEP_M, 0, 0]), np.array([0, 0, 2 * math.pi / PLACES]), 1.0), observe(pfh, sda, k, rng))
    assert m.object_map.config.match_distance_cells == 1.0
    wide = replace(m.config, match_distance_cells=7.0)
    lib_model, lib = WhiskerRatSLAM.library([m], ["a"], wide)
    assert lib_model.object_map.config.match_distance_cells == 7.0 and lib_model.object_map.config == wide.map_config()
    assert lib.object_map.n_experiences == m.object_map.n_experiences
    assert m.object_map.config.match_distance_cells == 1.0  # the source map is not touched
    with pytest.raises(InvalidInputError, match="grid"):
        WhiskerRatSLAM.library([m], ["a"], replace(m.config, grid_cells=7))


def test_odometry_only_updates_keep_the_history_and_the_iteration_count_together(tmp_path):
    """on_odo advanced ``iteration`` without recording the object map's history (issue 25)."""
    from maps.odometry import SpatialOdometry

    slam = WhiskerRatSLAM(WhiskerRatSLAMConfig())
    odo = SpatialOdometry(np.array([0.01, 0.0, 0.0]), np.zeros(3), 1.0)
    for k in range(4):
        slam.on_odo(odo)
        assert slam.iteration == slam.object_map.n_recorded == len(slam.object_map.history) == k + 1
    slam.step(odo, None)
    assert slam.iteration == slam.object_map.n_recorded == 5
    slam.save(tmp_path / "m.npz")  # a model that has seen no view saves and loads back
    again = WhiskerRatSLAM.load(tmp_path / "m.npz")
    assert again.iteration == again.object_map.n_recorded == 5
