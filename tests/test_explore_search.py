"""Search strategies (Sec 6.1.2) on hand-made maps."""

import math
from types import SimpleNamespace

import networkx as nx
import trimesh
import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from cansim.errors import CansimError, ConfigError, InvalidInputError
from cansim.explore.search import (
    DefaultSearch, FollowExperienceHistory, LeastSimilarRegion, ObjectView, SearchContext,
    active_strategy, cheapest_experience, make_strategy, similarity_rows,
)
from whisker_io.pose import Pose

I = [0.0, 0.0, 0.0, 1.0]


class _FrontEnd:
    """Stored regions with given (chi2, nmse) against the current region."""

    def __init__(self, chi2, nmse):
        self.chi2, self.nmse = np.array(chi2, float), np.array(nmse, float)

    def parse(self, obs):
        return obs, obs, obs

    def scores(self, f, s, m):
        return SimpleNamespace(chi2=self.chi2, nmse=self.nmse)


def _graph(edges):
    """Eq 6.3 weights by hand: w = w_t + w_r + 1 / n_l(target), n_l = links of the node."""
    g = nx.DiGraph()
    n_l = {}
    for a, b, _, _ in edges:
        n_l[a] = n_l.get(a, 0) + 1
        n_l[b] = n_l.get(b, 0) + 1
    for a, b, wt, wr in edges:
        g.add_edge(a, b, weight=wt + wr + 1.0 / n_l[b])
        g.add_edge(b, a, weight=wt + wr + 1.0 / n_l[a])
    return g


def _map(positions, view_ids, edges, history, current):
    poses = np.array([list(p) + I for p in positions], float)
    return SimpleNamespace(poses=poses, view_ids=np.array(view_ids), graph=_graph(edges), history=np.array(history), current_id=current)


def test_cheapest_path_cost_by_hand():
    # chain 0-1-2 and a shortcut 0-3-2: n_l = {0: 2, 1: 2, 2: 2, 3: 2}
    g = _graph([(0, 1, 0.1, 0.0), (1, 2, 0.1, 0.0), (0, 3, 0.05, 0.2), (3, 2, 0.05, 0.2)])
    t, cost = cheapest_experience(g, 0, [2])
    assert t == 2
    assert cost == pytest.approx((0.1 + 0.5) + (0.1 + 0.5))  # 1.2 < (0.25 + 0.5) * 2 = 1.5
    t, cost = cheapest_experience(g, 0, [2, 3])
    assert (t, cost) == (3, pytest.approx(0.75))
    assert cheapest_experience(g, 0, [99]) is None


def test_lsr_picks_least_similar_region_of_pair_of_maps():
    # object 0: regions 0, 1; object 1: regions 0, 1, 2. Least similar: object 1 region 2 (chi2 1.8)
    m0 = _map([(0, 0, 0), (0.1, 0, 0)], [0, 1], [(0, 1, 0.1, 0.0)], [0, 1], 0)
    m1 = _map([(0, 0, 0), (0.1, 0, 0), (0.2, 0, 0), (0.0, 0.1, 0)], [0, 1, 2, 2],
              [(0, 1, 0.1, 0.0), (1, 2, 0.1, 0.0), (0, 3, 0.1, 0.0)], [0, 1, 2, 3], 0)
    objs = [ObjectView(m0, _FrontEnd([1.2, 1.0], [0.5, 0.1]), 2, 2, 2),
            ObjectView(m1, _FrontEnd([1.0, 1.2, 1.8], [0.2, 0.9, 0.3]), 4, 3, 4, last_relocalised=0)]
    ctx = SearchContext(Pose([0, 0, 0.3]), objs, np.array([0.5, 1.0]), observation=object())
    rows = similarity_rows(ctx, [0, 1])
    assert rows[0, :2].tolist() == [1, 2]
    # chi2 ties (1.2) broken by NMSE descending: object 1 region 1 (0.9) before object 0 region 0 (0.5)
    assert rows[1, :2].tolist() == [1, 1] and rows[2, :2].tolist() == [0, 0]
    lsr = LeastSimilarRegion(step_m=0.03, along_surface=False)
    # region 2 lives at experiences 2 and 3; n_l = {0: 2, 1: 2, 2: 1, 3: 1}
    # path 0-1-2: (0.1 + 1/2) + (0.1 + 1/1) = 1.7; path 0-3: 0.1 + 1/1 = 1.1, the cheaper
    assert lsr.choose_target(ctx) == (1, 3)
    assert lsr.last_cost == pytest.approx(1.1)
    goal = lsr.propose(ctx)
    # experience 3 is 0.1 m along map y from the current (0); a 3-cm step that way
    np.testing.assert_allclose(goal.position_m, [0.0, 0.03, 0.3], atol=1e-12)
    # only objects with non-zero confidence are candidates
    ctx0 = SearchContext(Pose([0, 0, 0.3]), objs, np.array([0.5, 0.0]), observation=object())
    assert lsr.choose_target(ctx0)[0] == 0


