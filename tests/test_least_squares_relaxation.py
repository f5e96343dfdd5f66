"""maps.least_squares_relaxation: hand-computed pose graphs, exact graphs recovered, view ties, typed errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from maps.experience_map import ExperienceMap, MapConfig
from maps.least_squares_relaxation import LeastSquaresConfig, map_edges, relax_least_squares, solve_se2_graph, view_ties
from maps.object_map import ObjectMap
from whisker_io.errors import ConfigError, InvalidInputError, ShapeError

HYP = settings(max_examples=40, deadline=None)


def _relative(pa, pb):
    """Pose of b in a's frame, by hand: R(-theta_a) (p_b - p_a), theta_b - theta_a."""
    c, s = math.cos(pa[2]), math.sin(pa[2])
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    return (c * dx + s * dy, -s * dx + c * dy, (pb[2] - pa[2] + math.pi) % (2 * math.pi) - math.pi)


def test_two_parallel_edges_give_their_weighted_mean():
    start = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2]])
    ends = np.array([[0, 1], [0, 1]])
    rel = np.array([[1.0, 0.0, 0.0], [1.2, 0.0, 0.0]])
    equal = solve_se2_graph(start, ends, rel, [0.1, 0.1], [0.01, 0.01])
    np.testing.assert_allclose(equal[1], [1.1, 0.0, 0.0], atol=1e-6)
    # sigma 0.1 and 0.2: weights 1 and 1/4 -> (1.0 + 0.25 * 1.2) / 1.25 = 1.04
    weighted = solve_se2_graph(start, ends, rel, [0.1, 0.2], [0.01, 0.01])
    np.testing.assert_allclose(weighted[1], [1.04, 0.0, 0.0], atol=1e-6)
    np.testing.assert_array_equal(weighted[0], start[0])  # the gauge stays


def test_an_edge_is_read_in_its_source_frame():
    start = np.array([[0.0, 0.0, math.pi / 2], [0.0, 0.0, 0.0]])
    out = solve_se2_graph(start, [[0, 1]], [[1.0, 0.0, 0.3]], [0.01], [0.01])
    np.testing.assert_allclose(out[1], [0.0, 1.0, math.pi / 2 + 0.3], atol=1e-6)


@HYP
@given(n=st.integers(2, 8), extra=st.integers(0, 6), seed=st.integers(0, 2**31 - 1))
def test_an_exact_graph_is_recovered_from_perturbed_poses(n, extra, seed):
    rng = np.random.default_rng(seed)
    truth = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(-math.pi, math.pi, n)])
    ends = [(i, i + 1) for i in range(n - 1)] + [tuple(rng.choice(n, 2, replace=False)) for _ in range(extra)]
    rel = np.array([_relative(truth[a], truth[b]) for a, b in ends])
    start = truth + np.r_[[np.zeros(3)], rng.uniform(-0.05, 0.05, (n - 1, 3))]
    out = solve_se2_graph(start, np.array(ends), rel, np.full(len(ends), 0.02), np.full(len(ends), 0.01))
    np.testing.assert_allclose(out[:, :2], truth[:, :2], atol=1e-5)
    dth = (out[:, 2] - truth[:, 2] + math.pi) % (2 * math.pi) - math.pi
    assert np.max(np.abs(dth)) < 1e-5


def test_view_ties_join_each_later_experience_to_its_views_first():
    np.testing.assert_array_equal(view_ties([3, 1, 3, 3, 1, 2]), [[0, 2], [0, 3], [1, 4]])
    assert view_ties([]).shape == (0, 2)


def _drive(em, steps):
    """Drive the map: each step (v m/s, omega rad/s, dt s, packet cells, view id)."""
    prev = 0
    for v, w, dt, pc, view in steps:
        em.on_odo(v, w, dt)
        em.update(pc, view, prev)
        prev = view


def test_a_map_without_loop_closures_is_left_where_it_is():
    em = ExperienceMap(MapConfig(pc_shape=(30, 30, 36)))
    _drive(em, [(0.1, 0.0, 1.0, (0, 0, 0), 0)] + [(0.1, 0.3 * (k % 3), 1.0, (k, 0, 0), k) for k in range(1, 12)])
    assert em.n_experiences == 12
    np.testing.assert_allclose(relax_least_squares(em), em.poses, atol=1e-7)


