"""Explorer metrics (IM, SRT from hand-made IC traces) and a short simulated run through the safety envelope."""

import logging
import math

import numpy as np
import pytest

from cansim.errors import CansimError, ConfigError, InvalidInputError
from cansim.explore.explorer import ic_metrics


def test_im_srt_from_hand_made_traces():
    ic = np.array([[0, 0], [50, 10], [120, 40], [200, 90], [310, 150], [400, 310]], float)
    m = ic_metrics(ic, correct=0, threshold=300)
    assert (m.srt, m.im, m.identity, m.correct_first) == (4.0, 1.0, 0, True)
    m = ic_metrics(ic, correct=1, threshold=300)
    assert (m.srt, m.im, m.identity, m.correct_first) == (5.0, -1.0, 0, False)
    # never crossed: censored at n dt = 6
    m = ic_metrics(ic, correct=0, threshold=350)
    assert (m.srt, m.im, m.correct_first) == (5.0, 1.0, True)
    m = ic_metrics(ic, correct=0, threshold=1000, dt=0.5)
    assert (m.srt, m.im, m.identity, m.correct_first) == (3.0, 0.0, None, False)


@pytest.mark.parametrize("bad", [np.zeros(3), np.full((2, 2), np.nan), np.zeros((0, 2)).reshape(0, 2, 1)])
def test_bad_traces(bad):
    with pytest.raises(CansimError):
        ic_metrics(bad, 0, 300)
    with pytest.raises(CansimError):
        ic_metrics(np.zeros((3, 2)), 2, 300)
    with pytest.raises(CansimError):
        ic_metrics(np.zeros((3, 2)), 0, math.nan)


# ------------------------------------------------------------------ the loop (SimArm, Box)
from hypothesis import HealthCheck, example, given, settings, strategies as st  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from maps.odometry import SpatialOdometry  # noqa: E402

from cansim.explore.explorer import Explorer, build_object_model  # noqa: E402
from cansim.explore.placement import PlacementParams  # noqa: E402
from maps.surface_match import SurfaceMatchConfig  # noqa: E402
from cansim.explore.search import DefaultSearch  # noqa: E402
from whisker_io.errors import SafetyViolationError  # noqa: E402

#: T_pfh, T_sda of the Ch.6 experiment's calibration at the Sec 6.1.3.1.2 noise (0.75 quantile).
PFH_T, SDA_T = 1.2, 1.29
#: The object stands on z = 0 (0.35 m tall): the floor at z = 0.15 m makes about half the sphere's faces unreachable.
WORKSPACE = dict(workspace_min=(-0.75, -0.75, 0.15), workspace_max=(0.75, 0.75, 1.0), max_tool_tilt=math.pi)


def _model():
    from cansim.frontends.whisk import WhiskFrontEndConfig
    from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig

    fe = WhiskFrontEndConfig(features="both", pfh_threshold=PFH_T, sda_threshold=SDA_T, feature_update=False)
    return WhiskerRatSLAM(WhiskerRatSLAMConfig(cell_size_m=0.03, frontend=fe))


def _odometry(seed):
    from whisker_io.sim.odometry_noise import noisy_odometry

    rng = np.random.default_rng(seed)
    return lambda a, b: noisy_odometry(a, b, rng)


@pytest.fixture(scope="module")
def world():
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    known, chains = [], {}
    for i, name in enumerate(("box", "box_stack")):
        mesh = make_object(name)
        chain = WhiskChain(mesh, contact_model="tip")
        rng = np.random.default_rng(10 + i)
        traj = object_trajectory(mesh, "A", n_loops=1)
        known.append(build_object_model(name, traj, lambda p, c=chain, r=rng: c.features(p, r), _odometry(i),
                                        placement=PlacementParams(roll_rad=math.pi / 2), model=_model()))
        chains[name] = (mesh, chain)
    return known, chains


class CountingArm:
    """A SimArm wrapper that counts the refusals itself (independent of the explorer's count)."""

    def __init__(self, arm):
        self.arm, self.refused = arm, 0

    def pose(self):
        return self.arm.pose()

    def move_linear(self, goal):
        try:
            return self.arm.move_linear(goal)
        except SafetyViolationError:
            self.refused += 1
            raise


def _explorer(world, strategy="lsr", seed=3, n=60, spc=True):
    from whisker_io.hw.arm import SimArm
    from whisker_io.hw.safety import SafetyEnvelope

    known, chains = world
    mesh, chain = chains["box_stack"]
    search = DefaultSearch(mesh.bounds.mean(axis=0), float(np.linalg.norm(mesh.extents)) / 2, mesh=mesh, seed=seed)
    env = SafetyEnvelope(**WORKSPACE)
    search.current = int(np.argmax([search.face_pose(i).position_m[2] for i in range(len(search.directions))]))
    arm = CountingArm(SimArm(search.face_pose(search.current), env))
    rng = np.random.default_rng(seed)
    cycles = []

    def sensor(pose):
        f = chain.features(pose, rng)
        cycles.append((pose, f))
        return f

    ex = Explorer(known, sensor, arm, _odometry(100 + seed), search, strategy=strategy,
                  placement=PlacementParams(roll_rad=math.pi / 2) if spc else None, stop_threshold=math.inf, max_iterations=n)
    return ex, arm, env, cycles


