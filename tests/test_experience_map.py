"""Tests of maps.experience_map (OpenRatSLAM experience map, Eq 2.23-2.25)."""

import json
import math

import networkx as nx
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from whisker_io.errors import CorruptFileError, InvalidInputError
from maps.experience_map import Action, ExperienceMap, MapConfig
from maps.se2 import SE2Geometry, signed_delta_rad


def square_map(relax_passes=1):
    """Four experiences around a 1 x 1 square; the last step closes the loop 0.2 m short."""
    em = ExperienceMap(MapConfig(relax_passes=relax_passes, relax_budget=None), SE2Geometry(initial_heading_deg=0.0))
    em.update((0, 0, 0), 0, 0)  # exp 0 at the origin, facing 0
    em.on_odo(1.0, 0.0, 1.0)
    em.update((5, 0, 0), 1, 0)  # exp 1 at (1, 0)
    em.on_odo(1.0, math.pi / 2, 1.0)  # rotate first, then translate
    em.update((5, 5, 0), 2, 1)  # exp 2 at (1, 1), facing pi/2
    em.on_odo(0.0, math.pi / 2, 1.0)
    em.on_odo(1.2, 0.0, 1.0)
    em.update((0, 5, 0), 3, 2)  # exp 3 at (-0.2, 1), facing pi
    em.on_odo(0.0, math.pi / 2, 1.0)
    em.on_odo(1.0, 0.0, 1.0)
    em.on_odo(0.0, math.pi / 2, 1.0)  # facing 0 again, as when exp 0 was made
    return em


def link_residual(em):
    ends, data = em.links
    p = em.poses
    f, t = ends[:, 0], ends[:, 1]
    lx = p[f, 0] + data[:, 0] * np.cos(p[f, 2] + data[:, 1])
    ly = p[f, 1] + data[:, 0] * np.sin(p[f, 2] + data[:, 1])
    return float(np.sum((p[t, 0] - lx) ** 2 + (p[t, 1] - ly) ** 2))


def test_dead_reckoning_and_links_hand_computed():
    em = square_map()
    np.testing.assert_allclose(em.poses, [[0, 0, 0], [1, 0, 0], [1, 1, math.pi / 2], [-0.2, 1, math.pi]], atol=1e-12)
    ends, data = em.links
    assert ends.tolist() == [[0, 1], [1, 2], [2, 3]]
    # link 2->3: 1.2 m travelled towards pi from a source facing pi/2; 2 s
    np.testing.assert_allclose(data[2], [1.2, math.pi / 2, math.pi / 2, 2.0], atol=1e-12)


