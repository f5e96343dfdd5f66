"""Arm trajectories around an object (whisker_io.sim.trajectories): the fitted surface, the facing
frame, step bounds, the two Ch.5 families, contact coverage on the Mug and the Box."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from whisker_io.array.geometry import WhiskerArray
from whisker_io.errors import CansimError, ConfigError, InvalidInputError
from whisker_io.pose import Pose
from whisker_io.sim.objects import make_object
from whisker_io.sim.sweep import MeshTarget, SweepParams, sweep_array
from whisker_io.sim.trajectories import (
    LoopShape,
    ReachChoice,
    choose_reach,
    facing_pose,
    fit_surface,
    object_trajectory,
    reaching_roll_deg,
    step_sizes,
    touch_share,
)

ARRAY = WhiskerArray.thesis()
STANDOFF = 0.015 + 0.201860  # default clearance + the rostral bases' distance along the axis (Fig 2.15)
COUNT = SweepParams(refine=False)  # which whiskers touch is decided by the coarse 1-deg pass


@pytest.fixture(scope="module")
def box():
    return make_object("box")


@pytest.fixture(scope="module")
def mug_a(mug):
    return object_trajectory(mug, "A", n_loops=2)


def _axis(pose):
    return pose.rotation.apply([0.0, 1.0, 0.0])


def _distance_along_axis(mesh, poses):
    """Distance from each end-effector origin to the mesh along the array axis (+y), m."""
    origins = np.array([p.position_m for p in poses])
    axes = np.array([_axis(p) for p in poses])
    dist, _, _ = MeshTarget(mesh).first_hits(origins, axes, np.full(len(poses), 1.0))
    return dist


# ------------------------------------------------------------- hand-computed
def test_fit_surface_through_the_bounding_box_corners(box):
    e = fit_surface(box)
    np.testing.assert_allclose(e.centre_m, [0.0, 0.0, 0.175], atol=1e-12)
    np.testing.assert_allclose(e.semi_axes_m, math.sqrt(3) * np.array([0.1, 0.1, 0.175]), atol=1e-12)
    corner = np.array([0.1, 0.1, 0.35])  # on the ellipsoid: sum (x_i / a_i)^2 = 3 * (1/3) = 1
    assert np.sum(((corner - e.centre_m) / e.semi_axes_m) ** 2) == pytest.approx(1.0)
    s = fit_surface(box, "sphere")
    np.testing.assert_allclose(s.semi_axes_m, np.full(3, math.sqrt(0.01 + 0.01 + 0.175**2)), atol=1e-12)
    np.testing.assert_allclose(e.point(0.0, 0.0), [math.sqrt(3) * 0.1, 0.0, 0.175], atol=1e-12)


def test_facing_pose_hand_computed():
    """Axis +y toward (0, 1, 0) from 0.5 m: origin (0, 0.5, 0); z is world up, x = y x z = +x:
    the identity rotation."""
    p = facing_pose([0.0, 1.0, 0.0], [0.0, 2.0, 0.0], 0.5)
    np.testing.assert_allclose(p.position_m, [0.0, 0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(p.quaternion_xyzw, [0.0, 0.0, 0.0, 1.0], atol=1e-15)
    # looking straight down: z kept from the previous pose (Alg 8), made perpendicular to the axis
    down = facing_pose([0.0, 0.0, 0.0], [0.0, 0.0, -1.0], 0.2, previous_z=[1.0, 0.0, 0.1])
    np.testing.assert_allclose(down.rotation.apply([0, 0, 1]), [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(down.position_m, [0.0, 0.0, 0.2], atol=1e-15)


def test_loops_repeat_and_steps_are_bounded(mug_a):
    n = len(mug_a)
    assert n % 2 == 0
    m = n // 2
    assert all(mug_a[k] == mug_a[k + m] for k in range(m))  # the second loop revisits the first
    ring = mug_a[:m] + mug_a[:1]  # the closing step back to the start counts too
    trans, rot = step_sizes(ring)
    cost = np.maximum(trans / 0.11, rot / math.radians(12.0))
    # every step within both bounds, and one of them reached (equal cost increments)
    assert cost.max() <= 1.0 + 1e-9
    assert np.median(cost) > 0.95


def test_array_faces_the_surface_and_stays_clear_of_it(mug, mug_a):
    target = MeshTarget(mug)
    poses = mug_a[: len(mug_a) // 2]
    dist = _distance_along_axis(mug, poses)
    assert np.all(np.isfinite(dist))  # +y (the rostral array axis) points at the object
    # backing off only ever moves away; poses interpolated between two at the standoff sit on
    # the chord, a fraction of a millimetre closer to a convex surface
    assert np.all(dist >= STANDOFF - 1e-3)
    assert np.mean(np.abs(dist - STANDOFF) < 1e-3) > 0.8  # most poses at the standoff itself
    for p in poses:  # no whisker base inside or behind the object
        bases = p.apply(ARRAY.positions_m)
        seg = bases - p.position_m
        length = np.linalg.norm(seg, axis=1)
        d, _, _ = target.first_hits(np.tile(p.position_m, (len(seg), 1)), seg / length[:, None], length)
        assert not np.isfinite(d).any()


def test_roll_convention():
    """roll_deg = 0 is Alg 8's frame: z in the (up, axis) plane on the upward side. The default
    90 deg roll turns E's x-axis downward instead."""
    box = make_object("box")
    for pose in object_trajectory(box, "A", n_loops=1, roll_deg=0.0)[::5]:
        x, y, z = pose.rotation.as_matrix().T
        up = np.array([0.0, 0.0, 1.0])
        assert abs(np.linalg.det(np.column_stack([z, y, up]))) < 1e-9 and z @ up >= 0
    for pose in object_trajectory(box, "A", n_loops=1)[::5]:
        x, y, z = pose.rotation.as_matrix().T
        assert x @ [0.0, 0.0, 1.0] < 0 and abs(z @ [0.0, 0.0, 1.0]) < 1e-9