@pytest.mark.parametrize("strategy,spc", [("default", False), ("feh", False), ("lsr", False), ("lsr", True)])
def test_run_keeps_every_command_inside_the_envelope_and_replans_refusals(world, strategy, spc, caplog):
    ex, arm, env, cycles = _explorer(world, strategy, spc=spc, n=60 if not spc else 150)
    with caplog.at_level(logging.DEBUG, logger="cansim"):
        res = ex.run()
    n = len(res.ic)
    assert n == (60 if not spc else 150) == len(res.poses) == len(res.strategies) and res.stop_reason == "iterations"
    sent = [c for c in arm.arm.received if c.kind == "moveL"]
    for c in sent:  # re-checked here: nothing outside the envelope reached the arm
        env.check_pose(c.target)
        assert c.speed <= env.max_tcp_speed
    # faces below the floor are refused: counted, and the explorer moved on
    assert res.refused_commands == arm.refused
    refusals = [r for r in caplog.records if "refused by the safety envelope" in r.getMessage()]
    level = logging.WARNING if arm.refused >= n else logging.INFO  # a refusal a whisk or more: warned
    assert [r.levelno for r in refusals if r.levelno > logging.DEBUG] == ([level] if arm.refused else [])
    assert sum(r.levelno == logging.DEBUG for r in refusals) == arm.refused  # one line a run, each refusal at DEBUG
    if strategy == "default":  # the default search walks the sphere's faces and meets the floor
        assert arm.refused > 0
    assert len(sent) == n - res.strategies.count("none")  # a move per whisk unless every re-plan was refused
    # every whisk happened where the arm was
    moved = [p for p, s in zip(res.poses[1:], res.strategies) if s != "none"]
    np.testing.assert_allclose([p.position_m for p in moved], [c.target.position_m for c in sent][: len(moved)], atol=1e-9)
    assert set(res.strategies) <= {"spc", "default", "feh", "lsr", "none", "advance", "back_off", "turn"}
    # IC is the running sum of the raw confidence (dt = 1)
    np.testing.assert_allclose(res.ic, np.cumsum(res.confidence, axis=0))


def test_replay_of_a_recorded_session_gives_the_live_beliefs(world):
    ex, _, _, cycles = _explorer(world, "lsr", seed=5, n=50)
    live = ex.run()
    assert live.impulses.sum() > 0  # the comparison covers re-localisations
    known, _ = world
    again = Explorer(known, None, None, _odometry(105), DefaultSearch((0, 0, 0.17), 0.3), strategy="lsr")
    rep = again.replay(cycles)
    np.testing.assert_array_equal(rep.impulses, live.impulses)
    np.testing.assert_allclose(rep.ic, live.ic)
    assert rep.poses == live.poses


@pytest.fixture(scope="module")
def recorded(world):
    """A live run's cycles and the beliefs of replaying all of them."""
    ex, _, _, cycles = _explorer(world, "lsr", seed=5, n=50)
    ex.run()
    return cycles, _replayer(world).replay(cycles)


def _replayer(world, threshold=300.0):
    known, _ = world
    return Explorer(known, None, None, _odometry(105), DefaultSearch((0, 0, 0.17), 0.3), strategy="lsr",
                    stop_threshold=threshold)


@settings(max_examples=12, deadline=None)
@given(fraction=st.floats(0.05, 1.5))
def test_a_replay_stops_at_the_threshold_as_a_live_run_does(world, recorded, fraction):
    cycles, full = recorded
    peak = full.ic.max(axis=1)  # the leading IC after each whisk
    assert peak[-1] > 0  # the run re-localised: thresholds below and above its peak are both drawn
    threshold = fraction * float(peak[-1])
    crossed = np.flatnonzero(peak >= threshold)
    rep = _replayer(world, threshold).replay(cycles, stop_at_threshold=True)
    n = int(crossed[0]) + 1 if len(crossed) else len(cycles)  # the first whisk at the threshold, found from the full trace
    assert len(rep.ic) == n and rep.stop_reason == ("threshold" if len(crossed) else "iterations")
    np.testing.assert_array_equal(rep.ic, full.ic[:n])  # the same beliefs as far as it went
    np.testing.assert_array_equal(rep.impulses, full.impulses[:n])


@pytest.mark.parametrize("bad", [None, 1, "yes", 0.5])
def test_replay_refuses_a_stop_flag_that_is_not_a_bool(world, recorded, bad):
    with pytest.raises(InvalidInputError, match="stop_at_threshold"):
        _replayer(world).replay(recorded[0][:1], stop_at_threshold=bad)


def test_fresh_models_do_not_share_state(world):
    known, _ = world
    a = known[0].fresh_model()
    n0 = a.object_map.n_experiences
    ex, _, _, _ = _explorer(world, "default", seed=7, n=15)
    ex.run()
    assert known[0].fresh_model().object_map.n_experiences == n0 == known[0].n_built


def test_build_object_model_with_spc_whisks_more_and_stores_the_map(world):
    known, _ = world
    for k in known:
        assert k.n_built == k.model.object_map.n_experiences > 0
        assert len(k.poses) >= k.n_history > 0