def test_loop_closure_single_eq_2_25_update_hand_computed():
    em = square_map(relax_passes=1)
    r = em.update((0, 0, 0), 0, 3)  # view 0 again, packet on exp 0 -> link 3->0 and switch
    assert r.action == Action.CREATE_EDGE and r.relocalised and r.new_link and r.exp_id == 0 and r.src_id == 3
    # one Gauss-Seidel pass: links 0->1, 1->2, 2->3 are consistent; link 3->0 (d=1,
    # heading pi/2, facing pi) predicts exp 0 at (-0.2, 0) facing 0 while it is at
    # (0, 0) facing 0: both ends move by half (correction 0.5) of the 0.2 m residual.
    np.testing.assert_allclose(em.links[1][3], [1.0, math.pi / 2, math.pi, 3.0], atol=1e-12)
    p = em.poses
    np.testing.assert_allclose(p[3], [-0.1, 1.0, math.pi], atol=1e-12)
    np.testing.assert_allclose(p[0], [-0.1, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p[1], [1, 0, 0], atol=1e-12)


def test_relaxation_reduces_closure_error():
    em = square_map(relax_passes=0)
    em.update((0, 0, 0), 0, 3)
    before = link_residual(em)
    assert before == pytest.approx(0.04)
    for _ in range(20):
        em.iterate(n_updates=4)
    # the 0.2 m misclosure cannot vanish (sides 1 and 1.2 are both "parallel"), but it is
    # spread over the loop: the least-squares optimum is 0.2^2 / 4 = 0.01 m^2
    after = link_residual(em)
    assert 0.01 - 1e-12 <= after < 0.5 * before


def test_get_action_rules():
    em = ExperienceMap(MapConfig(match_distance_cells=2.0, pc_shape=(21, 21, 36)))
    assert em.update((10, 10, 18), 0, 0).action == Action.CREATE_NODE
    # same view, packet within threshold -> nothing
    assert em.update((11, 10, 18), 0, 0).action == Action.NO_ACTION
    # same view, packet moved 3 cells -> no other experience of view 0 -> create
    r = em.update((13, 10, 18), 0, 0)
    assert r.action == Action.CREATE_NODE and r.exp_id == 1 and em.experiences_of_view(0) == [0, 1]
    # new view -> create
    assert em.update((15, 10, 18), 1, 0).exp_id == 2
    # back to view 0 with the packet near exp 0 across the x wrap (20.5 vs 0.2 -> 0.7 cells)
    em2 = ExperienceMap()
    em2.update((0.2, 10, 0), 0, 0)
    em2.update((5, 10, 0), 1, 0)
    r = em2.update((20.5, 10, 35.5), 0, 1)
    # a link already joins 0 and 1 (0->1): OpenRatSLAM adds none in either direction
    assert r.action == Action.CREATE_EDGE and r.exp_id == 0 and r.relocalised and not r.new_link
    assert em2.n_links == 1


def test_first_experience_does_not_reset_accumulators():
    # OpenRatSLAM quirk: on_set_experience(0) with current id already 0 is a no-op
    em = ExperienceMap(MapConfig(), SE2Geometry(initial_heading_deg=0.0))
    em.on_odo(1.0, 0.0, 1.0)
    em.update((0, 0, 0), 0, 0)
    assert em.poses[0].tolist() == [1.0, 0.0, 0.0]
    em.on_odo(1.0, 0.0, 1.0)
    em.update((5, 0, 0), 1, 0)
    assert em.links[1][0, 0] == 2.0  # distance counts the motion before exp 0 too
    assert em.poses[1, 0] == 3.0


def test_initial_facing_from_config():
    em = ExperienceMap(MapConfig())  # initial heading 90 deg (OpenRatSLAM's default)
    em.on_odo(1.0, 0.0, 1.0)
    em.update((0, 0, 0), 0, 0)
    np.testing.assert_allclose(em.poses[0], [0.0, 1.0, math.pi / 2], atol=1e-15)


def random_drive(em, rng, steps, n_views=15):
    vt_prev = 0
    for _ in range(steps):
        em.on_odo(rng.uniform(0, 1), rng.normal(0, 0.3), 0.5)
        vt = int(rng.integers(0, n_views))
        em.update(tuple(rng.uniform(0, [21, 21, 36])), vt, vt_prev)
        vt_prev = vt


def test_bounded_relaxation_equals_openratslam_while_within_budget():
    a = ExperienceMap(MapConfig(match_distance_cells=6.0, relax_budget=None))
    b = ExperienceMap(MapConfig(match_distance_cells=6.0, relax_budget=10**6))
    random_drive(a, np.random.default_rng(1), 150)
    random_drive(b, np.random.default_rng(1), 150)
    assert a.n_links > 20
    assert a.poses.tobytes() == b.poses.tobytes()
    c = ExperienceMap(MapConfig(match_distance_cells=6.0, relax_budget=50))
    random_drive(c, np.random.default_rng(1), 150)
    assert c.iterate() == 50


def test_relaxation_order_is_by_source_then_creation():
    # links created 1->2 first, then 0->1: OpenRatSLAM relaxes 0->1 before 1->2
    em = ExperienceMap(MapConfig(relax_passes=0, relax_budget=None), SE2Geometry(initial_heading_deg=0.0))
    em.update((0, 0, 0), 0, 0)
    em.on_odo(1.0, 0.0, 1.0)
    em.update((5, 0, 0), 1, 0)
    em.on_odo(1.0, 0.0, 1.0)
    em.update((10, 0, 0), 2, 1)
    em.on_odo(-2.5, 0.0, 1.0)  # exp 2 thinks exp 0 is 2.5 m back (it is 2 m)
    em.update((0, 0, 0), 0, 2)  # link 2->0 created last
    assert em.links[0][:, 0].tolist() == [0, 1, 2]
    em.iterate(n_updates=3)
    # 0->1 and 1->2 consistent, 2->0: predicted x0 = 2 + 2.5 cos(0 + pi) = -0.5
    np.testing.assert_allclose(em.poses[:, 0], [-0.25, 1.0, 2.25], atol=1e-12)


def test_save_load_continue_is_bit_identical(tmp_path):
    rng_a, rng_b = np.random.default_rng(7), np.random.default_rng(7)
    a = ExperienceMap(MapConfig(match_distance_cells=5.0, relax_budget=40))
    random_drive(a, rng_a, 200)
    b = ExperienceMap(MapConfig(match_distance_cells=5.0, relax_budget=40))
    random_drive(b, rng_b, 100)
    path = tmp_path / "map.npz"
    b.save(path)
    c = ExperienceMap.load(path)
    assert c.poses.tobytes() == b.poses.tobytes() and c.config == b.config
    random_drive(c, rng_b, 100)
    assert c.n_experiences == a.n_experiences and c.n_links == a.n_links
    assert c.poses.tobytes() == a.poses.tobytes()
    assert c.pc_coords.tobytes() == a.pc_coords.tobytes()
    assert all(x.tobytes() == y.tobytes() for x, y in zip(c.links, a.links))
    assert (c.current_id, c.accumulator) == (a.current_id, a.accumulator)


def test_corrupt_map_files_raise_typed_error_naming_field(tmp_path):
    em = square_map()
    good = tmp_path / "good.npz"
    em.save(good)
    arrays = dict(np.load(good, allow_pickle=False))
    for field, value in [("exp_pose", arrays["exp_pose"][:, :2]), ("link_ends", arrays["link_ends"] + 10),
                         ("state_f", np.full(6, np.nan)), ("config", np.array("{not json"))]:
        bad = dict(arrays)
        bad[field] = value
        np.savez(tmp_path / "bad.npz", **bad)
        with pytest.raises(CorruptFileError, match=field) as info:
            ExperienceMap.load(tmp_path / "bad.npz")
        assert info.value.field == field
    missing = {k: v for k, v in arrays.items() if k != "exp_vt"}
    np.savez(tmp_path / "missing.npz", **missing)
    with pytest.raises(CorruptFileError, match="exp_vt"):
        ExperienceMap.load(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip file at all")
    with pytest.raises(CorruptFileError):
        ExperienceMap.load(tmp_path / "junk.npz")


def _count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _number(v) -> bool:
    return (isinstance(v, float) and math.isfinite(v)) or (_count(v) and abs(v) < 1e308)


#: which values each configuration entry accepts (independent of the library's validators)
_ACCEPTS = {
    "heading_cells": lambda v: _count(v) and v >= 1,
    "heading_axis": lambda v: _count(v) and v >= 0,
    "initial_heading_deg": _number,
    "correction": lambda v: _number(v) and 0 < v <= 1,
    "relax_passes": lambda v: _count(v) and v >= 0,
    "match_distance_cells": lambda v: _number(v) and v >= 0,
    "relax_budget": lambda v: _count(v) and v >= 1,
}


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["geometry_params.heading_cells", "geometry_params.initial_heading_deg", "geometry_params.heading_axis",
                        "map.correction", "map.relax_passes", "map.match_distance_cells", "map.relax_budget"]),
       st.sampled_from([math.inf, -math.inf, math.nan, "a", [], {}, 2.5, -1, 10**400]))