def test_families_a_and_b_are_different_loops(mug):
    """A turns counter-clockwise about the object's vertical axis, B clockwise; B starts
    elsewhere and passes at other heights."""
    centre = fit_surface(mug).centre_m
    for family, sign in (("A", 1), ("B", -1)):
        poses = object_trajectory(mug, family, n_loops=1)
        rel = np.array([p.position_m for p in poses]) - centre
        az = np.arctan2(rel[:, 1], rel[:, 0])
        turns = (np.diff(np.append(az, az[0])) + math.pi) % (2 * math.pi) - math.pi  # closed loop
        assert np.sum(turns) == pytest.approx(sign * 2 * math.pi, abs=1e-6)
        assert np.mean(np.sign(turns) == sign) > 0.9
    a = object_trajectory(mug, "A", n_loops=1)
    b = object_trajectory(mug, "B", n_loops=1)
    assert a[0].distance_to(b[0])[0] > 0.05
    pa = np.array([p.position_m for p in a])
    pb = np.array([p.position_m for p in b])
    nearest = np.min(np.linalg.norm(pb[:, None] - pa[None], axis=2), axis=1)
    assert np.median(nearest) > 0.01  # B's whisks are not A's


@pytest.mark.parametrize("name,step_m,step_deg", [("mug", 0.11, 12.0), ("box", 0.11, 12.0), ("box", 0.03, 3.0)])
@pytest.mark.parametrize("family", ["A", "B"])
def test_most_whisks_touch_with_three_contacts(name, step_m, step_deg, family):
    mesh = make_object(name)
    target = MeshTarget(mesh)
    poses = object_trajectory(mesh, family, n_loops=1, step_m=step_m, step_deg=step_deg)
    contacts = np.array([sum(c is not None for c in sweep_array(ARRAY, target, p, COUNT))
                         for p in poses])
    assert np.mean(contacts >= 3) >= 0.85, contacts


def test_sphere_loops_touch_too(box):
    target = MeshTarget(box)
    poses = object_trajectory(box, "A", n_loops=1, shape="sphere")
    contacts = np.array([sum(c is not None for c in sweep_array(ARRAY, target, p, COUNT))
                         for p in poses])
    assert np.mean(contacts >= 3) >= 0.8


def _touching(target, pose):
    return sum(c is not None for c in sweep_array(ARRAY, target, pose, COUNT))


def _bases_cross(target, origin, rotation):
    """Does a segment from the end-effector origin to a whisker base cross the mesh? (ray casts of the test's own)"""
    bases = ARRAY.positions_m @ rotation.as_matrix().T
    length = np.linalg.norm(bases, axis=1)
    dist, _, _ = target.first_hits(np.repeat(origin[None], len(bases), axis=0), bases / length[:, None], length)
    return bool(np.isfinite(dist).any())