def test_a_run_that_touched_nothing_or_never_moved_says_so(world, caplog):
    """It ended at its iteration limit with every IC at zero and said nothing (a new user's believed volume 1 m off)."""
    from whisker_io.hw.arm import SimArm
    from whisker_io.hw.safety import SafetyEnvelope

    known, chains = world
    mesh, chain = chains["box_stack"]
    rng = np.random.default_rng(5)
    far = mesh.bounds.mean(axis=0) + [0.0, 0.6, 0.0]  # the search round empty space beside the object
    search = DefaultSearch(far, 0.2, seed=5)
    env = SafetyEnvelope(**WORKSPACE)
    start = next(search.face_pose(f) for f in range(len(search.directions)) if search.face_pose(f).position_m[2] > 0.3)
    ex = Explorer(known, lambda p: chain.features(p, rng), SimArm(start, env), _odometry(5), search,
                  stop_threshold=math.inf, max_iterations=12)
    with caplog.at_level("WARNING", logger="cansim.explore.explorer"):
        ex.run()
    said = [r.getMessage().split(":")[0] for r in caplog.records]
    assert "none of the 12 whisks of this run touched anything" in said  # and, as its placements meet the floor,
    assert all(m == "none of the 12 whisks of this run touched anything" or "refused by the safety envelope" in m
               for m in said)  # at most the envelope's own warning beside it
    caplog.clear()
    locked = SafetyEnvelope(workspace_min=start.position_m - 1e-3, workspace_max=start.position_m + 1e-3,
                            max_tool_tilt=math.pi)  # the start pose only: every command refused
    ex = Explorer(known, lambda p: chain.features(p, rng), SimArm(start, locked), _odometry(5), search,
                  stop_threshold=math.inf, max_iterations=6)
    with caplog.at_level("WARNING", logger="cansim.explore.explorer"):
        res = ex.run()
    assert res.refused_commands >= 5 and all(p == start for p in res.poses)
    assert any(r.getMessage().startswith("the arm did not move in this run") for r in caplog.records)


def test_a_map_that_closed_no_loop_says_so(world, caplog):
    """Its poses are dead reckoning: a user mapping along a path that never comes back is told (one warning)."""
    from whisker_io.sim.trajectories import object_trajectory

    _, chains = world
    mesh, chain = chains["box"]
    rng = np.random.default_rng(3)
    loop = object_trajectory(mesh, "A", n_loops=1)
    with caplog.at_level("WARNING", logger="cansim.explore.explorer"):
        few = build_object_model("box", loop[:4], lambda p: chain.features(p, rng), _odometry(3), placement=None,
                                 model=_model())
    assert few.n_built > 0 and not any(few.mapping_log["relocalised"])
    assert [r.getMessage().split(":")[0] for r in caplog.records] == ["the map of 'box' closed no loop"]
    caplog.clear()
    with caplog.at_level("WARNING", logger="cansim.explore.explorer"):
        full = build_object_model("box", loop, lambda p: chain.features(p, rng), _odometry(3),
                                  placement=PlacementParams(roll_rad=math.pi / 2), model=_model())
    assert any(full.mapping_log["relocalised"]) and not caplog.records  # it closed loops: nothing to say


@settings(max_examples=25, deadline=None)
@given(st.one_of(st.integers(-3, 0), st.floats(allow_nan=True), st.text(max_size=3), st.booleans()),
       st.sampled_from(["default", "feh", "lsr", "random", ""]))
def test_explorer_bad_arguments_are_typed(world, max_iterations, strategy):
    known, _ = world
    with pytest.raises(CansimError):
        Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), strategy=strategy, max_iterations=max_iterations)


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(["max_adjustments", "max_replans", "stop_threshold", "time_limit_s"]),
       st.one_of(st.integers(-3, 0), st.floats(allow_nan=True), st.text(max_size=3), st.booleans(), st.none()))
@example("max_adjustments", math.inf)  # was an OverflowError
@example("max_replans", "a")  # was a ValueError
@example("stop_threshold", 10**400)  # was an OverflowError
def test_explorer_bad_limits_are_typed(world, name, value):
    known, _ = world
    if isinstance(value, bool) or value is None or isinstance(value, str):
        valid = False
    elif name in ("max_adjustments", "max_replans"):
        valid = isinstance(value, int) and value >= 0
    elif isinstance(value, int):  # the drawn ints are <= 0; 10**400 is not a float
        valid = False
    else:  # a positive number; math.inf is no limit
        valid = value > 0
    make = lambda: Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), **{name: value})  # noqa: E731
    if valid:
        assert getattr(make(), name) == value
    else:
        with pytest.raises(CansimError):
            make()


@settings(max_examples=25, deadline=None)
@given(st.one_of(st.integers(), st.text(max_size=3), st.lists(st.integers(), max_size=2),
                 st.dictionaries(st.sampled_from(["along_surface", "step_m", "bogus"]),
                                 st.one_of(st.none(), st.text(max_size=2), st.floats(max_value=0.0), st.just(float("nan"))),
                                 min_size=1)),
       st.sampled_from(["feh", "lsr"]))
def test_explorer_bad_strategy_options_are_typed(world, options, strategy):
    known, _ = world
    with pytest.raises(CansimError):
        Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), strategy=strategy, strategy_options=options)


def test_strategy_options_for_the_default_search_are_refused(world):
    """The default search takes no options: they were dropped silently, a typo'd key as well."""
    known, _ = world
    with pytest.raises(ConfigError, match="apply to the 'feh' and 'lsr' strategies"):
        Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), strategy="default",
                 strategy_options={"along_surfce": False})
    Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), strategy="default", strategy_options={})


