"""Pose-graph optimisation of whisk poses (maps.pose_graph).

Hand-solved small graphs (a chain is its dead reckoning; a 1-D loop shares its
misclosure as the normal equations say; a fixed node keeps its pose), the edges of a
hand-written whisk log, the stored surface of a noisy loop against the true poses, and
typed errors for bad input (hypothesis).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from maps.odometry import SpatialOdometry
from maps.pose_graph import (
    PoseGraphEdges,
    WhiskGraphConfig,
    dead_reckoned_poses,
    optimise_pose_graph,
    whisk_graph_edges,
    whisk_surface,
)
from whisker_io.errors import ConfigError, InvalidInputError, ShapeError

I7 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]


def _edges(ends, relative, sigma_m=1.0, sigma_rad=1.0) -> PoseGraphEdges:
    m = len(ends)
    return PoseGraphEdges(np.array(ends, dtype=np.int64).reshape(-1, 2), np.array(relative, dtype=float).reshape(-1, 7),
                          np.broadcast_to(np.asarray(sigma_m, dtype=float), (m,)).copy(),
                          np.broadcast_to(np.asarray(sigma_rad, dtype=float), (m,)).copy())


def _x(x: float) -> list[float]:
    return [x, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]


def test_a_chain_is_its_dead_reckoning_by_hand() -> None:
    qz = Rotation.from_euler("z", 90, degrees=True).as_quat()
    edges = _edges([(0, 1), (1, 2)], [[1.0, 0, 0, *qz], _x(1.0)])
    p = optimise_pose_graph(np.tile(I7, (3, 1)), edges)
    # node 1 at (1, 0, 0) turned 90 deg about z; node 2 one metre along node 1's x axis: (1, 1, 0)
    np.testing.assert_allclose(p[1, :3], [1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(p[2, :3], [1, 1, 0], atol=1e-6)
    np.testing.assert_allclose(np.abs(p[2, 3:] @ qz), 1.0, atol=1e-9)
    np.testing.assert_allclose(p[0], I7, atol=0)


def test_a_loop_shares_its_misclosure_as_the_normal_equations_say() -> None:
    # x1, x2 minimise (x1-1)^2 + (x2-x1-1)^2 + w (x2-2.3)^2: x2 = 2 x1 and (1 + 2w) x1 = 1 + 2.3 w
    for sigma_closure, x1 in ((1.0, 1.1), (0.1, 231.0 / 201.0)):
        edges = _edges([(0, 1), (1, 2), (0, 2)], [_x(1.0), _x(1.0), _x(2.3)], sigma_m=[1.0, 1.0, sigma_closure])
        p = optimise_pose_graph(np.tile(I7, (3, 1)), edges)
        np.testing.assert_allclose(p[1:, 0], [x1, 2 * x1], atol=1e-6)
        np.testing.assert_allclose(p[:, 1:3], 0, atol=1e-9)


def test_the_fixed_node_keeps_its_pose() -> None:
    start = np.tile(I7, (3, 1))
    start[1, :3] = [5.0, -2.0, 1.0]
    edges = _edges([(0, 1), (1, 2)], [_x(1.0), _x(1.0)])
    p = optimise_pose_graph(start, edges, fixed=1)
    np.testing.assert_allclose(p[1], start[1], atol=0)
    np.testing.assert_allclose(p[0, :3], [4.0, -2.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(p[2, :3], [6.0, -2.0, 1.0], atol=1e-6)


def _odo(v, w=(0.0, 0.0, 0.0)) -> SpatialOdometry:
    return SpatialOdometry(np.array(v, dtype=float), np.array(w, dtype=float), 1.0)


def test_dead_reckoning_and_edges_of_a_whisk_log_by_hand() -> None:
    odo = [None, _odo([1, 0, 0], [0, 0, math.pi / 2]), _odo([1, 0, 0]), _odo([1, 0, 0]), _odo([1, 0, 0])]
    dr = dead_reckoned_poses(odo)
    np.testing.assert_allclose(dr[:3, :3], [[0, 0, 0], [1, 0, 0], [1, 1, 0]], atol=1e-9)
    e = whisk_graph_edges(odo, [0, 1, 2, 0, 1], [False, False, False, True, True],
                          WhiskGraphConfig(closure_sigma_m=0.02, closure_sigma_deg=4.0))
    assert e.ends.tolist() == [[0, 1], [1, 2], [2, 3], [3, 4], [0, 3], [1, 4]]
    np.testing.assert_allclose(e.relative[1], _x(1.0), atol=1e-9)  # whisk 1 -> 2: one metre ahead
    np.testing.assert_allclose(e.relative[4:], [I7, I7], atol=0)  # closures: the same pose
    np.testing.assert_allclose(e.sigma_m, [0.01] * 4 + [0.02] * 2)
    np.testing.assert_allclose(e.sigma_rad, [math.radians(2.5)] * 4 + [math.radians(4.0)] * 2)


def test_a_switch_without_relocalisation_adds_no_closure() -> None:
    odo = [None, _odo([1, 0, 0]), _odo([1, 0, 0])]
    e = whisk_graph_edges(odo, [0, 1, 0], [False, False, False])
    assert e.ends.tolist() == [[0, 1], [1, 2]]


def _circle(n: int, loops: int) -> list[np.ndarray]:
    """Poses (4, 4) on a circle of radius 0.2 m, tool axis (+x) towards the centre."""
    out = []
    for k in range(n * loops):
        a = 2 * math.pi * (k % n) / n
        T = np.eye(4)
        T[:3, :3] = Rotation.from_euler("z", a + math.pi).as_matrix()
        T[:3, 3] = [0.2 * math.cos(a), 0.2 * math.sin(a), 0.0]
        out.append(T)
    return out


def test_closures_bring_a_noisy_loop_back_to_the_true_surface() -> None:
    """Four loops of 20 whisks around a circle, odometry with 2 deg / 5 mm noise per whisk, every
    later-loop whisk re-localised into its first-loop experience; contacts 0.1 m ahead. The stored
    surface of the pose graph is much closer to the truth than the dead-reckoned one (median error
    0.07-0.24 of it over seeds 0-9; 0.13-0.77 with two loops)."""
    rng = np.random.default_rng(3)
    n, loops = 20, 4
    T = _circle(n, loops)
    odo: list[SpatialOdometry | None] = [None]
    for k in range(1, len(T)):
        rel = np.linalg.inv(T[k - 1]) @ T[k]
        rv = (Rotation.from_matrix(rel[:3, :3]) * Rotation.from_rotvec(rng.normal(0, math.radians(2.0), 3))).as_rotvec()
        odo.append(_odo(rel[:3, 3] + rng.normal(0, 0.005, 3), rv))
    ids = [k % n for k in range(len(T))]
    reloc = [k >= n for k in range(len(T))]
    contacts = [np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.02]]) for _ in T]
    truth = np.concatenate([(T[k][:3, :3] @ c.T).T + T[k][:3, 3] - T[0][:3, 3] for k, c in enumerate(contacts)])
    truth = (T[0][:3, :3].T @ truth.T).T  # in the first whisk's frame
    dr = dead_reckoned_poses(odo)
    placed_dr = np.concatenate([dr[k, :3] + Rotation.from_quat(dr[k, 3:]).apply(c) for k, c in enumerate(contacts)])
    placed = whisk_surface(odo, ids, reloc, contacts)
    assert placed.shape == truth.shape
    err_dr = np.median(np.linalg.norm(placed_dr - truth, axis=1))
    err_pg = np.median(np.linalg.norm(placed - truth, axis=1))
    assert err_pg < 0.4 * err_dr, (err_pg, err_dr)


# --------------------------------------------------------------------------- typed errors
@settings(max_examples=25, deadline=None)
@given(st.one_of(st.just([[0.0] * 7, [np.nan] * 7]), st.just([[0.0] * 6] * 2), st.just([[0.0] * 7] * 2),
                 st.just("poses"), st.just(np.zeros((0, 7)))))
def test_bad_initial_poses_raise(poses: object) -> None:
    with pytest.raises((InvalidInputError, ShapeError)):
        optimise_pose_graph(poses, _edges([(0, 1)], [_x(1.0)]))


@settings(max_examples=25, deadline=None)
@given(st.one_of(
    st.just(_edges([(0, 2)], [_x(1.0)])),  # node out of range
    st.just(_edges([(1, 1)], [_x(1.0)])),  # a self loop
    st.just(_edges([(0, 1)], [[1.0, 0, 0, 0, 0, 0, 2.0]])),  # not a unit quaternion
    st.just(_edges([(0, 1)], [_x(1.0)], sigma_m=0.0)),
    st.just(_edges([(0, 1)], [_x(1.0)], sigma_rad=-1.0)),
    st.just(_edges([(0, 1)], [[np.nan] * 7])),
    st.just(PoseGraphEdges(np.array([[0.0, 1.0]]), np.array([_x(1.0)]), np.ones(1), np.ones(1))),  # float ends
    st.just("edges"),
))
def test_bad_edges_raise(edges: object) -> None:
    with pytest.raises((InvalidInputError, ShapeError)):
        optimise_pose_graph(np.tile(I7, (2, 1)), edges)  # type: ignore[arg-type]


@settings(max_examples=25, deadline=None)
@given(st.one_of(st.just(-1), st.just(2), st.just(True), st.just(0.5), st.just("0")))
def test_bad_fixed_node_raises(fixed: object) -> None:
    with pytest.raises(InvalidInputError):
        optimise_pose_graph(np.tile(I7, (2, 1)), _edges([(0, 1)], [_x(1.0)]), fixed=fixed)  # type: ignore[arg-type]


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(["odometry_sigma_m", "odometry_sigma_deg", "closure_sigma_m", "closure_sigma_deg"]),
       st.one_of(st.just(0), st.just(-1.0), st.just(float("nan")), st.just("x"), st.just(True)))
def test_bad_config_raises(field: str, value: object) -> None:
    with pytest.raises(ConfigError):
        WhiskGraphConfig(**{field: value})


def test_bad_whisk_logs_raise() -> None:
    odo = [None, _odo([1, 0, 0])]
    with pytest.raises(ShapeError):
        whisk_graph_edges(odo, [0], [False, False])
    with pytest.raises(InvalidInputError):
        whisk_graph_edges(odo, [0.0, 1.0], [False, False])
    with pytest.raises(InvalidInputError):
        whisk_graph_edges([None, "odometry"], [0, 1], [False, False])
    with pytest.raises(InvalidInputError):
        whisk_graph_edges(odo, [0, 1], [False, False], config="config")  # type: ignore[arg-type]
    with pytest.raises(ShapeError):
        whisk_surface(odo, [0, 1], [False, False], [None])
    with pytest.raises((InvalidInputError, ShapeError)):
        whisk_surface(odo, [0, 1], [False, False], [None, np.array([[np.nan, 0, 0]])])
    with pytest.raises(InvalidInputError):
        optimise_pose_graph(np.tile(I7, (2, 1)), _edges([(0, 1)], [_x(1.0)]), max_evaluations=0)


def test_whisk_surface_says_where_each_contact_was_felt_from() -> None:
    """Three whisks 1 m apart along x, no closure: the graph keeps dead reckoning, so the
    viewpoints are the whisk positions (0, 1, 2 m), one per contact; whisk 1 felt nothing."""
    odo = [None, _odo([1, 0, 0]), _odo([1, 0, 0])]
    contacts = [np.array([[0.1, 0.0, 0.0]]), None, np.array([[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])]
    points, seen = whisk_surface(odo, [0, 1, 2], [False] * 3, contacts, with_viewpoints=True)
    np.testing.assert_allclose(points, [[0.1, 0, 0], [2.1, 0, 0], [2.0, 0.2, 0]], atol=1e-9)
    np.testing.assert_allclose(seen, [[0, 0, 0], [2, 0, 0], [2, 0, 0]], atol=1e-9)
    np.testing.assert_allclose(whisk_surface(odo, [0, 1, 2], [False] * 3, contacts), points, atol=0)


def test_whisk_surface_in_an_anchors_frame() -> None:
    """``anchor``: the same three whisks with the first whisk at (1, 2, 3) m turned 90 deg about z - hand-placed:
    a point (x, y, z) of the first whisk's frame is at (1 - y, 2 + x, 3 + z); the viewpoints move alike."""
    odo = [None, _odo([1, 0, 0]), _odo([1, 0, 0])]
    contacts = [np.array([[0.1, 0.0, 0.0]]), None, np.array([[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]])]
    anchor = ([1.0, 2.0, 3.0], Rotation.from_euler("z", 90, degrees=True).as_quat())
    points, seen = whisk_surface(odo, [0, 1, 2], [False] * 3, contacts, with_viewpoints=True, anchor=anchor)
    np.testing.assert_allclose(points, [[1.0, 2.1, 3], [1.0, 4.1, 3], [0.8, 4.0, 3]], atol=1e-9)
    np.testing.assert_allclose(seen, [[1, 2, 3], [1, 4, 3], [1, 4, 3]], atol=1e-9)
    np.testing.assert_allclose(whisk_surface(odo, [0, 1, 2], [False] * 3, contacts, anchor=anchor), points, atol=0)
    for bad in ("pose", [1.0, 2.0], np.full((4, 4), np.nan)):
        with pytest.raises((InvalidInputError, ShapeError)):
            whisk_surface(odo, [0, 1, 2], [False] * 3, contacts, anchor=bad)