@pytest.mark.parametrize("name", ["duck", "blob"])
def test_reaching_for_contact_follows_its_rule_and_touches_more(name):
    """Module docstring item 6, checked pose by pose against rigid sweeps along each pose's own axis."""
    from whisker_io.sim.catalogue import resolve_object

    mesh = resolve_object(name).mesh
    target = MeshTarget(mesh)
    fixed = object_trajectory(mesh, "A", n_loops=1)
    reached = object_trajectory(mesh, "A", n_loops=2, reach_contacts=3, max_advance_m=0.12)
    assert len(reached) == 2 * len(fixed) and reached[:len(fixed)] == reached[len(fixed):]
    before, after = [], []
    for p, q in zip(fixed, reached):
        np.testing.assert_array_equal(q.quaternion_xyzw, p.quaternion_xyzw)  # orientations unchanged
        move = q.position_m - p.position_m
        along = float(move @ _axis(p))
        np.testing.assert_allclose(move, along * _axis(p), atol=1e-12)  # along its own axis only
        k = round(along / 0.01)
        assert abs(along - 0.01 * k) < 1e-9 and 0 <= k <= 12  # whole 1-cm steps, at most 12 cm
        n0 = _touching(target, p)
        counts = [n0]
        for j in range(1, k + 1):  # every step up to the chosen one: bases clear, fewer than 3 touching before it
            o = p.position_m + 0.01 * j * _axis(p)
            assert not _bases_cross(target, o, p.rotation)
            counts.append(_touching(target, Pose(o, p.quaternion_xyzw)))
        assert all(c < 3 for c in counts[:-1])
        if counts[-1] < 3:  # not reached: the most-touching step (nearest of equals), no step beyond touches more
            assert counts[-1] == max(counts) and counts.index(max(counts)) == k
            j = k + 1
            while j <= 12:
                o = p.position_m + 0.01 * j * _axis(p)
                if _bases_cross(target, o, p.rotation):
                    break
                assert _touching(target, Pose(o, p.quaternion_xyzw)) <= counts[-1]
                j += 1
        before.append(n0)
        after.append(counts[-1])
    before, after = np.array(before), np.array(after)
    assert np.all(after >= before)
    assert np.mean(after >= 3) >= np.mean(before >= 3) + 0.3, (np.mean(before >= 3), np.mean(after >= 3))


def test_reaching_for_no_contact_is_the_fixed_standoff(mug_a, mug):
    assert object_trajectory(mug, "A", n_loops=2, reach_contacts=0) == mug_a


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.integers(max_value=-1), st.integers(min_value=65), st.just(1.5), st.just(float("nan")), st.just("3")),
       st.one_of(st.floats(max_value=-1e-9), st.floats(min_value=1.0001), st.just(float("nan")), st.just(float("inf"))))
def test_bad_reach_settings_raise_typed_errors(box, reach, advance):
    with pytest.raises(InvalidInputError):
        object_trajectory(box, reach_contacts=reach)
    with pytest.raises(InvalidInputError):
        object_trajectory(box, reach_contacts=3, max_advance_m=advance)


def _share_touching(mesh, roll, k=3):
    """Share of one reaching loop's poses touched by >= k whiskers (rigid sweeps), counted here."""
    target = MeshTarget(mesh)
    loop = object_trajectory(mesh, "A", n_loops=1, roll_deg=roll, reach_contacts=k)
    return float(np.mean([_touching(target, p) >= k for p in loop]))


@pytest.mark.parametrize("name", ["torus_flat-v0", "mug", "duck"])
def test_the_roll_that_reaches_follows_its_rule(name):
    """reaching_roll_deg against shares counted here: the thesis' 90 deg unless 0 deg gives a share
    more than 0.1 higher. A torus lying flat sits between the rows of the array rolled by 90 deg
    (no pose touched by 3 whiskers) and is touched by 3 at every pose at 0 deg; the Mug keeps 90."""
    from whisker_io.sim.catalogue import resolve_object

    mesh = resolve_object(name).mesh
    at90, at0 = _share_touching(mesh, 90.0), _share_touching(mesh, 0.0)
    want = 0.0 if at0 > at90 + 0.1 else 90.0
    assert reaching_roll_deg(mesh, "A", 3) == want, (at90, at0)
    if name == "torus_flat-v0":
        assert at90 == 0.0 and at0 >= 0.9 and want == 0.0
    if name == "mug":
        assert want == 90.0
    assert reaching_roll_deg(mesh, "A", 3, candidates_deg=(0.0, 90.0)) == (90.0 if at90 > at0 + 0.1 else 0.0)
    assert reaching_roll_deg(mesh, "A", 3, min_gain=1.0) == 90.0  # no roll can gain more than every pose