def test_tying_a_views_two_experiences_brings_them_together():
    # view 0, then 1 m on with view 1, then back to the start by odometry that says 0.8 m: view 0 again, but the
    # packet is 10 cells from the first experience's, so the map makes a second experience of view 0
    em = ExperienceMap(MapConfig(pc_shape=(30, 30, 36)))
    _drive(em, [(0.0, 0.0, 1.0, (0, 0, 0), 0), (1.0, 0.0, 1.0, (5, 0, 0), 1),
                (0.0, math.pi, 1.0, (5, 0, 18), 2), (0.8, 0.0, 1.0, (10, 0, 18), 0)])
    assert em.experiences_of_view(0) == [0, 3]
    free = relax_least_squares(em, LeastSquaresConfig(tie_views=False))
    tied = relax_least_squares(em)
    assert np.hypot(*(free[3, :2] - free[0, :2])) == pytest.approx(0.2, abs=1e-6)  # the odometry's disagreement
    assert np.hypot(*(tied[3, :2] - tied[0, :2])) < 0.02
    ends, rel, s_m, s_r = map_edges(em)
    assert ends.tolist()[-1] == [0, 3] and rel[-1].tolist() == [0.0, 0.0, 0.0] and s_m[-1] == 0.01
    # the link 0 -> 1 spans 2 s of odometry (MapConfig's keep_first_accumulator counts the second before the first
    # experience again) = 3 steps of 2/3 s, one traversal: sigma * sqrt(3); the link 2 -> 3: 1 s, sqrt(1.5)
    k = ends.tolist().index([0, 1])
    assert s_m[k] == pytest.approx(0.0166 * math.sqrt(3)) and s_r[k] == pytest.approx(math.radians(0.3) * math.sqrt(3))
    assert s_m[ends.tolist().index([2, 3])] == pytest.approx(0.0166 * math.sqrt(1.5))
    np.testing.assert_allclose(rel[k], [1.0, 0.0, 0.0], atol=1e-12)


def test_bad_graphs_raise_typed_errors():
    p = np.zeros((2, 3))
    with pytest.raises(ShapeError):
        solve_se2_graph(p, [[0, 1, 2]], [[1, 0, 0]], [1.0], [1.0])
    with pytest.raises(InvalidInputError):
        solve_se2_graph(p, [[0, 2]], [[1, 0, 0]], [1.0], [1.0])
    with pytest.raises(InvalidInputError):
        solve_se2_graph(p, [[0, 1]], [[1, 0, 0]], [0.0], [1.0])
    with pytest.raises(InvalidInputError):
        solve_se2_graph(p, [[0, 1]], [[math.nan, 0, 0]], [1.0], [1.0])
    with pytest.raises(InvalidInputError):
        solve_se2_graph(p, [[0, 1]], [[1, 0, 0]], [1.0], [1.0], fixed=2)
    with pytest.raises(InvalidInputError):
        solve_se2_graph(p, [[0, 1]], [[1, 0, 0]], [1.0], [1.0], loss="square")
    with pytest.raises(InvalidInputError):
        relax_least_squares(ObjectMap())
    with pytest.raises(InvalidInputError):
        relax_least_squares("a map")
    with pytest.raises(InvalidInputError):
        view_ties([0.5, 1.5])


@HYP
@given(field=st.sampled_from(["step_s", "sigma_m", "sigma_deg", "tie_sigma_m", "tie_sigma_deg"]),
       value=st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf)))
def test_config_refuses_bad_values(field, value):
    with pytest.raises(ConfigError):
        LeastSquaresConfig(**{field: value})


def test_config_refuses_an_unknown_loss_and_too_few_evaluations():
    with pytest.raises(ConfigError):
        LeastSquaresConfig(loss="square")
    with pytest.raises(ConfigError):
        LeastSquaresConfig(max_evaluations=0)


def test_a_link_driven_twice_counts_as_two_traversals():
    # view 0, 1 m on to view 1, then back to view 0 at its pose cells: the map averages the return into the link
    em = ExperienceMap(MapConfig(pc_shape=(30, 30, 36), link_update="average", keep_first_accumulator=False))
    _drive(em, [(0.0, 0.0, 1.0, (0, 0, 0), 0), (1.0, 0.0, 1.0, (5, 0, 0), 1),
                (0.0, math.pi, 1.0, (5, 0, 0), 1), (1.0, 0.0, 1.0, (0, 0, 0), 0)])
    assert em.n_experiences == 2 and em.link_traversals.tolist() == [2]
    ends, _, s_m, _ = map_edges(em, LeastSquaresConfig(step_s=1.0, tie_views=False))
    # traversals of 1 s and 2 s: mean 1.5 s = 1.5 steps of 1 s, over 2 traversals: sigma * sqrt(1.5 / 2)
    assert ends.tolist() == [[0, 1]] and s_m[0] == pytest.approx(0.0166 * math.sqrt(0.75))
