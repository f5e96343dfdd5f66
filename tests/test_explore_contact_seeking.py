"""Contact seeking (cansim.explore.contact_seeking): advance until whiskers touch, back off when pressed, hold the range."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st
from scipy.spatial.transform import Rotation

from cansim.errors import CansimError, ConfigError, InvalidInputError
from cansim.explore.contact_seeking import ContactSeekingParams, clear_of_contacts, held_face_pose, seek_contact
from cansim.explore.placement import PlacementParams
from whisker_io.pose import Pose

SPC = PlacementParams(roll_rad=math.pi / 2)
#: A pose looking along world +x (its y-axis), 0.5 m from the origin.
ROT = Rotation.from_matrix(np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
POSE = Pose.from_rotation([-0.5, 0.0, 0.3], ROT)


def _y(p):
    return p.rotation.as_matrix()[:, 1]


def test_the_test_pose_looks_along_x():
    assert np.allclose(_y(POSE), [1.0, 0.0, 0.0])


def test_no_contact_advances_one_step_along_the_axis_orientation_kept():
    s = seek_contact(POSE, np.zeros((0, 3)), params=ContactSeekingParams(advance_step_m=0.04), placement=SPC)
    assert s.action == "advance" and s.advance_m == pytest.approx(0.04)
    assert np.allclose(s.goal.position_m, [-0.46, 0.0, 0.3])  # 4 cm along +x, by hand
    assert np.allclose(s.goal.rotation.as_matrix(), POSE.rotation.as_matrix())
    s2 = seek_contact(s.goal, np.zeros((0, 3)), params=ContactSeekingParams(advance_step_m=0.04), placement=SPC,
                      advance_m=s.advance_m)
    assert s2.advance_m == pytest.approx(0.08) and np.allclose(s2.goal.position_m, [-0.42, 0.0, 0.3])


def test_the_advance_stops_at_its_limit_and_at_the_search_centre():
    p = ContactSeekingParams(advance_step_m=0.04, max_advance_m=0.1)
    assert seek_contact(POSE, [], params=p, placement=SPC, advance_m=0.08) is None  # 0.12 > 0.1
    assert seek_contact(POSE, [], params=p, placement=SPC, advance_m=0.06).action == "advance"  # exactly 0.1
    # the front (0.2019 m along y) may go up to beyond_centre_m (0.1 m) past the centre:
    p = ContactSeekingParams(advance_step_m=0.04, beyond_centre_m=0.1)
    front_x = -0.5 + 0.2019
    assert seek_contact(POSE, [], params=p, placement=SPC, centre_m=[front_x + 0.03, 0, 0.3]) is not None
    assert seek_contact(POSE, [], params=p, placement=SPC, centre_m=[front_x - 0.05, 0, 0.3]) is not None  # 0.05 + 0.04 <= 0.1
    assert seek_contact(POSE, [], params=p, placement=SPC, centre_m=[front_x - 0.07, 0, 0.3]) is None  # 0.07 + 0.04 > 0.1


def test_a_pressed_whisk_backs_off_before_any_turn():
    # three contacts, all to one side (the median far outside the 24-deg cone: Alg 7 alone would turn),
    # at 0.19 m along y: nearer than the band (0.21-0.26 m): the array backs off along -y first
    c = np.array([[0.15, 0.19, 0.0], [0.16, 0.19, 0.01], [0.14, 0.19, -0.01]])
    s = seek_contact(POSE, c, placement=SPC)
    assert s.action == "back_off"
    back = max(0.01, (0.235 - 0.19) / 2)  # band middle 0.235 m, two translation steps
    assert np.allclose(s.goal.position_m, POSE.position_m - back * _y(POSE))
    assert np.allclose(s.goal.rotation.as_matrix(), POSE.rotation.as_matrix())


def test_contacts_in_the_band_are_left_to_alg7():
    c = np.array([[0.0, 0.235, 0.1], [0.1, 0.235, -0.05], [-0.1, 0.235, -0.05]])
    assert seek_contact(POSE, c, placement=SPC) is None


def test_few_contacts_off_the_axis_turn_toward_them():
    c = np.array([[0.2, 0.235, 0.0]])  # 40 deg off y toward the frame's x
    s = seek_contact(POSE, c, placement=SPC)
    assert s.action == "turn"
    assert np.allclose(s.goal.position_m, POSE.position_m)  # Alg 7 turns about the end-effector origin
    target = POSE.rotation.apply([0.2, 0.235, 0.0])
    target /= np.linalg.norm(target)
    assert math.acos(_y(s.goal) @ target) < math.acos(_y(POSE) @ target)


def test_few_contacts_are_left_to_the_search_without_turn_few():
    c = np.array([[0.2, 0.235, 0.0]])
    assert seek_contact(POSE, c, params=ContactSeekingParams(turn_few=False), placement=SPC) is None


@pytest.mark.parametrize("value", [1, 0, "yes", None, 1.0])
def test_bad_turn_few_is_typed(value):
    with pytest.raises(ConfigError):
        ContactSeekingParams(turn_few=value)


def test_held_face_pose_comes_in_along_the_face_direction_never_out():
    face = Pose.from_rotation([0.0, -0.6, 0.2], ROT)
    g = held_face_pose(face, [0.0, 0.0, 0.2], 0.2, 0.1, 0.015)
    assert np.allclose(g.position_m, [0.0, -(0.1 + 0.015 + 0.2), 0.2])  # by hand
    assert np.allclose(g.rotation.as_matrix(), face.rotation.as_matrix())
    far = held_face_pose(face, [0.0, 0.0, 0.2], 0.2, 0.5, 0.015)  # held farther than the face: kept
    assert far == face


@settings(max_examples=40, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-1.4, 1.4), st.floats(0.005, 0.1))
def test_every_advance_is_one_step_along_the_axis(yaw, pitch, step):
    rot = Rotation.from_euler("zx", [yaw, pitch])
    pose = Pose.from_rotation([0.1, -0.2, 0.4], rot)
    s = seek_contact(pose, np.zeros((0, 3)), params=ContactSeekingParams(advance_step_m=step), placement=SPC)
    assert s.action == "advance"
    assert np.allclose(s.goal.position_m - pose.position_m, step * rot.as_matrix()[:, 1], atol=1e-12)


_BAD = st.one_of(st.just(math.nan), st.just(math.inf), st.just(-0.01), st.just("0.03"), st.just(True), st.just(5.0))


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["advance_step_m", "max_advance_m", "front_m", "backoff_min_m", "hold_margin_m",
                        "hold_max_turn_rad", "beyond_centre_m", "clear_ahead_m", "clear_radius_m"]), _BAD)
def test_bad_parameters_are_typed(name, value):
    with pytest.raises(ConfigError):
        ContactSeekingParams(**{name: value})


@settings(max_examples=30, deadline=None)
@given(st.one_of(st.just(math.nan), st.just(-1.0), st.just("0"), st.just(math.inf), st.just(None)))
def test_bad_advance_is_typed(value):
    with pytest.raises(InvalidInputError):
        seek_contact(POSE, [], placement=SPC, advance_m=value)


@pytest.mark.parametrize("contacts", [[[math.nan, 0.2, 0.0]], [[0.0, 20.0, 0.0]], [[0.1, 0.2]], "x"])
def test_bad_contacts_are_typed(contacts):
    with pytest.raises(CansimError):
        seek_contact(POSE, contacts, placement=SPC)


def test_bad_parameter_objects_are_typed():
    with pytest.raises(InvalidInputError):
        seek_contact(POSE, [], params=SPC)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        seek_contact(POSE, [], placement=ContactSeekingParams())  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        held_face_pose(POSE, [0, 0, 0], 0.2, -0.1, 0.0)


# ------------------------------------------------------------ clear of contacts
def test_a_contact_before_the_array_pushes_the_goal_back_to_the_clearance():
    # the goal looks along world +x from (-0.5, 0, 0.3); a contact 0.15 m ahead on the axis must lie 0.21 m ahead
    g = clear_of_contacts(POSE, [[-0.35, 0.0, 0.3]], ahead_m=0.21, radius_m=0.1)
    assert np.allclose(g.position_m, [-0.56, 0.0, 0.3])  # 0.06 m back along -x, by hand
    assert np.allclose(g.rotation.as_matrix(), POSE.rotation.as_matrix())


def test_contacts_beside_or_far_ahead_leave_the_goal():
    beside = [[-0.40, 0.12, 0.3]]  # 0.12 m off the axis: a splayed long whisker's tip
    ahead = [[-0.25, 0.05, 0.3]]  # 0.25 m ahead, already clear
    assert clear_of_contacts(POSE, beside, ahead_m=0.21, radius_m=0.1) == POSE
    assert clear_of_contacts(POSE, ahead, ahead_m=0.21, radius_m=0.1) == POSE
    assert clear_of_contacts(POSE, np.zeros((0, 3)), ahead_m=0.21, radius_m=0.1) == POSE
    # the nearest of several contacts before the array sets the shift: 0.21 - 0.12 = 0.09 m
    g = clear_of_contacts(POSE, beside + ahead + [[-0.38, -0.02, 0.31]], ahead_m=0.21, radius_m=0.1)
    assert np.allclose(g.position_m, [-0.59, 0.0, 0.3])


@settings(max_examples=60, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-1.4, 1.4),
       st.lists(st.tuples(st.floats(-0.3, 0.3), st.floats(-0.1, 0.5), st.floats(-0.3, 0.3)), max_size=8),
       st.floats(0.05, 0.4), st.floats(0.02, 0.3))
@example(1.072064815449135, 0.41213063240790015, [(0.0, 0.0, 0.25)], 0.25, 0.25)  # a contact on the radius: moved
def test_after_the_guard_every_contact_before_the_array_is_clear(yaw, pitch, local, ahead, radius):
    pose = Pose.from_rotation([0.1, -0.2, 0.4], Rotation.from_euler("zx", [yaw, pitch]))
    contacts = pose.apply(np.array(local, dtype=float).reshape(-1, 3)) if local else np.zeros((0, 3))
    g = clear_of_contacts(pose, contacts, ahead_m=ahead, radius_m=radius)
    assert np.allclose(g.rotation.as_matrix(), pose.rotation.as_matrix())
    moved = g.position_m - pose.position_m
    y = _y(pose)
    assert np.allclose(moved, (moved @ y) * y, atol=1e-12) and moved @ y <= 1e-12  # only back along the axis
    if len(contacts):
        loc = g.inverse().apply(contacts)
        off_axis = np.hypot(loc[:, 0], loc[:, 2])
        # a contact on the radius itself may count either way (the pose's round trip moves it by ~1e-17 m: a draw
        # with a contact at exactly radius_m found it, a base install's run): the clearance is asserted strictly
        # inside, the nearest one the move was for within the radius' rounding
        assert (loc[off_axis < radius - 1e-9, 1] >= ahead - 1e-9).all()
        if moved @ y < -1e-12:  # moved only as far as the nearest contact before the array needs
            assert np.isclose(loc[off_axis < radius + 1e-9, 1].min(), ahead)


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(["ahead_m", "radius_m"]), _BAD)
def test_bad_clearances_are_typed(name, value):
    kw = {"ahead_m": 0.21, "radius_m": 0.1, name: value}
    with pytest.raises(InvalidInputError):
        clear_of_contacts(POSE, [[0.0, 0.2, 0.0]], **kw)


@pytest.mark.parametrize("contacts", [[[math.nan, 0.2, 0.0]], [[0.1, 0.2]], "x"])
def test_bad_contacts_for_the_guard_are_typed(contacts):
    with pytest.raises(CansimError):
        clear_of_contacts(POSE, contacts, ahead_m=0.21, radius_m=0.1)


# ------------------------------------------------------------------ end to end
def _peanut():
    """A freeform shape that fills 40 % of its bounding box (two joined ellipsoids, 0.35 m long), on z = 0."""
    import trimesh

    parts = []
    for c, r in (([-0.09, 0.0, 0.09], [0.085, 0.075, 0.09]), ([0.1, 0.0, 0.07], [0.075, 0.065, 0.07])):
        m = trimesh.creation.icosphere(subdivisions=3)
        m.vertices = m.vertices * r + c
        parts.append(m)
    return trimesh.util.concatenate(parts)


def _run(mesh, seeking, n, seed=4):
    import trimesh

    from cansim.explore.explorer import Explorer, build_object_model
    from cansim.frontends.whisk import WhiskFrontEndConfig
    from cansim.explore.search import DefaultSearch
    from cansim.models.whisker_ratslam import WhiskerRatSLAM, WhiskerRatSLAMConfig
    from whisker_io.array.geometry import WhiskerArray
    from whisker_io.hw.arm import SimArm
    from whisker_io.hw.safety import SafetyEnvelope
    from whisker_io.sim.odometry_noise import noisy_odometry
    from whisker_io.sim.sweep import ContactNoise
    from whisker_io.sim.whisk_chain import WhiskChain

    rng = np.random.default_rng(seed)
    chain = WhiskChain(mesh, contact_model="tip", contact_noise=ContactNoise().scaled(0.3))
    fe = WhiskFrontEndConfig(features="both", pfh_threshold=1.2, sda_threshold=1.29, feature_update=False)
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.trajectories import object_trajectory

    box_chain = WhiskChain(make_object("box"), contact_model="tip")  # a small map of another object: the run recognises nothing
    few = object_trajectory(make_object("box"), "A", n_loops=1)[:8]
    known = [build_object_model("box", few, lambda p: box_chain.features(p, rng), lambda a, b: noisy_odometry(a, b, rng),
                                model=WhiskerRatSLAM(WhiskerRatSLAMConfig.mapping(cell_size_m=0.03, frontend=fe)))]
    lo, hi = mesh.bounds
    big = 1.5 * (hi - lo)  # the believed box: 1.5 times the object, on the table
    c = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, big[2] / 2])
    box = trimesh.creation.box(bounds=np.array([c - big / 2, c + big / 2]))
    search = DefaultSearch(c, float(np.linalg.norm(box.extents)) / 2, mesh=box, seed=seed,
                           footprint_m=WhiskerArray.thesis().positions_m)
    env = SafetyEnvelope(workspace_min=(-0.75, -0.75, 0.02), workspace_max=(0.75, 0.75, 1.0), max_tool_tilt=math.pi)
    start = next(search.face_pose(f) for f in range(len(search.directions)) if search.face_pose(f).position_m[2] > 0.3)
    arm = SimArm(start, env)
    counts = []

    def sensor(pose):
        f = chain.features(pose, rng)
        counts.append(f.n_contacts)
        return f

    kw = {"contact_seeking": ContactSeekingParams() if seeking == "default" else seeking}
    ex = Explorer(known, sensor, arm, lambda a, b: noisy_odometry(a, b, rng), search, stop_threshold=math.inf,
                  max_iterations=n, placement=PlacementParams(roll_rad=math.pi / 2), **kw)
    res = ex.run()
    return np.array(counts), res, arm, env


@pytest.fixture(scope="module")
def peanut_runs():
    mesh = _peanut()
    return {"default": _run(mesh, "default", 80), "thesis": _run(mesh, None, 40),
            "unguarded": _run(mesh, ContactSeekingParams(clear_ahead_m=0.0), 80)}


def _whisks_base_inside(mesh, poses):
    """Whisks with a base of the thesis array inside ``mesh``, counted as the Ch.6 study counts them (a vote over fixed
    ray directions: the same on every run, where trimesh's contains retries ambiguous points at random)."""
    from cansim.studies.ch6_active_exploration import bases_inside

    return int(bases_inside(mesh, poses).sum())


def test_the_contact_guard_puts_fewer_bases_inside_the_held_out_shape(peanut_runs):
    # measured (80 whisks, seeds 4-6): 15 -> 10, 19 -> 12, 27 -> 23 whisks with a base inside; contact 0.68 -> 0.66
    mesh = _peanut()
    guarded = _whisks_base_inside(mesh, peanut_runs["default"][1].poses)
    unguarded = _whisks_base_inside(mesh, peanut_runs["unguarded"][1].poses)
    assert guarded < unguarded
    assert (peanut_runs["default"][0] >= 1).mean() >= 0.55


@pytest.mark.xfail(strict=True, reason="issue 22 item 3: the sensor base still goes inside the held-out shape "
                                       "(10 of 80 whisks): a blind advance or a face at the held range meets a surface "
                                       "ahead of the front bases, where no whisker sweeps")
def test_no_base_ever_inside_the_held_out_shape(peanut_runs):
    assert _whisks_base_inside(_peanut(), peanut_runs["default"][1].poses) == 0


def test_freeform_shape_with_a_loose_believed_box_is_touched_by_default(peanut_runs):
    counts, res, _, _ = peanut_runs["default"]
    # measured 0.66 on this held-out shape (80 whisks, seed 4; 0.68 without the contact guard); the thesis' placement 0.0-0.3
    assert (counts >= 1).mean() >= 0.55
    assert {"advance", "spc"} <= set(res.strategies)  # it got there by advancing, then Alg 7 placed it
    thesis_counts, thesis_res, _, _ = peanut_runs["thesis"]
    assert (thesis_counts >= 1).mean() < 0.3  # the thesis' placement stands out of reach
    assert not {"advance", "back_off", "turn"} & set(thesis_res.strategies)


@pytest.mark.xfail(strict=True, reason="issue 22 target not reached on this held-out shape: 66 % of 80 whisks touch (target 70 %)")
def test_freeform_shape_meets_the_issue_22_contact_target(peanut_runs):
    counts, _, _, _ = peanut_runs["default"]
    assert (counts >= 1).mean() >= 0.7  # issue 22: >= 70 % of the whisks touch a freeform object


def test_every_command_of_the_run_passed_the_envelope(peanut_runs):
    for counts, res, arm, env in peanut_runs.values():
        moves = [c for c in arm.received if c.kind == "moveL"]
        assert moves
        for c in moves:
            env.check_pose(c.target)
            assert c.speed <= env.max_tcp_speed and c.acceleration_or_dt <= env.max_tcp_acceleration


def test_pressed_whisks_are_followed_by_a_move_away(peanut_runs):
    counts, res, _, _ = peanut_runs["default"]
    backs = [i for i, s in enumerate(res.strategies) if s == "back_off"]
    assert backs  # the run pressed against the peanut at least once
    for i in backs:
        if i + 1 < len(res.poses):
            moved = res.poses[i + 1].position_m - res.poses[i].position_m
            assert moved @ _y(res.poses[i]) < 0  # away from the surface along the array's axis


@settings(max_examples=10, deadline=None)
@given(st.sampled_from(["on", 1, True, 0.03, PlacementParams(), {"advance_step_m": 0.03}]))
def test_explorer_rejects_a_bad_contact_seeking(value):
    from cansim.explore.explorer import Explorer

    with pytest.raises(ConfigError):
        Explorer([object()], lambda p: None, object(), lambda a, b: None, object(), contact_seeking=value)  # type: ignore[arg-type]


def test_a_surface_can_come_within_16_mm_of_a_base_without_a_whisker_touching():
    """Why a blind advance cannot be made safe by contact feedback alone with the thesis array (module docstring).

    Its whiskers splay outward (at full protraction 40 deg off the array's axis), so the
    space straight ahead of the front bases is swept by none of them: a sphere of radius
    0.12 m on the axis, its apex 3 mm beyond the front bases' plane (y = 0.2019 m), lies
    about 1.5 cm from the nearest base (by hand: at the bases' ring radius 0.054 m the
    surface is 0.12 - sqrt(0.12^2 - 0.054^2) = 12.8 mm further on), yet the 60-mm
    whiskers' tips at protraction (0.093 m off the axis, 0.046 m ahead of their bases)
    stay just outside it and no whisker touches (with the apex 2 mm beyond, five do). An
    advance of 2 cm after such a whisk puts a base inside.
    """
    import trimesh

    from whisker_io.array.geometry import WhiskerArray
    from whisker_io.sim.sweep import ContactNoise
    from whisker_io.sim.whisk_chain import WhiskChain

    r, gap = 0.12, 0.003
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=r)
    sphere.apply_translation([0.0, 0.2019 + gap + r, 0.0])
    f = WhiskChain(sphere, contact_model="truth", contact_noise=ContactNoise().scaled(0.0)).features(Pose.identity(), np.random.default_rng(0))
    assert f.n_contacts == 0
    bases = np.asarray(WhiskerArray.thesis().positions_m)
    clearance = -sphere.nearest.signed_distance(bases).max()
    assert 0.0 < clearance < 0.016
    ahead = bases + [0.0, 0.02, 0.0]  # the same array 2 cm further along its axis
    assert sphere.contains(ahead).any()