@settings(max_examples=25, deadline=None)
@given(st.one_of(
    st.fixed_dictionaries({"candidates_deg": st.sampled_from([(), (float("nan"),), (90.0, float("inf")), ("x",)])}),
    st.fixed_dictionaries({"min_gain": st.one_of(st.floats(max_value=-1e-9), st.floats(min_value=1.0001),
                                                 st.just(float("nan")))}),
    st.fixed_dictionaries({"reach_contacts": st.one_of(st.integers(max_value=0), st.just(2.5))}),
    st.fixed_dictionaries({"roll_deg": st.just(0.0)}),
    st.fixed_dictionaries({"n_loops": st.just(2)}),
    st.fixed_dictionaries({"step_m": st.just(-0.1)}),
    st.fixed_dictionaries({"bogus": st.just(1)}),
))
def test_bad_roll_choices_raise_typed_errors(box, kwargs):
    with pytest.raises(CansimError) as err:
        reaching_roll_deg(box, "A", **kwargs)
    assert isinstance(err.value, (InvalidInputError, ConfigError))


def test_touch_share_counts_the_poses_touched_by_enough_whiskers(box):
    """Hand-placed poses on the Box: facing its side at the thesis standoff (every pose of the loops above
    touches with 3 or more there), facing away from it (none), and the share of a mix of the two."""
    centre = box.bounds.mean(axis=0)
    side = np.array([box.bounds[1, 0], centre[1], centre[2]])  # the middle of the Box's +x face
    facing = facing_pose(side, np.array([-1.0, 0.0, 0.0]), STANDOFF)
    away = facing_pose(centre + np.array([0.6, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), 0.0)
    touching = sum(c is not None for c in sweep_array(ARRAY, MeshTarget(box), facing, COUNT))
    assert touching >= 3  # the truth the share is counted against, from the sweep itself
    assert touch_share(box, [facing]) == 1.0 and touch_share(box, [away]) == 0.0
    assert touch_share(box, [facing, away, away, away]) == 0.25
    assert touch_share(MeshTarget(box), [facing, away], reach_contacts=touching) == 0.5
    assert touch_share(box, [facing], reach_contacts=touching + 1) == 0.0
    assert touch_share(box, (facing, away)) == 0.5  # a tuple of poses as well


@settings(max_examples=20, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.6, 0.6), st.floats(-0.6, 0.6), st.floats(0.0, 0.5),
                          st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda t: abs(t[3]) + abs(t[4]) + abs(t[5]) > 0.1), min_size=1, max_size=4),
       st.integers(1, 8))
def test_touch_share_is_a_share_and_falls_as_more_whiskers_are_asked(box, rows, k):
    poses = [facing_pose(np.array(r[:3]), np.array(r[3:]), 0.1) for r in rows]
    share = touch_share(box, poses, k)
    assert 0.0 <= share <= 1.0 and share * len(poses) == pytest.approx(round(share * len(poses)))
    assert touch_share(box, poses, k + 1) <= share <= touch_share(box, poses, max(k - 1, 1))


@pytest.mark.parametrize("poses,k", [([], 3), ("poses", 3), ([Pose.identity()], 0), ([Pose.identity()], 65),
                                      ([Pose.identity()], 2.5), ([np.zeros(7)], 3)])
def test_bad_touch_share_input_raises_typed_errors(box, poses, k):
    with pytest.raises(InvalidInputError):
        touch_share(box, poses, k)
    with pytest.raises(InvalidInputError, match="WhiskerArray"):
        touch_share(box, [Pose.identity()], 3, array="x")


@pytest.mark.parametrize("name", ["mug", "torus_flat", "duck"])
def test_choose_reach_keeps_the_standoff_where_it_touches_and_reaches_where_it_does_not(name):
    """Against shares counted here with the sweep: the Mug's fixed-standoff loop is touched by 3 whiskers at
    most poses (kept), a flat torus' at none and the duck's at few (reaching, at reaching_roll_deg's roll)."""
    from whisker_io.sim.catalogue import resolve_object

    mesh = resolve_object(name).mesh
    target = MeshTarget(mesh)
    loop = object_trajectory(mesh, "A", n_loops=1)
    counted = float(np.mean([sum(c is not None for c in sweep_array(ARRAY, target, p, COUNT)) >= 3 for p in loop]))
    choice = choose_reach(mesh)
    assert choice.standoff_touch_share == pytest.approx(counted)
    if counted >= 0.5:
        assert choice == ReachChoice(counted, 0, 90.0) and name == "mug"
    else:
        assert choice == ReachChoice(counted, 3, reaching_roll_deg(mesh, "A", 3)) and name != "mug"
    assert choose_reach(mesh, min_share=0.0).reach_contacts == 0  # nothing is below no share
    assert choose_reach(mesh, min_share=1.0).reach_contacts == (0 if counted == 1.0 else 3)
    if name == "torus_flat":
        assert counted == 0.0 and choice.roll_deg == 0.0