@example("geometry_params.heading_cells", math.inf)  # int(inf): OverflowError instead of CorruptFileError
@example("geometry_params.initial_heading_deg", 10**400)  # float(10**400): OverflowError
@example("geometry_params.heading_cells", "36")  # int("36") was accepted
def test_a_bad_number_in_the_saved_configuration_is_a_corrupt_file(where, value):
    """JSON reads Infinity, NaN, 1e400 and any int: each bad one must be a CorruptFileError naming the config."""
    arrays = square_map().to_arrays()
    spec = json.loads(str(arrays["config"]))
    part, key = where.split(".")
    spec[part][key] = value
    arrays["config"] = np.array(json.dumps(spec))
    if _ACCEPTS[key](value):
        ExperienceMap.from_arrays(arrays)
        return
    with pytest.raises(CorruptFileError, match="config"):
        ExperienceMap.from_arrays(arrays)


def test_bad_odometry_leaves_state_unchanged():
    em = square_map()
    before = (em.accumulator, em.accum_time_s)
    for args in [(math.nan, 0, 1), (1, math.inf, 1), (1, 0, -1)]:
        with pytest.raises(InvalidInputError):
            em.on_odo(*args)
    assert (em.accumulator, em.accum_time_s) == before
    with pytest.raises(InvalidInputError):
        em.update((math.nan, 0, 0), 0, 0)