def test_strategy_options_reach_the_strategy(world):
    known, _ = world
    ex = Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), strategy="feh",
                  strategy_options={"along_surface": False, "step_m": 0.05})
    assert ex.strategy.along_surface is False and ex.strategy.step_m == 0.05
    assert Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), strategy="lsr").strategy.along_surface is True


def test_empty_known_and_short_trajectory_are_typed():
    with pytest.raises(CansimError):
        Explorer([], None, None, None, DefaultSearch((0, 0, 0), 0.3))
    with pytest.raises(CansimError):
        build_object_model("x", [], None, None)


def test_exploring_model_has_no_pose_belief_and_relocalises_at_any_packet_distance(world):
    from cansim.explore.explorer import any_distance_cells

    known, _ = world
    k = known[0]
    assert any_distance_cells((5,) * 6) == pytest.approx(math.sqrt(6 * 2.5**2) + 1.0)  # above every wrapped 6-D distance
    m = k.exploring_model()
    assert not m.config.pose_prior and m.object_map.config.match_distance_cells == pytest.approx(any_distance_cells((5,) * 6))
    assert m.object_map.n_experiences == k.n_built and m.n_views == k.n_built_regions
    np.testing.assert_array_equal(m.object_map.history, k.model.object_map.history)
    assert k.model.object_map.config.match_distance_cells == 1.0  # the mapped model is not touched
    # whisking a stored region again re-localises to an experience holding it, wherever the packet is
    om, fe = m.object_map, m.frontend
    vids = om.view_ids[: k.n_built]
    regions = [int(r) for r in np.unique(vids)][1:9][::-1]  # distinct, none the loop's initial view 0
    from maps.odometry import SpatialOdometry

    for r in regions:
        st = m.step(SpatialOdometry(np.array([0.05, 0, 0]), np.zeros(3), 1.0), (fe.pfh[r], fe.sda[r]))
        assert st.view_id == r and st.relocalised and vids[st.exp_id] == r


def test_build_object_model_rejects_a_bad_adjustment_count(world):
    known, _ = world
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(CansimError):
            build_object_model("x", known[0].poses[:3], lambda p: None, _odometry(0), adjustments_per_pose=bad)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 12), min_size=1, max_size=6), st.integers(0, 2**31))
def test_any_distance_exceeds_every_wrapped_distance(shape, seed):
    from cansim.explore.explorer import any_distance_cells

    rng = np.random.default_rng(seed)
    n = np.array(shape, float)
    a, b = rng.uniform(0, n, (200, len(shape))), rng.uniform(0, n, (200, len(shape)))
    d = np.abs(a - b)
    d = np.minimum(d, n - d)  # wrapped per axis, as the experience map measures (Eq 2.22)
    assert np.sqrt((d**2).sum(axis=1)).max() < any_distance_cells(shape)


@settings(max_examples=25, deadline=None)
@example([math.inf])
@example([2.0, -math.inf, 5])
@given(st.one_of(st.just([]), st.lists(st.one_of(st.integers(-3, 0), st.floats(allow_nan=True).filter(lambda x: not (math.isfinite(x) and x > 0 and x == int(x))),
                                                     st.text(max_size=2), st.booleans()), min_size=1, max_size=3)))
def test_any_distance_bad_shapes_typed(shape):
    from cansim.explore.explorer import any_distance_cells

    with pytest.raises(CansimError):
        any_distance_cells(shape)


# ------------------------------------------------------------ the surface matcher as the impulse source (issue 22)
def test_stored_surface_with_exact_odometry_and_true_contacts_lies_on_the_object():
    """Mapped with noiseless odometry and noiseless true contacts, the stored surface is the mesh: every point within
    1 mm of it (the pose graph keeps the dead-reckoned poses, which are the true ones), one point per contact felt,
    and each felt from outside the object (its viewpoint farther from the centre than the point)."""
    import trimesh

    from whisker_io.sim.objects import make_object
    from whisker_io.sim.odometry_noise import OdometryNoise, noisy_odometry
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    mesh = make_object("mug")
    chain = WhiskChain(mesh, contact_model="truth", contact_noise=None)
    rng, exact = np.random.default_rng(0), OdometryNoise(euler_std_rad=0.0, displacement_std_m=0.0)
    k = build_object_model("mug", object_trajectory(mesh, "A", n_loops=1)[:20], lambda p: chain.features(p, rng),
                           lambda a, b: noisy_odometry(a, b, rng, exact), placement=None, model=_model())
    points, seen = k.stored_surface()
    felt = sum(len(c) for c in k.mapping_log["contacts"] if c is not None)
    assert points.shape == seen.shape == (felt, 3) and felt > 50
    _, d, _ = trimesh.proximity.closest_point(mesh, points)
    assert d.max() < 1e-3, d.max()
    centre = mesh.bounds.mean(axis=0)
    assert np.all(np.linalg.norm(seen - centre, axis=1) > np.linalg.norm(points - centre, axis=1))
    assert k.stored_surface()[0] is points  # computed once


def test_a_known_object_without_a_mapping_log_has_no_stored_surface(world):
    from cansim.explore.explorer import KnownObject

    known, _ = world
    bare = KnownObject("box", known[0].model, known[0].n_built, known[0].n_built_regions, known[0].n_history, known[0].poses)
    with pytest.raises(ConfigError, match="mapping log"):
        bare.stored_surface()
    with pytest.raises(ConfigError, match="mapping log"):
        Explorer([bare], None, None, None, DefaultSearch((0, 0, 0), 0.3), matcher="surface")