@settings(max_examples=20, deadline=None)
@given(st.one_of(
    st.fixed_dictionaries({"min_share": st.one_of(st.floats(max_value=-1e-9), st.floats(min_value=1.0001),
                                                  st.just(float("nan")), st.just("half"))}),
    st.fixed_dictionaries({"reach_contacts": st.one_of(st.integers(max_value=0), st.just(2.5))}),
    st.fixed_dictionaries({"roll_deg": st.just(0.0)}),
    st.fixed_dictionaries({"n_loops": st.just(2)}),
    st.fixed_dictionaries({"step_m": st.just(-0.1)}),
    st.fixed_dictionaries({"bogus": st.just(1)}),
    st.fixed_dictionaries({"array": st.just("x")}),
))
def test_bad_reach_choices_raise_typed_errors(box, kwargs):
    with pytest.raises(CansimError) as err:
        choose_reach(box, "A", **kwargs)
    assert isinstance(err.value, (InvalidInputError, ConfigError))


# ------------------------------------------------------------- bad input
def test_bad_input_raises_typed_errors(box):
    with pytest.raises(InvalidInputError, match="Trimesh"):
        object_trajectory("box")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="family"):
        object_trajectory(box, "C")
    with pytest.raises(InvalidInputError):
        object_trajectory(box, step_m=0.0)
    with pytest.raises(InvalidInputError):
        object_trajectory(box, step_deg=np.nan)
    with pytest.raises(InvalidInputError):
        object_trajectory(box, n_loops=0)
    with pytest.raises(InvalidInputError):
        object_trajectory(box, shape="cube")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError):
        object_trajectory(box, clearance_m=-0.01)
    with pytest.raises(InvalidInputError):
        object_trajectory(box, up=[0.0, 0.0, 0.0])
    with pytest.raises(InvalidInputError):
        object_trajectory(box, array="thesis")  # type: ignore[arg-type]
    with pytest.raises(ConfigError):
        LoopShape(direction=2)
    with pytest.raises(ConfigError):
        LoopShape(elevation_amplitude_deg=70.0, elevation_offset_deg=15.0)
    with pytest.raises(InvalidInputError):
        LoopShape(elevation_waves=-1)
    with pytest.raises(InvalidInputError):
        facing_pose([0, 0, 0], [0, 0, 0], 0.2)
    with pytest.raises(InvalidInputError):
        facing_pose([0, 0, np.nan], [0, 1, 0], 0.2)
    with pytest.raises(InvalidInputError, match="up"):
        facing_pose([0, 0, 0], [0, 1, 0], 0.2, up=[0, 0, 0])
    with pytest.raises(InvalidInputError, match="previous_z"):
        facing_pose([0, 0, 0], [0, 0, 1], 0.2, previous_z=[0, 0, 0])


# ------------------------------------------------------------- properties
@settings(max_examples=30, deadline=None)
@given(st.floats(0.02, 0.3), st.floats(2.0, 30.0), st.floats(0.0, 40.0), st.integers(0, 4),
       st.sampled_from([1, -1]), st.floats(-180, 180), st.sampled_from(["ellipsoid", "sphere"]))