def test_steps_along_the_surface_never_approach_it():
    # the array at the origin facing world +y (its axis); a target 0.1 m ahead and 0.1 m to the side (x), 0.1 m up
    m = _map([(0, 0, 0), (0.1, 0.1, 0.1)], [0, 1], [(0, 1, 0.1, 0.0)], [0, 1, 1], 0)
    objs = [ObjectView(m, _FrontEnd([1.0, 1.9], [0.0, 0.0]), 2, 2, 3, last_relocalised=0)]
    ctx = SearchContext(Pose([0, 0, 0.3]), objs, np.array([1.0]), observation=object(), relocalised=[(0, 0)])
    # FEH: flattened to the horizontal, without the part along y: 3 cm along x only
    np.testing.assert_allclose(FollowExperienceHistory().propose(ctx).position_m, [0.03, 0.0, 0.3], atol=1e-12)
    # without along_surface the horizontal step heads for the target, toward the surface too: 3 cm along (1, 1, 0)
    np.testing.assert_allclose(FollowExperienceHistory(along_surface=False).propose(ctx).position_m,
                               [0.03 / math.sqrt(2), 0.03 / math.sqrt(2), 0.3], atol=1e-12)
    # LSR: 3-D, without the part along y: 3 cm along (1, 0, 1)
    lsr = LeastSimilarRegion()
    assert lsr.choose_target(ctx) == (0, 1)
    np.testing.assert_allclose(lsr.propose(ctx).position_m, [0.03 / math.sqrt(2), 0.0, 0.3 + 0.03 / math.sqrt(2)], atol=1e-12)
    # a target straight ahead is reached at once (nothing to do along the surface): FEH plays on, to the history's end
    ahead = _map([(0, 0, 0), (0.0, 0.1, 0.0)], [0, 1], [(0, 1, 0.1, 0.0)], [0, 1], 0)
    ctx2 = SearchContext(Pose([0, 0, 0.3]), [ObjectView(ahead, None, 2, 2, 2)], np.array([1.0]), observation=object(),
                         relocalised=[(0, 0)])
    assert FollowExperienceHistory().propose(ctx2) is None
    for bad in (1, "yes", None):
        with pytest.raises(CansimError):
            FollowExperienceHistory(along_surface=bad)
        with pytest.raises(CansimError):
            LeastSimilarRegion(along_surface=bad)


def test_lsr_retargets_when_leader_changes():
    m = _map([(0, 0, 0), (0.5, 0, 0)], [0, 1], [(0, 1, 0.1, 0.0)], [0, 1], 0)
    objs = [ObjectView(m, _FrontEnd([0.1, 1.5], [0, 0]), 2, 2, 2), ObjectView(m, _FrontEnd([1.9, 0.1], [0, 0]), 2, 2, 2)]
    lsr = LeastSimilarRegion()
    lsr.propose(SearchContext(Pose([0, 0, 0.3]), objs, np.array([1.0, 0.0]), object()))
    assert lsr.target == (0, 1)
    lsr.propose(SearchContext(Pose([0, 0, 0.3]), objs, np.array([1.0, 0.5]), object()))
    assert lsr.target == (0, 1)  # same leader: kept
    lsr.propose(SearchContext(Pose([0, 0, 0.3]), objs, np.array([1.0, 2.0]), object()))
    assert lsr.target == (1, 0)  # overtaken: re-targeted (object 1's region 0 is least similar)


