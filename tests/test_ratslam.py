"""Tests of cansim.models.ratslam: the RatSLAM model, its OpenRatSLAM parity preset, config files,
save/resume, bad input, and the synthetic end-to-end acceptance (map vs dead reckoning, kidnapping)."""

import math
import warnings

import numpy as np
import pytest

from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.frontends.tactile import TactileTemplateConfig
from cansim.frontends.visual import VisualTemplateConfig
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from cansim.testing.worlds import LoopRoute, make_run, render_view, scatter_landmarks
from whisker_io.errors import CorruptFileError
from maps.experience_map import Action
from maps.metrics import absolute_trajectory_error, energy_metric, experience_metric

ROUTE = LoopRoute(width_m=4.0, height_m=3.0, corner_radius_m=0.75, step_m=0.05)
CFG = RatSLAMConfig(cell_size_m=0.05, xy_cells=21, inject_energy=0.05)


def snapshot(slam):
    em = slam.experience_map
    return (slam.pose_cells.activity.tobytes(), slam.n_views, slam.iteration, em.poses.tobytes(),
            em.n_links, em.accumulator, slam.best_pc)


def test_keyword_parameters_and_presets():
    slam = RatSLAM(xy_cells=15, heading_cells=24, relax_passes=3)
    assert slam.pose_cells.shape == (15, 15, 24)
    assert slam.experience_map.config.relax_passes == 3
    with pytest.raises(ConfigError, match="pc_dimxy"):
        RatSLAM(pc_dimxy=3)
    with pytest.raises(ConfigError, match="pc_dim_xy is OpenRatSLAM's name: use xy_cells="):
        RatSLAM(pc_dim_xy=30)
    par = RatSLAMConfig.openratslam()
    assert (par.frame, par.dtype, par.relax_budget, par.strict_translation) == ("openratslam", "float64", None, True)
    ch3 = RatSLAMConfig.thesis_ch3()
    assert (ch3.xy_cells, ch3.cell_size_m, ch3.match_distance_cells, ch3.initial_heading_deg) == (30, 0.015, 1.0, 180.0)
    assert ch3.frontend == TactileTemplateConfig(match_threshold=20.0) and ch3.relax_passes == 10
    assert RatSLAM(ch3).pose_cells.shape == (30, 30, 36)