def test_networkx_view_typed_attributes_and_path_search():
    em = square_map()
    em.update((0, 0, 0), 0, 3)
    g = em.to_networkx()
    assert isinstance(g, nx.DiGraph) and g.number_of_nodes() == 4 and g.number_of_edges() == 4
    assert set(g.nodes[2]) == {"pc_cells", "view_id", "x_m", "y_m", "th_rad"}
    assert g.nodes[2]["view_id"] == 2 and g.graph["current_id"] == 0
    assert g.edges[2, 3]["d_m"] == pytest.approx(1.2)
    assert nx.shortest_path(g.to_undirected(), 1, 3, weight="d_m") in ([1, 0, 3], [1, 2, 3])


def test_signed_delta_rad_matches_cpp_semantics():
    assert signed_delta_rad(0.0, math.pi / 2) == pytest.approx(math.pi / 2)
    assert signed_delta_rad(3.0, -3.0) == pytest.approx(2 * math.pi - 6.0)
    assert signed_delta_rad(-3.0, 3.0) == pytest.approx(-(2 * math.pi - 6.0))


def test_plots_return_figures_with_the_map_and_log():
    import matplotlib

    matplotlib.use("Agg")
    from maps.plot_maps import plot_experience_ids, plot_experience_map

    em = square_map()
    em.update((0, 0, 0), 0, 3)
    truth = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    log = [0, 1, 2, 3, 0]
    fig = plot_experience_map(em, truth, truth + 0.05, log)
    ax = fig.axes[0]
    offsets = ax.collections[-1].get_offsets()
    assert len(offsets) == 4  # one marker per experience
    # aligned onto the truth by the same rigid transform as the trajectory error
    assert np.abs(np.asarray(offsets)[:4] - truth[:4]).max() < 0.15
    fig2 = plot_experience_ids(log, relocalisation_indices=[4], base_end=4, correct_indices=[4])
    assert fig2.axes[0].get_xlabel() == "iteration"
    with pytest.raises(InvalidInputError):
        plot_experience_map(em, truth, None, [0, 1, 2, 3, 9])


def test_the_map_plot_draws_given_poses_with_the_maps_links():
    """``poses=`` (e.g. a least-squares relaxation's) places the experiences; the links join them; bad poses are typed."""
    import matplotlib

    matplotlib.use("Agg")
    from maps.plot_maps import plot_experience_map

    em = square_map()
    given_poses = np.array([[5.0, 5.0, 0.0], [6.0, 5.0, 0.0], [6.0, 6.0, 0.0], [5.0, 6.0, 0.0]])
    ax = plot_experience_map(em, poses=given_poses).axes[0]
    np.testing.assert_allclose(np.asarray(ax.collections[-1].get_offsets()), given_poses[:, :2])
    ends, _ = em.links
    segs = np.asarray(ax.collections[0].get_segments())
    np.testing.assert_allclose(segs, np.stack([given_poses[ends[:, 0], :2], given_poses[ends[:, 1], :2]], axis=1))
    for bad in (given_poses[:3], given_poses[:, :1], np.full((4, 3), np.nan), "x"):
        with pytest.raises(InvalidInputError):  # ShapeError is one
            plot_experience_map(em, poses=bad)