@settings(max_examples=25, deadline=None)
@given(st.one_of(st.text(max_size=8), st.integers(), st.none(), st.just(["surface"])).filter(lambda m: m not in ("thesis", "surface")),
       st.one_of(st.none(), st.integers(), st.text(max_size=3), st.just({"particles": 10})))
def test_explorer_bad_matcher_or_surface_config_is_a_config_error(world, matcher, config):
    known, _ = world
    with pytest.raises(ConfigError, match="matcher"):
        Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), matcher=matcher)
    if config is not None:
        with pytest.raises(ConfigError, match="surface_config"):
            Explorer(known, None, None, None, DefaultSearch((0, 0, 0), 0.3), matcher="surface", surface_config=config)


def _block_run(world, n=120, seed=5):
    """A block standing beside where the Box and the Box-Stack were mapped (0.25 m from their faces): every contact
    lies off both maps' surfaces."""
    import trimesh

    from whisker_io.hw.arm import SimArm
    from whisker_io.hw.safety import SafetyEnvelope
    from whisker_io.sim.whisk_chain import WhiskChain

    known, _ = world
    block = trimesh.creation.box(extents=(0.2, 0.25, 0.3))
    block.apply_translation([0.45, 0.0, 0.3])
    chain = WhiskChain(block, contact_model="tip")
    search = DefaultSearch(block.bounds.mean(axis=0), float(np.linalg.norm(block.extents)) / 2, mesh=block, seed=seed)
    search.current = int(np.argmax([search.face_pose(i).position_m[2] for i in range(len(search.directions))]))
    arm = SimArm(search.face_pose(search.current), SafetyEnvelope(**WORKSPACE))
    rng = np.random.default_rng(seed)
    counts = []

    def sensor(pose):
        f = chain.features(pose, rng)
        counts.append(len(np.asarray(getattr(f, "contact_points_m", np.zeros((0, 3)))).reshape(-1, 3)))
        return f

    ex = Explorer(known, sensor, arm, _odometry(200 + seed), search, stop_threshold=math.inf, max_iterations=n,
                  matcher="surface", surface_config=SurfaceMatchConfig(seed=seed))
    return ex.run(), np.array(counts)


def test_the_explorer_says_once_when_the_surface_matcher_has_ruled_every_object_out(world, caplog):
    """Every contact is off both stored surfaces (residual ``cap_m`` = 30 mm, above twice the 8-mm tolerance), so the
    matcher rules both objects out when its window holds ``window_whisks`` (20) whisks with contacts, and not before:
    one INFO line names that whisk, counted here from the sensor's own output, and no impulse ever comes."""
    with caplog.at_level(logging.INFO, logger="cansim.explore.explorer"):
        res, counts = _block_run(world)
    with_contact = np.flatnonzero(counts >= 1)
    assert len(with_contact) >= 20  # the block is touched: the run is about ruling out, not about missing it
    assert res.stop_reason == "iterations" and len(res.poses) == 120 and not res.impulses.any()
    lines = [r for r in caplog.records if "every object ruled out" in r.getMessage()]
    assert len(lines) == 1 and lines[0].levelno == logging.INFO
    assert f"whisk {with_contact[19] + 1}," in lines[0].getMessage(), (lines[0].getMessage(), with_contact[:21])


def test_surface_matcher_names_each_object_along_its_mapping_poses_with_exact_odometry():
    """End to end through the explorer's frames (map anchors, the matcher's start pose, the odometry's sense): a Box and
    a Mug mapped with noiseless odometry, each whisked again at its mapping poses (new contact noise) with noiseless
    odometry. With ``matcher="surface"`` there are impulses and every one names the presented object."""
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.odometry_noise import OdometryNoise, noisy_odometry
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    exact = OdometryNoise(euler_std_rad=0.0, displacement_std_m=0.0)
    rng = np.random.default_rng(3)
    odometry = lambda a, b: noisy_odometry(a, b, rng, exact)  # noqa: E731
    known, chains = [], {}
    for name in ("box", "mug"):
        mesh = make_object(name)
        chain = WhiskChain(mesh, contact_model="tip")
        known.append(build_object_model(name, object_trajectory(mesh, "A", n_loops=1), lambda p, c=chain: c.features(p, rng),
                                        odometry, placement=None, model=_model()))
        chains[name] = chain
    for k, obj in enumerate(known):
        cycles = [(p, chains[obj.name].features(p, rng)) for p in obj.poses]
        surf = Explorer(known, None, None, odometry, DefaultSearch((0, 0, 0.17), 0.3), matcher="surface",
                        surface_config=SurfaceMatchConfig(seed=k, rotation_sigma_deg=0.5, displacement_sigma_m=0.002)
                        ).replay(cycles)
        assert surf.impulses[:, k].sum() >= 10 and surf.impulses[:, 1 - k].sum() == 0, (obj.name, surf.impulses.sum(axis=0))