def test_feh_next_experience_flattened_3cm():
    m = _map([(0, 0, 0), (0.1, 0, 0.1), (0.2, 0, 0)], [0, 1, 2], [(0, 1, 0.1, 0), (1, 2, 0.1, 0)], [0, 0, 1, 2, 1, 0], 0)
    assert FollowExperienceHistory.next_in_history(m.history, 0) == 1
    assert FollowExperienceHistory.next_in_history(m.history, 1) == 2
    assert FollowExperienceHistory.next_in_history(np.array([0, 1]), 1) is None
    objs = [ObjectView(m, None, 3, 3, 6)]
    feh = FollowExperienceHistory()
    ctx = SearchContext(Pose([1.0, 1.0, 0.3]), objs, np.array([1.0]), object(), relocalised=[(0, 0)])
    goal = feh.propose(ctx)
    # target exp 1 is (+0.1, 0, +0.1) from the current: flattened to +x, 3 cm
    np.testing.assert_allclose(goal.position_m, [1.03, 1.0, 0.3], atol=1e-12)
    assert FollowExperienceHistory().propose(SearchContext(Pose([0, 0, 0]), objs, np.array([1.0]))) is None


def test_default_search_visits_every_face_closest_first():
    d = DefaultSearch([0, 0, 0.175], 0.225, seed=4)
    seen = []
    for _ in range(len(d.directions)):
        d.propose()
        seen.append(d.current)
    assert sorted(seen) == list(range(len(d.directions)))
    assert seen[0] == DefaultSearch([0, 0, 0.175], 0.225, seed=4).next_face()
    # faces of one seed differ from another for most seeds
    starts = {DefaultSearch([0, 0, 0], 0.2, seed=s).next_face() for s in range(10)}
    assert len(starts) > 3
    # every step goes to the closest unvisited face
    d2 = DefaultSearch([0, 0, 0], 0.2, seed=1)
    a = d2.next_face()
    b = d2.next_face()
    others = np.delete(np.arange(len(d2.directions)), a)
    dist = np.linalg.norm(d2.directions[others] - d2.directions[a], axis=1)
    assert np.linalg.norm(d2.directions[b] - d2.directions[a]) == pytest.approx(dist.min())
    # the pose faces the centre with the bases on the sphere
    p = d2.face_pose(b)
    np.testing.assert_allclose(p.rotation.as_matrix()[:, 1], -d2.directions[b], atol=1e-12)
    assert np.linalg.norm(p.position_m) == pytest.approx(0.2 + 0.2019)


def test_switching_rules():
    assert active_strategy("lsr", np.zeros(2), True) == "default"
    assert active_strategy("lsr", np.array([0, 0.1]), False) == "default"
    assert active_strategy("feh", np.array([0, 0.1]), True) == "feh"
    with pytest.raises(ConfigError):
        active_strategy("random", np.zeros(2), True)
    with pytest.raises(ConfigError):
        make_strategy("bogus")


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3), st.none()))
@example(1e300)  # a huge semi-axis overflowed the norms: NaN/inf face directions and distances, no error
@example(10**400)  # an int too large for a float: OverflowError
@example(math.inf)  # subdivisions: OverflowError
def test_bad_constructor_input_typed(x):
    for make in (lambda: FollowExperienceHistory(step_m=x), lambda: LeastSimilarRegion(step_m=x),
                 # reach_m / seed None is valid (one step / a fresh seed), so is a huge int seed:
                 # a negative value stands for them here
                 lambda: FollowExperienceHistory(reach_m=-1.0 if x is None else x),
                 lambda: LeastSimilarRegion(reach_m=-1.0 if x is None else x),
                 lambda: DefaultSearch([0, 0, x], 0.2), lambda: DefaultSearch([0, 0, 0], x),
                 lambda: DefaultSearch([0, 0, 0], 0.2, semi_axes_m=[0.1, x, 0.2]),
                 lambda: DefaultSearch([0, 0, 0], 0.2, clearance_m=x),
                 lambda: DefaultSearch([0, 0, 0], 0.2, subdivisions=x),
                 lambda: DefaultSearch([0, 0, 0], 0.2, seed=-1 if x is None or isinstance(x, int) else x),
                 lambda: DefaultSearch([0, 0, 0], 0.2, footprint_m=[[0.0, x, 0.0]])):
        try:
            made = make()
        except CansimError:
            continue
        assert isinstance(x, float) and math.isfinite(x)
        if isinstance(made, DefaultSearch):  # every face has a finite pose
            assert np.isfinite(made.directions).all() and np.isfinite(made.distance_m).all()
            assert np.isfinite(made.face_pose(0).position_m).all()