def test_relaxation_order_stays_by_source_then_creation_over_many_links():
    # links are inserted into the relaxation order one by one; the order must stay the
    # sort by (source id, creation) - here recomputed from scratch - also after a reload
    em = ExperienceMap(MapConfig(match_distance_cells=6.0, relax_budget=None, relax_passes=1))
    random_drive(em, np.random.default_rng(3), 300)
    ends, _ = em.links
    m = len(ends)
    assert m > 100 and len(set(ends[:, 0].tolist())) > 20
    want = np.lexsort((np.arange(m), ends[:, 0]))
    assert em._a.order[:m].tolist() == want.tolist()
    again = ExperienceMap.from_arrays(em.to_arrays())
    assert again._a.order[:m].tolist() == want.tolist()
    random_drive(em, np.random.default_rng(4), 50)
    random_drive(again, np.random.default_rng(4), 50)
    assert again.poses.tobytes() == em.poses.tobytes() and again.links[0].tolist() == em.links[0].tolist()


def _view0_map(positions):
    """Experiences 0.. of view 0 at ``positions`` (cells, 21 x 21 x 36), each made under view 0, then view 1 current."""
    em = ExperienceMap(MapConfig(match_distance_cells=2.0, pc_shape=(21, 21, 36)))
    for k, p in enumerate(positions):
        em.update(p, 0, 0 if k == 0 else 1)  # a view change each time: with no close experience, create
        em.update(p, 1, 0)  # far from every view-1 experience except its own
    return em


def test_relocalisation_picks_the_nearest_experience_of_the_view_hand_computed():
    # view-0 experiences at even ids; from the packet (0.5, 10, 35): exp 2 (2.3, 10, 35) is
    # 1.8 cells away, exp 4 (0.5, 10.9, 0.6) sqrt(0.9^2 + 1.6^2) = 1.84 (theta across the
    # wrap: 36 - 34.4), exp 6 (20, 10, 35) 1.5 (x across the wrap: 21 - 19.5) - the nearest,
    # though not the first within the 2-cell threshold; the rest are far
    pos = [(10, 10, 18), (2.3, 10, 35), (0.5, 10.9, 0.6), (20, 10, 35), (5, 5, 5), (15, 15, 30)]
    em = _view0_map(pos)
    assert em.experiences_of_view(0) == [0, 2, 4, 6, 8, 10]
    r = em.update((0.5, 10, 35), 0, 1)
    assert r.action == Action.CREATE_EDGE and r.exp_id == 6 and r.relocalised


def test_relocalisation_tie_goes_to_the_lower_id_and_the_threshold_is_strict():
    # two view-0 experiences 1 cell either side of the packet: the first made wins
    em = _view0_map([(10, 10, 18), (10, 12, 18), (10, 14, 18), (4, 4, 4)])
    r = em.update((10, 13, 18), 0, 1)
    assert r.action == Action.CREATE_EDGE and r.exp_id == 2  # exps 2 (y 12) and 4 (y 14) tie at 1.0
    # exactly the threshold (2.0 cells) away from the nearest: not a match, a new experience
    em = _view0_map([(10, 10, 18), (4, 4, 4), (16, 16, 16), (1, 18, 30)])
    r = em.update((10, 12, 18), 0, 1)
    assert r.action == Action.CREATE_NODE and r.exp_id == 8


def test_the_current_experience_is_not_a_relocalisation_target():
    # the packet sits on the current experience (exp 2, view 0) but moved from it per the
    # view change; the only other view-0 experience (exp 0) is 1 cell away: link to it
    em = ExperienceMap(MapConfig(match_distance_cells=2.0, pc_shape=(21, 21, 36)))
    em.update((10, 10, 18), 0, 0)
    em.update((10, 15, 18), 1, 0)
    em.update((10, 11, 18), 0, 1)  # 1 cell from exp 0 of view 0: relocalises to exp 0
    assert em.current_id == 0
    em.update((10, 15, 18), 1, 0)  # back to exp 1
    em.update((3, 3, 3), 0, 1)  # far from exp 0: a new view-0 experience, exp 2
    assert em.current_id == 2 and em.experiences_of_view(0) == [0, 2]
    r = em.update((3, 3, 3), 0, 2)  # view changed, packet on exp 2 itself; exp 0 far: create
    assert r.action == Action.CREATE_NODE and r.exp_id == 3