# ------------------------------------------------------------ a mapped object saved and loaded back (issue 22)
def _same_known(a, b):
    assert a.name == b.name and (a.n_built, a.n_built_regions, a.n_history) == (b.n_built, b.n_built_regions, b.n_history)
    assert len(a.poses) == len(b.poses)
    for p, q in zip(a.poses, b.poses):
        assert np.array_equal(p.position_m, q.position_m) and np.array_equal(p.quaternion_xyzw, q.quaternion_xyzw)
    if a.mapping_log is None:
        assert b.mapping_log is None
        return
    la, lb = a.mapping_log, b.mapping_log
    assert la["odometry"] == lb["odometry"] and la["exp_ids"] == lb["exp_ids"] and la["relocalised"] == lb["relocalised"]
    assert len(la["contacts"]) == len(lb["contacts"])
    for c, d in zip(la["contacts"], lb["contacts"]):
        assert (c is None and d is None) or np.array_equal(np.asarray(c, dtype=float).reshape(-1, 3), d)


def test_a_saved_known_object_loads_back_with_its_model_log_and_stored_surface(world, tmp_path):
    """Everything mapping left survives the file: the model (its arrays member by member, and a whisk after loading gives
    the same state as on the original's fresh copy), the mapping poses and log, and so the stored surface bit for bit.
    The file is also a model file: WhiskerRatSLAM.load reads it."""
    from cansim.explore.explorer import KnownObject
    from cansim.models.whisker_ratslam import WhiskerRatSLAM

    known, chains = world
    obj = known[0]
    path = tmp_path / "box.npz"
    obj.save(path)
    back = KnownObject.load(path)
    _same_known(obj, back)
    pa, pb = obj.stored_surface(), back.stored_surface()
    assert all(np.array_equal(x, y) for x, y in zip(pa, pb)) and len(pa[0]) > 50
    ours, theirs = obj._model_arrays(), back._model_arrays()
    assert ours.keys() == theirs.keys() and all(np.array_equal(ours[k], theirs[k]) for k in ours)
    assert isinstance(WhiskerRatSLAM.load(path), WhiskerRatSLAM)
    mesh, chain = chains["box"]
    feats = chain.features(obj.poses[3], np.random.default_rng(5))
    odo = SpatialOdometry(np.array([0.01, 0.0, 0.0]), np.zeros(3), 1.0)
    s1, s2 = obj.fresh_model().step(odo, feats), back.fresh_model().step(odo, feats)
    assert (s1.exp_id, s1.relocalised) == (s2.exp_id, s2.relocalised)
    assert KnownObject.load(path, name="other").name == "other"


def test_a_bare_model_file_loads_as_a_known_object_without_a_stored_surface(world, tmp_path):
    from cansim.explore.explorer import KnownObject

    known, _ = world
    path = tmp_path / "model.npz"
    known[1].model.save(path)
    with pytest.raises(InvalidInputError, match="name"):
        KnownObject.load(path)
    bare = KnownObject.load(path, name="box_stack")
    assert bare.mapping_log is None and bare.poses == [] and bare.n_built == known[1].model.object_map.n_experiences
    with pytest.raises(ConfigError, match="mapping log"):
        bare.stored_surface()


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.one_of(st.none(), st.integers(0, 4)), min_size=1, max_size=12), st.integers(0, 2**31 - 1),
       st.booleans())
def test_any_mapping_log_round_trips(world, sizes, seed, with_log):
    """Logs with whisks without a contact array (None), with empty ones and with several contacts all come back as they
    were; so do poses and counts."""
    import io

    from cansim.explore.explorer import KnownObject
    from whisker_io.pose import Pose

    rng = np.random.default_rng(seed)
    known, _ = world
    n = len(sizes)
    poses = [Pose(rng.normal(size=3), Rotation.random(random_state=seed + i).as_quat()) for i in range(n)]
    log = {"odometry": [SpatialOdometry(rng.normal(0, 0.01, 3), rng.normal(0, 0.05, 3), float(rng.uniform(0.1, 2))) for _ in range(n)],
           "exp_ids": [int(v) for v in rng.integers(-1, 50, n)], "relocalised": [bool(v) for v in rng.integers(0, 2, n)],
           "contacts": [None if k is None else rng.normal(size=(k, 3)) for k in sizes]} if with_log else None
    obj = KnownObject("thing", known[0].model, 3, 2, 1, poses, log)
    obj._snapshot = known[0]._model_arrays()
    buf = io.BytesIO()
    obj.save(buf)
    buf.seek(0)
    _same_known(obj, KnownObject.load(buf))


def _corrupted(arrays, member, how):
    a = dict(arrays)
    v = np.asarray(a[member])
    if how == "drop":
        del a[member]
    elif how == "shape":
        a[member] = np.concatenate([v.reshape(-1), v.reshape(-1)[:1]]) if v.size else np.zeros(3)
    elif how == "dtype":
        a[member] = np.full(v.shape, 1.5) if v.dtype.kind in "Ui" else v.astype(str)
    elif how == "nan":
        w = v.astype(np.float64).copy()
        w.reshape(-1)[0] = np.nan
        a[member] = w
    return a


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(["known_format", "known_name", "known_sizes", "known_poses", "known_odometry", "known_exp_ids",
                        "known_relocalised", "known_contact_counts", "known_contacts", "known_odometry_scale"]),
       st.sampled_from(["drop", "shape", "dtype", "nan"]))
def test_a_damaged_known_object_file_is_a_corrupt_file_error_naming_the_member(world, saved_box, member, how):
    import io

    from cansim.explore.explorer import KnownObject
    from whisker_io.errors import CorruptFileError

    if how == "nan" and member in ("known_name", "known_relocalised", "known_format", "known_sizes", "known_exp_ids",
                                   "known_contact_counts"):
        return  # no NaN in an integer, boolean or string member (their dtype case covers them)
    arrays = _corrupted(saved_box, member, how)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    buf.seek(0)
    if (member, how) == ("known_odometry_scale", "drop"):  # a file written before the member: Eq 6.4-6.11's noise
        assert KnownObject.load(buf).odometry_scale == 1.0
        return
    with pytest.raises(CorruptFileError) as err:
        KnownObject.load(buf)
    assert err.value.field == member, (member, how, err.value)


