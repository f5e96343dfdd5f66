"""SE(3) map geometry: Alg 6 / Eq 5.13-5.15 accumulation, the relaxation kernel against scipy, persistence."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from maps.experience_map import ExperienceMap, MapConfig
from maps.odometry import SpatialOdometry
from maps.se3 import SE3Geometry
from whisker_io.errors import CorruptFileError, InvalidInputError, ShapeError


def test_alg6_quarter_turn_by_hand():
    g = SE3Geometry()
    acc = g.initial_accumulator()
    g.accumulate(acc, SpatialOdometry([0, 0, 0], [0, 0, math.pi / 2], 1.0))
    np.testing.assert_allclose(acc[3:], [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)], atol=1e-15)


def test_closed_rotation_loop_accumulates_to_identity():
    g = SE3Geometry()
    acc = g.initial_accumulator()
    for axis in range(3):  # a full turn about x, then y, then z, in 7 unequal pieces each
        for frac in (0.1, 0.2, 0.05, 0.15, 0.3, 0.12, 0.08):
            w = np.zeros(3)
            w[axis] = 2 * math.pi * frac
            g.accumulate(acc, SpatialOdometry([0, 0, 0], w, 1.0))
    assert Rotation.from_quat(acc[3:]).magnitude() < 1e-9


def test_eq_5_13_displacement_is_rotated_into_the_experience_frame():
    g = SE3Geometry()
    acc = g.initial_accumulator()
    g.accumulate(acc, SpatialOdometry([1, 0, 0], [0, 0, math.pi / 2], 1.0))  # 1 m along x, then a quarter turn
    g.accumulate(acc, SpatialOdometry([2, 0, 0], [0, 0, 0], 1.0))  # 2 m along the new body x = old +y
    np.testing.assert_allclose(acc[:3], [1, 2, 0], atol=1e-12)
    # a new experience from a base at (10, 0, 0) turned by pi about z: p = p_e + R(q_e) d
    base = np.array([10, 0, 0, 0, 0, 1, 0], dtype=float)
    pose = g.new_pose(base, acc)
    np.testing.assert_allclose(pose[:3], [9, -2, 0], atol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(pose[3:]).as_rotvec(), [0, 0, -math.pi / 2], atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-2, 2), min_size=3, max_size=3), st.lists(st.floats(-3, 3), min_size=3, max_size=3),
       st.floats(0.01, 2.0), st.integers(0, 2**31 - 1))
def test_compiled_accumulation_equals_the_scipy_form(v, w, dt, seed):
    q0 = Rotation.random(random_state=seed)
    acc = [0.3, -0.1, 0.2, *q0.as_quat()]
    SE3Geometry().accumulate(acc, SpatialOdometry(v, w, dt))
    d = np.array([0.3, -0.1, 0.2]) + q0.apply(np.array(v) * dt)
    q = q0 * Rotation.from_rotvec(np.array(w) * dt)
    np.testing.assert_allclose(acc[:3], d, atol=1e-12)
    assert (Rotation.from_quat(acc[3:]).inv() * q).magnitude() < 1e-10


def _reference_relax(poses, ends, links, c, order):
    """The same Gauss-Seidel update written with scipy's Rotation (the kernel's oracle)."""
    poses = poses.copy()
    for k in order:
        f, t = ends[k]
        qf, qt = Rotation.from_quat(poses[f, 3:]), Rotation.from_quat(poses[t, 3:])
        dq = Rotation.from_quat(links[k, 3:7])
        res = poses[t, :3] - (poses[f, :3] + qf.apply(links[k, :3]))
        poses[f, :3] += res * c
        poses[t, :3] -= res * c
        r = ((qf * dq).inv() * qt).as_rotvec()
        poses[t, 3:] = (qt * Rotation.from_rotvec(-c * r)).as_quat()
        poses[f, 3:] = (qf * dq * Rotation.from_rotvec(c * r) * dq.inv()).as_quat()
    return poses


def _same_rotation(a, b):
    return (Rotation.from_quat(a).inv() * Rotation.from_quat(b)).magnitude()


def test_relax_kernel_equals_the_scipy_reference():
    rng = np.random.default_rng(3)
    n, m = 6, 9
    poses = np.hstack([rng.normal(size=(n, 3)), Rotation.random(n, random_state=1).as_quat()])
    ends = np.array([(i, (i + 1) % n) for i in range(n)] + [(0, 3), (1, 4), (2, 5)], dtype=np.int64)
    links = np.hstack([rng.normal(size=(m, 3)), Rotation.random(m, random_state=2).as_quat(), np.ones((m, 1))])
    order = np.arange(m, dtype=np.int64)
    expected = _reference_relax(poses, ends, links, 0.5, list(order) * 3)
    got = poses.copy()
    end = SE3Geometry().relax(order, ends, links, got, 0.5, 3 * m, 0)
    assert end == 0
    np.testing.assert_allclose(got[:, :3], expected[:, :3], atol=1e-10)
    assert max(_same_rotation(got[i, 3:], expected[i, 3:]) for i in range(n)) < 1e-10


def _random_graph(seed, n=12, m=40):
    """Random poses and links (repeated and reversed pairs included) for the kernel-vs-scipy checks."""
    rng = np.random.default_rng(seed)
    poses = np.hstack([rng.normal(size=(n, 3)), Rotation.random(n, random_state=seed).as_quat()])
    ends = rng.integers(0, n, (m, 2))
    ends[:, 1] = np.where(ends[:, 0] == ends[:, 1], (ends[:, 1] + 1) % n, ends[:, 1])
    links = np.hstack([rng.normal(size=(m, 3)), Rotation.random(m, random_state=seed + 100).as_quat(), np.ones((m, 1))])
    return poses, ends.astype(np.int64), links, rng.permutation(m).astype(np.int64)


@pytest.mark.parametrize("c", [0.5, 0.3, 0.85])  # 0.5 takes the midpoint form, the others the slerp
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_relax_kernel_equals_the_scipy_reference_to_1e_12(c, seed):
    poses, ends, links, order = _random_graph(seed)
    expected = _reference_relax(poses, ends, links, c, list(order) * 5)
    got = poses.copy()
    SE3Geometry().relax(order, ends, links, got, c, 5 * len(order), 0)
    np.testing.assert_allclose(got[:, :3], expected[:, :3], rtol=0, atol=1e-12)
    assert max(_same_rotation(got[i, 3:], expected[i, 3:]) for i in range(len(poses))) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(got[:, 3:], axis=1), 1.0, rtol=0, atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-10, 10), min_size=3, max_size=3), st.lists(st.floats(-10, 10), min_size=3, max_size=3),
       st.integers(0, 2**31 - 1))
def test_new_pose_equals_the_scipy_composition(p, d, seed):
    qe, q = Rotation.random(2, random_state=seed)
    got = SE3Geometry().new_pose(np.array([*p, *qe.as_quat()]), [*d, *q.as_quat()])
    np.testing.assert_allclose(got[:3], np.array(p) + qe.apply(np.array(d)), rtol=0, atol=1e-12)
    assert (Rotation.from_quat(got[3:]).inv() * qe * q).magnitude() < 1e-12
    assert abs(math.sqrt(sum(v * v for v in got[3:])) - 1.0) < 1e-15


def test_one_link_at_half_correction_closes_its_residual():
    poses = np.array([[0, 0, 0, 0, 0, 0, 1], [1, 1, 0, *Rotation.from_rotvec([0, 0, 0.4]).as_quat()]], dtype=float)
    links = np.array([[1, 0, 0, 0, 0, 0, 1, 1.0]])
    ends = np.array([[0, 1]], dtype=np.int64)
    SE3Geometry().relax(np.array([0]), ends, links, poses, 0.5, 1, 0)
    qf, qt = Rotation.from_quat(poses[0, 3:]), Rotation.from_quat(poses[1, 3:])
    # positions are corrected with the source orientation before the update (identity), as Eq 2.25 in 2-D
    np.testing.assert_allclose(poses[1, :3], poses[0, :3] + [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(poses[0, :3], [0, 0.5, 0], atol=1e-12)
    assert (qf.inv() * qt).magnitude() < 1e-12
    assert qt.magnitude() == pytest.approx(0.2, abs=1e-12)  # both ends met half way


def _loop_map(relax_passes):
    """A unit square whose odometry over-reads the second side by 0.3 m and the first turn by 0.2 rad, closed at view 0."""
    em = ExperienceMap(MapConfig(pc_shape=(5,) * 6, offset_axes=(), relax_passes=relax_passes, relax_budget=None,
                                 match_distance_cells=1.0), SE3Geometry())
    cells = [(0, 0, 0, 0, 0, 0), (2, 0, 0, 0, 0, 1), (2, 2, 0, 0, 0, 2), (0, 2, 0, 0, 0, 3)]
    em.update(cells[0], 0, 0)
    for k in range(1, 5):
        em.on_odo([1.3 if k == 2 else 1.0, 0, 0], [0, 0, math.pi / 2 + (0.2 if k == 1 else 0.0)], 1.0)
        em.update(cells[k % 4], k % 4, k - 1)
    assert em.n_experiences == 4 and em.current_id == 0 and em.n_links == 4
    return em


def _errors(em):
    """Summed position (m) and rotation (rad) error of the map against the true unit square, frame-free."""
    truth = [np.array(p, dtype=float) for p in ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0))]
    p = em.poses
    q0 = Rotation.from_quat(p[0, 3:])
    perr = sum(np.linalg.norm(q0.inv().apply(p[i, :3] - p[0, :3]) - truth[i]) for i in range(4))
    rerr = sum((Rotation.from_rotvec([0, 0, i * math.pi / 2]).inv() * q0.inv() * Rotation.from_quat(p[i, 3:])).magnitude()
               for i in range(4))
    return perr, rerr


def test_relaxation_moves_an_inconsistent_loop_toward_the_least_squares_layout():
    raw_p, raw_r = _errors(_loop_map(0))
    relaxed_p, relaxed_r = _errors(_loop_map(20))
    assert raw_p > 0.15 and raw_r > 0.15  # the injected inconsistency is visible
    assert relaxed_p < 0.6 * raw_p and relaxed_r < 0.6 * raw_r


def test_graph_weights_follow_eq_6_3():
    em = _loop_map(0)
    g = em.graph
    assert g.number_of_nodes() == 4 and g.number_of_edges() == 8  # 4 links, both directions
    e = g.edges[0, 1]
    # link 0->1: 1 m and a turn of pi/2 + 0.2; node 1 has 2 links
    assert e["weight"] == pytest.approx(1.0 + math.pi / 2 + 0.2 + 1 / 2)
    em.on_odo([1.0, 0, 0], [0, 0, 0], 1.0)
    em.update((4, 4, 4, 4, 4, 4), 7, 0)  # a new experience linked from 0: node 0 now has 3 links
    assert g.edges[1, 0]["weight"] == pytest.approx(1.0 + math.pi / 2 + 0.2 + 1 / 3)


def test_save_load_round_trip_is_exact(tmp_path):
    em = _loop_map(5)
    em.save(tmp_path / "m.npz")
    back = ExperienceMap.load(tmp_path / "m.npz")
    assert back.poses.tobytes() == em.poses.tobytes()
    assert all(a.tobytes() == b.tobytes() for a, b in zip(back.links, em.links))
    assert back.accumulator == em.accumulator and isinstance(back.geometry, SE3Geometry)
    arrays = dict(np.load(tmp_path / "m.npz"))
    arrays["exp_pose"] = arrays["exp_pose"] * 2
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(CorruptFileError, match="exp_pose"):
        ExperienceMap.load(tmp_path / "bad.npz")


finite = st.floats(-1e3, 1e3)
bad = st.sampled_from([math.nan, math.inf, -math.inf])


@settings(max_examples=60, deadline=None)
@given(st.lists(finite, min_size=3, max_size=3), st.lists(finite, min_size=3, max_size=3), st.floats(0, 10),
       st.integers(0, 8), bad)
def test_spatial_odometry_rejects_bad_input_and_map_state_is_unchanged(v, w, dt, where, value):
    em = _loop_map(1)
    before = (em.accumulator, em.accum_time_s)
    fields = [list(v), list(w), dt]
    if where < 3:
        fields[0][where] = value
    elif where < 6:
        fields[1][where - 3] = value
    elif where == 6:
        fields[2] = value
    elif where == 7:
        fields[2] = -1.0 - dt
    else:
        fields[0] = fields[0][:2]
    with pytest.raises((InvalidInputError, ShapeError)):
        em.on_odo(*fields)
    assert (em.accumulator, em.accum_time_s) == before


def test_huge_odometry_is_rejected_not_hanging():
    from maps.odometry import PlanarOdometry

    with pytest.raises(InvalidInputError, match="split"):
        PlanarOdometry(0.0, 1.0, 1e17)
    em = ExperienceMap()
    with pytest.raises(InvalidInputError):
        em.on_odo(0.0, 1.0, 1e17)
    with pytest.raises(InvalidInputError):
        SpatialOdometry([1e300, 0, 0], [0, 0, 0], 1.0)


def test_object_map_resets_the_accumulator_at_the_first_experience():
    """Motion before the first experience is not counted again in the next link (Alg 6)."""
    from maps.object_map import ObjectMap

    om = ObjectMap()
    om.on_odo([0.2, 0, 0], [0, 0, 0], 1.0)
    om.update((0,) * 6, 0, 0)  # first experience at the accumulated pose (0.2, 0, 0)
    om.on_odo([0.1, 0, 0], [0, 0, 0], 1.0)
    om.update((2,) * 6, 1, 0)
    np.testing.assert_allclose(om.poses[1, :3], [0.3, 0, 0], atol=1e-12)
    np.testing.assert_allclose(om.links[1][0, :3], [0.1, 0, 0], atol=1e-12)


def _wandering_object_map(seed, n_steps=60, n_views=9):
    """An object map from random whisks over a few views (new experiences, links and re-localisations)."""
    from maps.object_map import ObjectMap

    rng = np.random.default_rng(seed)
    om = ObjectMap()
    for _ in range(n_steps):
        om.on_odo(rng.normal(0, 0.05, 3), rng.normal(0, 0.4, 3), 1.0)
        om.update(tuple(rng.uniform(0, 5, 6)), int(rng.integers(0, n_views)), 0)
        om.record()
    return om


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gated_views_equal_the_gate_written_with_numpy(seed):
    om = _wandering_object_map(seed)
    rng = np.random.default_rng(seed + 10)
    n = om.n_experiences
    pose = np.array([*rng.normal(0, 0.05, 3), *Rotation.random(random_state=seed).as_quat()])
    gate_m, gate_rad = rng.uniform(0.01, 0.3, n), rng.uniform(0.1, 3.0, n)
    consistent, cost = om.gated_views(pose, gate_m, gate_rad, 12)
    poses, views = om.poses, om.view_ids
    dp = np.linalg.norm(poses[:, :3] - pose[:3], axis=1)
    dr = 2 * np.arccos(np.minimum(np.abs(poses[:, 3:] @ pose[3:]), 1.0))
    np.testing.assert_allclose(om.pose_distances(pose), (dp, dr), rtol=0, atol=1e-12)
    ok = (dp <= gate_m) & (dr <= gate_rad)
    want_c = np.zeros(12, dtype=bool)
    want_c[views[ok]] = True
    want = np.full(12, np.inf)
    np.minimum.at(want, views[ok], (dp / gate_m + dr / gate_rad)[ok])
    assert 0 < ok.sum() < n  # the gates keep some experiences and drop others
    np.testing.assert_array_equal(consistent, want_c)
    np.testing.assert_allclose(cost, np.where(want_c, want, 0.0), rtol=1e-12, atol=0)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["pose_nan", "pose_short", "pose_non_unit", "gate_short", "gate_2d", "gate_text", "gate_nan",
                        "gate_negative", "few_views", "views_negative", "views_text"]))
def test_gated_views_rejects_bad_input(kind):
    om = _wandering_object_map(0, n_steps=12)
    n = om.n_experiences
    pose, gm, gr, nv = [0, 0, 0, 0, 0, 0, 1.0], np.full(n, 0.1), np.full(n, 0.5), 9
    if kind == "pose_nan":
        pose = [math.nan, 0, 0, 0, 0, 0, 1.0]
    elif kind == "pose_short":
        pose = pose[:6]
    elif kind == "pose_non_unit":
        pose = [0, 0, 0, 0, 0, 0, 2.0]
    elif kind == "gate_short":
        gm = gm[:-1]
    elif kind == "gate_2d":
        gr = np.full((n, 2), 0.5)
    elif kind == "gate_text":
        gm = ["a"] * n
    elif kind == "gate_nan":
        gr = np.full(n, math.nan)
    elif kind == "gate_negative":
        gm = np.full(n, -0.1)
    elif kind == "few_views":
        nv = int(om.view_ids.max())
    else:
        nv = -1 if kind == "views_negative" else "9"
    with pytest.raises((InvalidInputError, ShapeError)):
        om.gated_views(pose, gm, gr, nv)