def test_ellipsoid_faces_and_the_mapping_tour():
    import trimesh

    c, axes = np.array([0.0, 0.0, 0.2]), np.array([0.17, 0.17, 0.3])
    # a sphere's semi-axes give the sphere's faces
    np.testing.assert_allclose(DefaultSearch(c, 0.3, semi_axes_m=(0.3, 0.3, 0.3)).directions, DefaultSearch(c, 0.3).directions)
    e = DefaultSearch(c, 0.3, semi_axes_m=axes, seed=2)
    ico = trimesh.creation.icosphere(subdivisions=1)
    ico.apply_transform(np.diag([*axes, 1.0]))  # trimesh's own scaling: face centroids of the ellipsoid mesh
    cent = ico.triangles_center
    np.testing.assert_allclose(e.directions, cent / np.linalg.norm(cent, axis=1, keepdims=True), atol=1e-12)
    for f in (0, 17, 55):  # without a mesh the whisker bases sit on the ellipsoid, the array facing the centre
        p = e.face_pose(f)
        y = p.rotation.as_matrix()[:, 1]
        np.testing.assert_allclose(y, -e.directions[f], atol=1e-12)
        bases = p.position_m + 0.2019 * y
        assert np.sum(((bases - c) / axes) ** 2) == pytest.approx(1.0)
    n = len(e.directions)
    tour = DefaultSearch(c, 0.3, semi_axes_m=axes, seed=2).tour(2)
    key = [tuple(np.round(p.position_m, 9)) for p in tour]
    assert len(tour) == 2 * n - 1  # the loops share the face where the first ends
    assert len(set(key[:n])) == n and set(key[n - 1:]) == set(key[:n])  # each loop visits every face once
    assert tour[0] == e.face_pose(e.next_face())  # the seed's start face first
    high = DefaultSearch(c, 0.3, semi_axes_m=axes, seed=2).tour(1, accept=lambda p: p.position_m[2] > 0.2)
    assert 0 < len(high) < n and all(p.position_m[2] > 0.2 for p in high)
    for bad in (0, 1.5, True, "2"):
        with pytest.raises(CansimError):
            e.tour(bad)
    with pytest.raises(CansimError):
        DefaultSearch(c, 0.3, semi_axes_m=(0.1, 0.0, 0.2))


def test_footprint_keeps_every_point_clear_of_the_believed_volume():
    import trimesh

    box = trimesh.creation.box(bounds=[[-0.1, -0.1, 0.0], [0.1, 0.1, 0.35]])
    c = np.array([0.0, 0.0, 0.175])
    # two points 5 cm either side of the array's axis, one 4 cm back from the bases' plane (y = 0.2019)
    foot = np.array([[0.05, 0.2019, 0.0], [-0.05, 0.1619, 0.0]])
    plain = DefaultSearch(c, 0.225, mesh=box, seed=0)
    fp = DefaultSearch(c, 0.225, mesh=box, seed=0, footprint_m=foot, clearance_m=0.02)
    for f in range(len(fp.directions)):
        p = fp.face_pose(f)
        pts = p.apply(foot)
        assert not box.contains(pts).any()
        y = p.rotation.as_matrix()[:, 1]
        # the ray along y from each point: the nearest hit is exactly the clearance ahead (when one hits)
        locs, rays, _ = box.ray.intersects_location(pts, np.repeat(y[None], 2, axis=0), multiple_hits=False)
        if len(locs):
            assert min(np.linalg.norm(locs - pts[rays], axis=1)) == pytest.approx(0.02, abs=1e-9)
    # a face straight along +x of the box's centre, by hand: the face plane x = 0.1, the axis point 2 cm before it
    u = np.array([1.0, 0.0, 0.0])
    one = DefaultSearch(c, 0.225, mesh=box, clearance_m=0.02, footprint_m=[[0.0, 0.2019, 0.0]])
    one.directions = u[None]
    one.distance_m = np.array([0.225])
    one._clear(box, np.array([[0.0, 0.2019, 0.0]]), 0.02)
    assert one.distance_m[0] == pytest.approx(0.1 + 0.02)
    # the default footprint is the single axis point: the central ray, as without footprint_m
    np.testing.assert_allclose(plain.distance_m, DefaultSearch(c, 0.225, mesh=box, seed=0, footprint_m=[[0, 0.2019, 0]]).distance_m)
    for bad in ([[0.0, 0.2]], [[np.nan, 0, 0]], np.zeros((0, 3)), "x"):
        with pytest.raises(CansimError):
            DefaultSearch(c, 0.225, mesh=box, footprint_m=bad)
    with pytest.raises(CansimError):
        DefaultSearch(c, 0.225, clearance_m=float("nan"))