@pytest.fixture(scope="module")
def saved_box(world):
    import io

    known, _ = world
    buf = io.BytesIO()
    known[0].save(buf)
    buf.seek(0)
    with np.load(buf, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(["short", "long_ids", "no_key", "odometry_type", "contact_shape", "contact_nan", "size", "pose"]))
def test_a_known_object_that_could_not_load_back_is_not_saved(world, tmp_path, bad):
    """An inconsistent mapping log is refused by save with a typed error and no file is written."""
    from cansim.explore.explorer import KnownObject
    from whisker_io.errors import ShapeError

    known, _ = world
    good = known[0]
    log = {k: list(v) for k, v in good.mapping_log.items()}
    poses = list(good.poses)
    if bad == "short":
        poses = poses[:-1]
    elif bad == "long_ids":
        log["exp_ids"] = log["exp_ids"] + [0]
    elif bad == "no_key":
        del log["relocalised"]
    elif bad == "odometry_type":
        log["odometry"][1] = (np.zeros(3), np.zeros(3), 1.0)
    elif bad == "contact_shape":
        log["contacts"][0] = np.zeros((2, 6))
    elif bad == "contact_nan":
        log["contacts"][0] = np.full((1, 3), np.nan)
    elif bad == "pose":
        poses[2] = np.r_[poses[2].position_m, poses[2].quaternion_xyzw]
    sizes = (good.n_built, -1 if bad == "size" else good.n_built_regions, good.n_history)
    obj = KnownObject(good.name, good.model, *sizes, poses, log)
    path = tmp_path / f"{bad}.npz"
    with pytest.raises((InvalidInputError, ShapeError)):
        obj.save(path)
    assert not path.exists()


# ------------------------------------------------------------ a newcomer's mistakes are typed errors (session 45)
def test_explorer_refuses_what_is_not_a_list_of_known_objects_or_a_search(world):
    known, _ = world
    search = DefaultSearch((0, 0, 0.17), 0.3)
    for bad in (known[0], [known[0].model], [], "box"):
        with pytest.raises(InvalidInputError, match="KnownObject"):
            Explorer(bad, None, None, None, search)
    with pytest.raises(InvalidInputError, match="distinct names"):
        Explorer([known[0], known[0]], None, None, None, search)
    with pytest.raises(InvalidInputError, match="DefaultSearch"):
        Explorer(known, None, None, None, None)
    with pytest.raises(InvalidInputError, match="callable"):
        Explorer(known, None, None, 3.0, search)
    with pytest.raises(ConfigError, match="sensor and an arm"):
        Explorer(known, None, None, _odometry(1), search).run()


def test_odometry_that_returns_no_motion_is_a_typed_error_at_the_second_whisk(world):
    known, _ = world
    pose = known[0].poses[0]
    ex = Explorer(known, None, None, lambda a, b: None, DefaultSearch((0, 0, 0.17), 0.3))
    ex.observe(pose, None)  # the first whisk moves by nothing: odometry is not called
    with pytest.raises(InvalidInputError, match=r"\(v \(3,\) m/s, omega"):
        ex.observe(pose, None)
    with pytest.raises(ConfigError, match="no odometry"):
        ex2 = Explorer(known, None, None, None, DefaultSearch((0, 0, 0.17), 0.3))
        ex2.observe(pose, None)
        ex2.observe(pose, None)


def test_build_object_model_names_an_untouched_map_and_refuses_bad_callables(world, caplog):
    known, _ = world
    poses = known[0].poses[:6]
    ok_odometry = _odometry(2)
    with pytest.raises(InvalidInputError, match="name"):
        build_object_model(None, poses, lambda p: None, ok_odometry)
    with pytest.raises(InvalidInputError, match="callable"):
        build_object_model("x", poses, None, ok_odometry)
    with pytest.raises(InvalidInputError, match="must return"):
        build_object_model("x", poses, lambda p: None, lambda a, b: (np.zeros(3), np.zeros(3)))  # no dt
    with caplog.at_level(logging.WARNING, logger="cansim"):
        untouched = build_object_model("air", poses, lambda p: None, ok_odometry, placement=None, model=_model())
    assert untouched.mapping_observations() == (0, 6)
    assert any("only 0 of the 6 mapping whisks of 'air' observed a region" in r.getMessage() for r in caplog.records)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.one_of(st.none(), st.integers(0, 8)), max_size=12))
def test_mapping_observations_count_the_whisks_with_three_contacts_or_more(world, counts):
    from cansim.explore.explorer import KnownObject

    known, _ = world
    log = {"odometry": [], "exp_ids": [], "relocalised": [],
           "contacts": [None if c is None else np.zeros((c, 3)) for c in counts]}
    from whisker_io.features.region import MIN_OBSERVATION_CONTACTS

    assert MIN_OBSERVATION_CONTACTS == 3  # a region of Eq 5.5
    k = KnownObject("box", known[0].model, 1, 1, 1, [], log)
    observed = sum(c is not None and c >= 3 for c in counts)
    assert k.mapping_observations() == (observed, len(counts))
    assert k.seldom_observed() == (observed < 0.5 * len(counts))
    bare = KnownObject("box", known[0].model, 1, 1, 1)
    assert bare.mapping_observations() is None and not bare.seldom_observed()