@settings(max_examples=50, deadline=None)
@given(st.one_of(st.floats(0.0, 1e3), st.just(-1.0), st.just(float("nan")), st.just(float("inf")), st.booleans(), st.none()))
@example(1.0)
@example(0.0)
def test_noise_models_for_an_odometry_scale_never_go_below_the_floor(scale):
    from maps.pose_graph import MIN_NOISE_SCALE, WhiskGraphConfig
    from maps.surface_match import SurfaceMatchConfig

    good = isinstance(scale, float) and math.isfinite(scale) and scale >= 0
    if not good:
        with pytest.raises(InvalidInputError, match="scale"):
            WhiskGraphConfig().for_odometry_scale(scale)
        with pytest.raises(InvalidInputError, match="scale"):
            SurfaceMatchConfig().for_odometry_scale(scale)
        return
    k = max(scale, 0.25)
    assert MIN_NOISE_SCALE == 0.25
    g = WhiskGraphConfig().for_odometry_scale(scale)  # Eq 6.9's 1 cm and Eq 6.6's 2.5 deg, times k; closures kept
    assert (g.odometry_sigma_m, g.odometry_sigma_deg, g.closure_sigma_m, g.closure_sigma_deg) == pytest.approx(
        (0.01 * k, 2.5 * k, 0.01, 3.0))
    m = SurfaceMatchConfig(seed=7).for_odometry_scale(scale)
    assert (m.rotation_sigma_deg, m.displacement_sigma_m) == pytest.approx((2.5 * k, 0.01 * k))
    assert m.seed == 7 and m.tolerance_m == SurfaceMatchConfig().tolerance_m
    if scale == 1.0:  # the thesis' noise: the defaults themselves, every field
        assert g == WhiskGraphConfig() and m == SurfaceMatchConfig(seed=7)