def test_config_file_unknown_key_warned_malformed_rejected(tmp_path):
    text = "[general]\ntopic_root=irat_red\n[ratslam]\npc_dim_xy=31\nvt_panoramic=1\nvt_match_threshold=0.05\nexp_loops = 20\n"
    path = tmp_path / "config_irat.txt.in"
    path.write_text(text)
    with pytest.warns(UserWarning, match="topic_root"):
        cfg = RatSLAMConfig.from_file(path)
    assert (cfg.xy_cells, cfg.frontend.panoramic, cfg.frontend.match_threshold, cfg.relax_passes) == (31, True, 0.05, 20)
    for bad in ("pc_dim_xy=2.5", "vt_match_threshold=abc", "vt_panoramic=maybe", "pc_w_e_dim=4"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with pytest.raises(ConfigError, match=bad.split("=")[0] + ".*line 2|line 2.*" + bad.split("=")[0]):
                RatSLAMConfig.from_text("[ratslam]\n" + bad + "\n")


def test_nan_odometry_and_bad_observation_leave_state_unchanged():
    slam = RatSLAM(CFG)
    for k in range(5):
        slam.step(0.05, 0.01, 1.0, k % 3)
    before = snapshot(slam)
    for args in [(math.nan, 0.0, 1.0), (0.05, math.inf, 1.0), (0.05, 0.0, -1.0)]:
        with pytest.raises(InvalidInputError):
            slam.step(*args, 0)
    with pytest.raises(InvalidInputError):
        slam.step(0.05, 0.0, 1.0, "not an id")
    assert snapshot(slam) == before


def test_wrong_image_size_leaves_state_unchanged():
    visual = VisualTemplateConfig(template_width_blocks=20, template_height_blocks=4, shift_match_blocks=2, step_match_blocks=1)
    slam = RatSLAM(CFG, frontend=visual)
    lm = scatter_landmarks(ROUTE, seed=0)
    slam.step(0.05, 0.0, 1.0, render_view((0, -1.5, 0), lm, shape=(20, 80)))
    before = snapshot(slam)
    with pytest.raises(ShapeError):
        slam.step(0.05, 0.0, 1.0, render_view((0, -1.5, 0), lm, shape=(20, 60)))
    assert snapshot(slam) == before


def test_tactile_frontend_reuses_templates():
    slam = RatSLAM(RatSLAMConfig.thesis_ch3(frontend=TactileTemplateConfig(match_threshold=5.0)))
    img = np.zeros((3, 6), dtype=np.uint8)
    img[1, 2] = 200
    a = slam.step(0.0, 0.0, 1.0, img)
    b = slam.step(0.0, 0.0, 1.0, img + np.uint8(4))  # S = 18 * 2 = 36 > 5 -> new
    c = slam.step(0.0, 0.0, 1.0, img)
    assert (a.view_id, b.view_id, c.view_id) == (0, 1, 0)
    assert a.new_view and b.new_view and not c.new_view


@pytest.mark.parametrize(
    "frame,engine,axis,sign",
    [("openratslam", "openratslam", 1, -1), ("openratslam", "population", 1, -1), ("standard", "population", 0, -1)],
)
def test_theta_index_zero_direction_per_frame(frame, engine, axis, sign):
    # the packet starts at theta index 18 (180 deg): the C++ frame moves it along -y
    # ((sin, cos)(pi) = (0, -1)); the standard frame along -x ((cos, sin)(pi) = (-1, 0)).
    slam = RatSLAM(RatSLAMConfig.openratslam(frame=frame, pose_cells=engine))
    start = np.array(slam.best_pc)
    for _ in range(3):
        slam.step(1.0, 0.0, 1.0)  # one cell per step, no view
    moved = np.array(slam.best_pc) - start
    assert moved[axis] == pytest.approx(3 * sign, abs=0.05)
    assert abs(moved[1 - axis]) < 0.05 and abs(moved[2]) < 0.05


def test_parity_translation_limited_to_one_cell():
    slam = RatSLAM(RatSLAMConfig.openratslam(cell_size_m=0.1))
    slam.step(0.1, 0.0, 1.0, 0)
    with pytest.raises(InvalidInputError, match="one cell per step"):
        slam.step(0.25, 0.0, 1.0, 0)
    RatSLAM(CFG).step(0.25, 0.0, 1.0, 0)  # the default engine handles any shift


def test_experience_only_after_odometry_and_view():
    slam = RatSLAM(CFG)
    s = slam.step(0.05, 0.0, 1.0)  # odometry only
    assert s.exp_id == -1 and s.action == Action.NO_ACTION
    s = slam.step(0.05, 0.0, 1.0, 7)
    assert s.exp_id == 0 and s.action == Action.CREATE_NODE and s.view_id == 0
    s = slam.step(0.05, 0.0, 1.0, 9)
    assert s.exp_id == 1 and slam.experience_map.n_links == 1


@pytest.mark.parametrize(
    "cfg",
    [RatSLAMConfig(cell_size_m=0.05, relax_budget=300), RatSLAMConfig.openratslam(cell_size_m=0.1)],
    ids=["default", "openratslam_parity"],
)
def test_save_resume_equals_uninterrupted(tmp_path, cfg):
    run = make_run(LoopRoute(step_m=0.05), loops=(1, 1), seed=2)
    full = RatSLAM(cfg)
    full_log = full.run(run.vtrans, run.vrot, run.dt, run.view_ids)
    half = len(run) // 2 + 7
    first = RatSLAM(cfg)
    log_a = first.run(run.vtrans[:half], run.vrot[:half], run.dt, run.view_ids[:half])
    first.save(tmp_path / "model.npz")
    resumed = RatSLAM.load(tmp_path / "model.npz")
    log_b = resumed.run(run.vtrans[half:], run.vrot[half:], run.dt, run.view_ids[half:])
    assert np.array_equal(np.concatenate([log_a.exp_ids, log_b.exp_ids]), full_log.exp_ids)
    assert np.concatenate([log_a.best_pc, log_b.best_pc]).tobytes() == full_log.best_pc.tobytes()
    assert snapshot(resumed) == snapshot(full)
    a, b = resumed.experience_map.links, full.experience_map.links
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()


def test_corrupt_model_file_names_field(tmp_path):
    slam = RatSLAM(CFG)
    slam.step(0.05, 0.0, 1.0, 0)
    slam.save(tmp_path / "m.npz")
    arrays = dict(np.load(tmp_path / "m.npz", allow_pickle=False))
    arrays["pc_activity"] = arrays["pc_activity"][:, :, :5]
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(CorruptFileError, match="pc_activity"):
        RatSLAM.load(tmp_path / "bad.npz")
    del arrays["em_exp_pose"]
    arrays["pc_activity"] = slam.pose_cells.activity
    np.savez(tmp_path / "bad2.npz", **arrays)
    with pytest.raises(CorruptFileError, match="em_exp_pose"):
        RatSLAM.load(tmp_path / "bad2.npz")


@pytest.mark.slow
def test_synthetic_five_loops_map_beats_dead_reckoning_and_kidnapping_hurts():
    clean = make_run(ROUTE, loops=(1,) * 5, seed=0)
    n = clean.n_places
    kid = make_run(ROUTE, loops=(1,) * 5, seed=0, kidnap=[(int((1.3 + 1.25 * j) * n), 10) for j in range(3)])
    results = {}
    for name, run in (("clean", clean), ("kidnapped", kid)):
        slam = RatSLAM(CFG)
        log = slam.run(run.vtrans, run.vrot, run.dt, run.view_ids)
        est = slam.experience_map.poses[log.exp_ids]
        results[name] = (
            experience_metric(log.exp_ids, run.truth, base_end=n + 1),
            energy_metric(est, run.truth).energy,
            absolute_trajectory_error(est, run.truth).rmse,
            absolute_trajectory_error(run.dead_reckoning, run.truth).rmse,
        )
    exm, em, ate_map, ate_dr = results["clean"]
    kexm, kem, _, _ = results["kidnapped"]
    assert ate_map <= 0.30 * ate_dr
    assert kexm.arr < exm.arr
    assert kem > em
    assert exm.arcr > 0.9


def test_long_run_relaxation_work_is_bounded():
    # the acceptance's 20,000-iteration time/memory measurement lives in
    # bench/test_bench_ratslam_parts.py; here the invariant behind it: per-step
    # relaxation work never exceeds relax_budget however large the map grows.
    run = make_run(LoopRoute(step_m=0.05), loops=(1,) * 12, seed=1)
    slam = RatSLAM(CFG, relax_budget=600)
    work, ids = [], []
    for k in range(len(run)):
        ids.append(slam.step(run.vtrans[k], run.vrot[k], run.dt, int(run.view_ids[k])).exp_id)
        work.append(slam.experience_map.last_relax_updates)
    assert slam.experience_map.n_links * CFG.relax_passes > 600  # the budget was binding
    assert max(work) == 600
    est = slam.experience_map.poses[np.array(ids)]
    assert absolute_trajectory_error(est, run.truth).rmse < 0.5 * absolute_trajectory_error(run.dead_reckoning, run.truth).rmse


def test_visual_model_save_resume_equals_uninterrupted(tmp_path):
    run = make_run(LoopRoute(step_m=0.1), loops=(1, 1), seed=5)
    lm = scatter_landmarks(LoopRoute(step_m=0.1), seed=1)
    images = [render_view(p, lm, shape=(12, 48)) for p in run.truth]
    cfg = RatSLAMConfig(cell_size_m=0.1, frontend=VisualTemplateConfig(
        template_width_blocks=24, template_height_blocks=4, shift_match_blocks=2, step_match_blocks=1, match_threshold=0.02))
    full = RatSLAM(cfg)
    full_log = full.run(run.vtrans, run.vrot, run.dt, images)
    assert full.n_views < len(run)  # the second loop re-uses templates
    half = 30
    first = RatSLAM(cfg)
    first.run(run.vtrans[:half], run.vrot[:half], run.dt, images[:half])
    first.save(tmp_path / "visual.npz")
    resumed = RatSLAM.load(tmp_path / "visual.npz")
    log_b = resumed.run(run.vtrans[half:], run.vrot[half:], run.dt, images[half:])
    assert np.array_equal(log_b.view_ids, full_log.view_ids[half:])
    assert snapshot(resumed) == snapshot(full)


def test_step_equals_on_view_then_on_odo_and_views_can_arrive_alone():
    run = make_run(LoopRoute(step_m=0.05), loops=(1, 1), seed=9)
    a, b = RatSLAM(CFG), RatSLAM(CFG)
    for k in range(len(run)):
        sa = a.step(run.vtrans[k], run.vrot[k], run.dt, int(run.view_ids[k]))
        b.on_view(int(run.view_ids[k]))
        sb = b.on_odo(run.vtrans[k], run.vrot[k], run.dt)
        assert (sa.exp_id, sa.best_pc, sa.action) == (sb.exp_id, sb.best_pc, sb.action)
    assert snapshot(a) == snapshot(b)
    # a view with no odometry yet creates no experience (C++: get_action needs both)
    c = RatSLAM(CFG)
    c.on_view(0)
    assert c.experience_map.n_experiences == 0
    assert c.on_odo(0.05, 0.0, 1.0).exp_id == 0


@pytest.mark.slow
def test_20000_iterations_stay_under_200_mb():
    """Issue acceptance: a 20,000-iteration run stays under 200 MB (numpy allocations are traced).

    The per-iteration time growth (<= 2x from iteration 1,000 to 20,000) is measured in
    bench/test_bench_ratslam_parts.py (ratio 0.89); the bound on relaxation work per
    step that keeps it flat is asserted by test_long_run_relaxation_work_is_bounded.
    """
    import tracemalloc

    from cansim.testing.worlds import LoopRoute, make_run

    n = 20_000
    route = LoopRoute(width_m=4.0, height_m=3.0, corner_radius_m=0.75, step_m=0.05)
    run = make_run(route, loops=(1,) * (n // 254 + 2), seed=0)
    tracemalloc.start()
    try:
        slam = RatSLAM(RatSLAMConfig(cell_size_m=0.05, inject_energy=0.05))
        slam.step(0.0, 0.0, 1.0, 0)
        for k in range(1, n + 1):
            slam.step(run.vtrans[k], run.vrot[k], run.dt, int(run.view_ids[k]))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert slam.iteration >= n
    assert peak < 200e6


@pytest.mark.parametrize("field, value", [("lv_locations", -np.inf), ("lv_locations", np.nan), ("lv_decay", np.inf),
                                          ("lv_v", np.nan)])
def test_a_saved_model_with_non_finite_view_state_is_refused(tmp_path, field, value):
    """RatSLAM.load accepted -inf written into lv_locations (issue 25)."""
    slam = RatSLAM(CFG)
    for k in range(5):
        slam.step(0.05, 0.0, 1.0, k % 2)
    slam.save(tmp_path / "m.npz")
    arrays = dict(np.load(tmp_path / "m.npz", allow_pickle=False))
    assert arrays[field].size
    bad = arrays[field].astype(np.float64).copy()
    bad.flat[0] = value
    arrays[field] = bad
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(CorruptFileError, match=field):
        RatSLAM.load(tmp_path / "bad.npz")


@pytest.mark.parametrize("keep", [True, False])
def test_the_first_experience_resets_dead_reckoning_unless_kept_as_the_cpp_does(keep):
    """Ten steps of 0.3 m north, a new view each: the robot is at 0.3 (k + 1) m after step k. OpenRatSLAM counts the
    motion before experience 0 twice (``keep_first_accumulator``, the default), so experience k >= 1 lies one step on."""
    slam = RatSLAM(RatSLAMConfig(frontend="ids", cell_size_m=1.0, keep_first_accumulator=keep))
    for k in range(10):
        slam.step(0.3, 0.0, 1.0, k)
    em = slam.experience_map
    expected = [0.3] + [0.3 * (k + 1 + keep) for k in range(1, 10)]  # initial heading 90 deg: along +y
    np.testing.assert_allclose(em.poses[:em.n_experiences, 1], expected, atol=1e-12)
    np.testing.assert_allclose(em.poses[:em.n_experiences, 0], 0.0, atol=1e-12)
    assert RatSLAMConfig.openratslam().keep_first_accumulator  # the parity preset keeps the C++'s rule


def test_implausible_odometry_is_warned_once_each_and_still_runs():
    """A yaw rate in deg/s (45 "rad/s" x 0.5 s) and a 40-cell step were taken silently (a user's pass, session 47)."""
    slam = RatSLAM(RatSLAMConfig(frontend="ids", cell_size_m=0.25))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        slam.step(0.2, 0.5, 0.5, 0)  # plausible: no warning
        slam.step(1.3, 0.0, 1.0, 0)  # 5.2 cells, just under a quarter of the grid (5.25 cells): no warning either
        assert record == []
        slam.step(0.2, 45.0, 0.5, 1)
        slam.step(0.2, -45.0, 0.5, 1)  # the same fault again: warned once
        slam.step(10.0, 0.0, 1.0, 2)
        slam.step(10.0, 0.0, 1.0, 3)
    texts = [str(w.message) for w in record]
    assert len(texts) == 2 and all(w.filename == __file__ for w in record)  # pointing at the caller's step
    assert "vrot*dt = 22.5 rad turns more than half a circle" in texts[0] and "deg/s" in texts[0]
    assert "vtrans*dt = 10 m moves the packet 40 cells in one step, a quarter of the 21-cell grid" in texts[1]
    assert slam.iteration == 6  # warned, not refused
    strict = RatSLAM(RatSLAMConfig.openratslam(frontend="ids", cell_size_m=0.25))
    with pytest.warns(UserWarning, match="half a circle"):  # the parity preset refuses a long step, warns of a turn
        strict.step(0.2, 45.0, 0.5, 0)
    with pytest.raises(InvalidInputError, match="40 cells"):
        strict.step(10.0, 0.0, 1.0, 0)


def test_the_odometry_warning_points_at_the_callers_line_whichever_way_the_step_came():
    """A fixed stacklevel pointed into the library for run() and one frame off for on_odo() (a review, session 47)."""
    for how in ("step", "on_odo", "run"):
        slam = RatSLAM(RatSLAMConfig(frontend="ids"))
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            if how == "step":
                slam.step(0.2, 45.0, 0.5, 0)
            elif how == "on_odo":
                slam.on_odo(0.2, 45.0, 0.5)
            else:
                slam.run(np.array([0.2]), np.array([45.0]), np.array([0.5]), [0])
        assert [w.filename for w in record] == [__file__], how