def test_an_envelope_that_refuses_most_moves_is_warned_of(world, caplog):
    """A workspace whose floor lies above most of the search's placements: a refusal a whisk or more is a warning
    that names the envelope; the run still keeps every command inside it."""
    from whisker_io.hw.arm import SimArm
    from whisker_io.hw.safety import SafetyEnvelope

    known, _ = world
    search = DefaultSearch((0, 0, 0.17), 0.3, seed=2)
    env = SafetyEnvelope(workspace_min=(-0.75, -0.75, 0.35), workspace_max=(0.75, 0.75, 1.0), max_tool_tilt=math.pi)
    start = next(search.face_pose(f) for f in range(len(search.directions)) if search.face_pose(f).position_m[2] > 0.4)
    arm = SimArm(start, env)
    ex = Explorer(known, lambda p: None, arm, _odometry(4), search, placement=None, max_iterations=20,
                  stop_threshold=math.inf)
    with caplog.at_level(logging.INFO, logger="cansim"):
        res = ex.run()
    assert res.refused_commands >= len(res.ic)
    lines = [r for r in caplog.records if "refused by the safety envelope" in r.getMessage()]
    assert [r.levelno for r in lines] == [logging.WARNING] and "check the envelope" in lines[0].getMessage()


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from([0.0, 0.1, 0.25, 0.5, 1.0, 3.0]))
def test_a_known_objects_odometry_scale_saves_loads_and_sets_its_pose_graph(world, scale):
    """The stored surface of an object mapped with odometry ``scale`` x Eq 6.4-6.11 is whisk_surface's with the
    graph for that scale (at least the floor), before and after a save and a load."""
    import io
    from dataclasses import replace as dc_replace

    from cansim.explore.explorer import KnownObject
    from maps.pose_graph import WhiskGraphConfig, whisk_surface

    known, _ = world
    k = dc_replace(known[0], odometry_scale=scale, _surface=None)
    log = k.mapping_log
    graph = WhiskGraphConfig(odometry_sigma_m=0.01 * max(scale, 0.25), odometry_sigma_deg=2.5 * max(scale, 0.25))
    want = whisk_surface(log["odometry"], log["exp_ids"], log["relocalised"], log["contacts"], graph,
                         with_viewpoints=True, anchor=k.poses[0])
    buf = io.BytesIO()
    k.save(buf)
    buf.seek(0)
    back = KnownObject.load(buf)
    assert back.odometry_scale == scale
    for got in (k.stored_surface(), back.stored_surface()):
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
    for bad in (-1.0, None, float("nan"), True, "1"):
        with pytest.raises(InvalidInputError, match="odometry_scale"):
            dc_replace(k, odometry_scale=bad)


def test_build_object_model_refuses_a_trajectory_that_is_not_poses(world):
    known, _ = world
    for bad in (None, 5, "AB", [known[0].poses[0], (0, 0, 0)]):
        with pytest.raises(InvalidInputError, match="trajectory must be a sequence of Pose"):
            build_object_model("x", bad, lambda p: None, _odometry(1))
    with pytest.raises(InvalidInputError, match="name"):
        build_object_model("  ", known[0].poses[:3], lambda p: None, _odometry(1))


def test_the_default_surface_matcher_assumes_the_known_objects_odometry_noise(world):
    """Objects mapped with odometry a quarter as noisy: the explorer's matcher moves its hypotheses by a quarter of
    Eq 6.4-6.11's 2.5 deg and 1 cm; objects of different scales, or a config given, leave it as given / the thesis'."""
    from dataclasses import replace as dc_replace

    known, _ = world
    quarter = [dc_replace(k, odometry_scale=0.25) for k in known]
    search = DefaultSearch((0, 0, 0.17), 0.3)
    cfg = Explorer(quarter, None, None, _odometry(1), search, matcher="surface")._surface_config
    assert (cfg.rotation_sigma_deg, cfg.displacement_sigma_m) == pytest.approx((0.625, 0.0025))
    mixed = [quarter[0], *known[1:]]
    cfg = Explorer(mixed, None, None, _odometry(1), search, matcher="surface")._surface_config
    assert (cfg.rotation_sigma_deg, cfg.displacement_sigma_m) == (2.5, 0.01)
    given = SurfaceMatchConfig(rotation_sigma_deg=1.0)
    assert Explorer(quarter, None, None, _odometry(1), search, matcher="surface",
                    surface_config=given)._surface_config is given


def test_a_replay_in_which_nothing_touched_says_so_once(world, recorded, caplog):
    cycles = recorded[0]
    with caplog.at_level(logging.WARNING, logger="cansim.explore.explorer"):
        _replayer(world).replay([(pose, None) for pose, _ in cycles[:5]])  # whisks without contact (volts read as counts)
    said = [r for r in caplog.records if "replayed whisks touched anything" in r.getMessage()]
    assert len(said) == 1 and "none of the 5 replayed whisks" in said[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="cansim.explore.explorer"):
        _replayer(world).replay(cycles[:5])  # the recorded whisks touched
    assert not [r for r in caplog.records if "touched anything" in r.getMessage()]