@example(0.0625, 2.0, 35.75, 3, 1, 0.0, "ellipsoid")  # found by hypothesis: a chord 4.0 mm inside the standoff
def test_any_loop_gives_valid_bounded_poses(box, step_m, step_deg, amplitude, waves, direction, start, shape):
    loop = LoopShape(azimuth_start_deg=start, direction=direction, elevation_amplitude_deg=amplitude,
                     elevation_waves=waves)
    poses = object_trajectory(box, loop, n_loops=1, step_m=step_m, step_deg=step_deg, shape=shape)
    assert len(poses) >= 3
    for p in poses:
        assert np.all(np.isfinite(p.position_m)) and np.linalg.norm(p.quaternion_xyzw) == pytest.approx(1.0)
    trans, rot = step_sizes(poses + poses[:1])
    cost = np.maximum(trans / step_m, rot / math.radians(step_deg))
    # the bound holds between poses at the standoff; a pose that backed off (its bases would be
    # behind a face it sees obliquely) may exceed it by the back-off
    dist = _distance_along_axis(box, poses)
    # interpolated poses round a corner cut it (a chord between two dense poses): within millimetres - 4.0 mm at
    # the example above, on a 0.22-m standoff (step 2 deg, elevation waving 3 times by 36 deg); no bound documented
    assert np.all(dist >= STANDOFF - 5e-3)
    at_standoff = dist < STANDOFF + 2.5e-3
    both = at_standoff & np.roll(at_standoff, -1)
    assert np.all(cost[both] <= 1.0 + 1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       st.floats(0.0, 1.0))
@example([0.0, 0.0, 0.0], [0.0, 0.0, 1.29e-158], 0.5)  # found by hypothesis: its norm underflowed
@example([0.1, 0.0, 0.0], [3e-170, -4e-170, 0.0], 0.2)
def test_facing_pose_points_its_axis(point, axis, standoff):
    a = np.asarray(axis)
    try:
        p = facing_pose(point, axis, standoff)
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError) and not np.any(a)
        return
    y = a / np.abs(a).max()  # scaled first: the squares of an axis of 1e-158 underflow
    y /= np.linalg.norm(y)
    np.testing.assert_allclose(_axis(p), y, atol=1e-9)
    np.testing.assert_allclose(p.position_m + standoff * y, point, atol=1e-9)
    R = p.rotation.as_matrix()
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) == pytest.approx(1.0)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0.01, 1.0), min_size=3, max_size=3), st.lists(st.floats(-1, 1), min_size=3, max_size=3))
def test_fitted_surface_encloses_the_box(extents, centre):
    import trimesh

    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(centre)
    for shape in ("ellipsoid", "sphere"):
        e = fit_surface(mesh, shape)
        inside = np.sum(((mesh.vertices - e.centre_m) / e.semi_axes_m) ** 2, axis=1)
        assert np.all(inside <= 1.0 + 1e-9)  # every vertex inside or on the surface
        assert np.max(inside) == pytest.approx(1.0)  # and the corners on it


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       st.one_of(st.none(), st.lists(st.floats(-1, 1), min_size=3, max_size=3)))
@example([0.0, 0.0, 1.0], [0.0, 0.0, 1e-170], None)  # an up whose squares underflow
@example([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 2.0])  # vertical axis, previous z along it
def test_facing_pose_any_up_and_previous_z_give_a_rotation_or_a_typed_error(axis, up, previous_z):
    """A vertical axis takes its roll from ``previous_z`` (or x when that lies along the axis); any
    non-zero up and previous z give a proper rotation whose y is the axis; zero ones a typed error."""
    a = np.asarray(axis)
    try:
        p = facing_pose([0.0, 0.0, 0.0], axis, 0.3, previous_z, up)
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        assert not np.any(a) or not np.any(up) or (previous_z is not None and not np.any(previous_z))
        return
    R = p.rotation.as_matrix()
    assert np.all(np.isfinite(R))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(R) == pytest.approx(1.0)
    y = a / np.abs(a).max()
    np.testing.assert_allclose(R[:, 1], y / np.linalg.norm(y), atol=1e-9)


def test_poses_left_inside_the_object_are_named_with_the_mesh_and_counted(monkeypatch, caplog):
    """The warning names the trajectory, the mesh (its file, or its extents) and how many of how many poses."""
    import logging

    import trimesh

    from whisker_io.sim import trajectories

    monkeypatch.setattr(trajectories, "_bases_blocked", lambda target, origin, R, bases: np.ones(len(origin), bool))
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.3))
    with caplog.at_level(logging.WARNING, logger="whisker_io"):
        poses = object_trajectory(box, "B", 1)
    msg = [r.getMessage() for r in caplog.records if "behind the surface" in r.getMessage()]
    assert len(msg) == 1
    assert msg[0].startswith(f"trajectory B of the mesh of extents [0.2, 0.2, 0.3] m: {len(poses)} of {len(poses)} poses")
    box.metadata["file_name"] = "my_box.stl"
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="whisker_io"):
        object_trajectory(box, "B", 1)
    assert any(r.getMessage().startswith("trajectory B of my_box.stl:") for r in caplog.records)