def test_feh_plays_the_history_on_from_a_reached_target():
    # history 0, 0, 1, 2, 1, 0; the array stands at experience 1 (the map's current experience)
    m = _map([(0, 0, 0), (0.1, 0, 0.1), (0.2, 0, 0)], [0, 1, 2], [(0, 1, 0.1, 0), (1, 2, 0.1, 0)], [0, 0, 1, 2, 1, 0], 1)
    objs = [ObjectView(m, None, 3, 3, 6)]
    feh = FollowExperienceHistory()
    assert feh.following(m.history, 1) == (1, 2) and feh.following(m.history, 3) == (1, 4) and feh.following(m.history, 5) is None
    goal = feh.propose(SearchContext(Pose([1.0, 1.0, 0.3]), objs, np.array([1.0]), object(), relocalised=[(0, 0)]))
    # target 1 (after the first visit of 0) is where the array is: reached, so the next in the history, 2,
    # lying (+0.1, 0, -0.1) from experience 1: flattened to +x, 3 cm
    assert feh.target == (0, 2)
    np.testing.assert_allclose(goal.position_m, [1.03, 1.0, 0.3], atol=1e-12)
    # at the end of the history there is nothing to follow
    m.current_id = 0
    feh2 = FollowExperienceHistory()
    feh2.target, feh2._index = (0, 0), 5
    assert feh2.propose(SearchContext(Pose([0, 0, 0.3]), objs, np.array([1.0]), object())) is None and feh2.target is None


def test_lsr_follows_the_dijkstra_path_experience_by_experience():
    # a chain 0 - 1 - 2 along map x; region 2 (experience 2) is the least similar
    m = _map([(0, 0, 0), (0.1, 0, 0), (0.2, 0, 0)], [0, 1, 2], [(0, 1, 0.1, 0.0), (1, 2, 0.1, 0.0)], [0, 1, 2], 0)
    objs = [ObjectView(m, _FrontEnd([0.1, 0.5, 1.9], [0, 0, 0]), 3, 3, 3, last_relocalised=0)]
    lsr = LeastSimilarRegion()
    goal = lsr.propose(SearchContext(Pose([0, 0, 0.3]), objs, np.array([1.0]), object()))
    assert lsr.target == (0, 2) and lsr.path == [1, 2]
    np.testing.assert_allclose(goal.position_m, [0.03, 0, 0.3], atol=1e-12)  # toward experience 1 first
    m.current_id = 1  # the array is at experience 1: reached, on to 2 (0.1 m further along x)
    goal = lsr.propose(SearchContext(Pose([0.1, 0, 0.3]), objs, np.array([1.0]), object()))
    assert lsr.path == [2] and lsr.target == (0, 2)
    np.testing.assert_allclose(goal.position_m, [0.13, 0, 0.3], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.one_of(st.integers(-3, 0), st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3), st.none(), st.booleans()))
def test_tour_bad_loop_counts_typed(n):
    d = DefaultSearch([0, 0, 0.2], 0.3, seed=1)
    before = (d.current, d.visited.copy())
    with pytest.raises(CansimError):
        d.tour(n)
    assert d.current == before[0] and (d.visited == before[1]).all()  # nothing advanced


@pytest.mark.parametrize("mesh", [3, "box", np.zeros((3, 3)), trimesh.Trimesh()])
def test_a_mesh_that_is_not_a_mesh_is_a_typed_error(mesh):
    """DefaultSearch(mesh=3) raised AttributeError (issue 25)."""
    with pytest.raises(InvalidInputError, match="trimesh.Trimesh"):
        DefaultSearch([0, 0, 0], 0.2, mesh=mesh)


def test_a_search_radius_in_millimetres_is_refused():
    """A believed volume given in millimetres (radius 350) was accepted; every face lay 350 m out."""
    from cansim.errors import ConfigError

    with pytest.raises(ConfigError, match="millimetres"):
        DefaultSearch((0.0, 0.0, 0.0), 350.0)
    assert DefaultSearch((0.0, 0.0, 0.0), 0.35).radius_m == 0.35
