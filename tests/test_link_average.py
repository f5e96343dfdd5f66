"""Tests of the experience map's ``link_update="average"`` (maps.link_average): a link driven again
becomes the running mean of its traversals; the default keeps OpenRatSLAM's first traversal."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from maps.experience_map import ExperienceMap, MapConfig
from maps.link_average import average_se2_link, invert_se2_link
from maps.se2 import SE2Geometry
from maps.se3 import SE3Geometry
from whisker_io.errors import ConfigError, CorruptFileError, InvalidInputError, ShapeError

R2 = math.sqrt(0.5)


def three_experiences(link_update="first"):
    """Experiences 0 -> 1 -> 2, 1 m apart straight ahead (1 s each), then a re-localisation 2 -> 0."""
    em = ExperienceMap(MapConfig(relax_budget=None, link_update=link_update), SE2Geometry(initial_heading_deg=0.0))
    em.update((0, 0, 0), 0, 0)
    em.on_odo(1.0, 0.0, 1.0)
    em.update((5, 0, 0), 1, 0)
    em.on_odo(1.0, 0.0, 1.0)
    em.update((10, 0, 0), 2, 1)
    em.on_odo(1.0, math.pi, 2.0)
    em.update((0, 0, 0), 0, 2)  # view 0, packet on exp 0: link 2 -> 0, exp 0 current
    assert em.current_id == 0 and em.n_links == 3
    return em


def drive_0_to_1_with_a_left_turn(em):
    """From exp 0: turn left by 90 deg, then 1 m (1 s) - then view 1 again (link 0 -> 1 exists)."""
    em.on_odo(1.0, math.pi / 2, 1.0)  # rotate first, then translate: 1 m at +90 deg, facing +90 deg
    r = em.update((5, 0, 0), 1, 0)
    assert r.relocalised and r.exp_id == 1 and not r.new_link


def test_forward_traversal_is_averaged_hand_computed():
    em = three_experiences("average")
    drive_0_to_1_with_a_left_turn(em)
    ends, data = em.links
    assert ends.tolist() == [[0, 1], [1, 2], [2, 0]]
    # link 0->1: first (d 1, heading 0, facing 0, 1 s), now (1, pi/2, pi/2, 1 s).
    # Mean displacement (0.5, 0.5) m: d = sqrt(0.5), heading pi/4; mean facing pi/4; dt 1 s.
    np.testing.assert_allclose(data[0], [R2, math.pi / 4, math.pi / 4, 1.0], atol=1e-12)
    np.testing.assert_allclose(data[1], [1.0, 0.0, 0.0, 1.0], atol=1e-12)  # untouched
    assert em.link_traversals.tolist() == [2, 1, 1]


def test_reverse_traversal_is_inverted_then_averaged_hand_computed():
    em = three_experiences("average")
    em.on_odo(1.0, 0.0, 1.0)
    em.update((5, 0, 0), 1, 0)  # 0 -> 1 straight again: the mean stays (1, 0, 0)
    np.testing.assert_allclose(em.links[1][0], [1.0, 0.0, 0.0, 1.0], atol=1e-12)
    # from exp 1: turn around and drive 1 m (1 s), then turn a further +90 deg (1 s): seen from
    # exp 1, exp 0 is 1 m at heading pi with facing -pi/2. From exp 0, exp 1 is then 1 m at
    # heading pi/2 with facing pi/2, so the mean of (1, 0, 0) x 2 and that is: displacement
    # (2/3, 1/3) m, facing pi/6, dt (1 + 1 + 2) / 3 s.
    em.on_odo(1.0, math.pi, 1.0)
    em.on_odo(0.0, math.pi / 2, 1.0)
    r = em.update((0, 0, 0), 0, 1)
    assert r.relocalised and r.exp_id == 0 and not r.new_link
    d, heading = math.hypot(2 / 3, 1 / 3), math.atan2(1 / 3, 2 / 3)
    np.testing.assert_allclose(em.links[1][0], [d, heading, math.pi / 6, 4 / 3], atol=1e-12)
    assert em.link_traversals.tolist() == [3, 1, 1]


def test_default_keeps_the_first_traversal_as_openratslam():
    for em in (three_experiences(), three_experiences("first")):
        drive_0_to_1_with_a_left_turn(em)
        np.testing.assert_allclose(em.links[1][0], [1.0, 0.0, 0.0, 1.0], atol=1e-12)
        assert em.link_traversals.tolist() == [1, 1, 1]


def test_default_map_file_is_unchanged_and_a_map_without_link_update_loads(tmp_path):
    em = three_experiences()
    arrays = em.to_arrays()
    assert "link_update" not in str(arrays["config"]) and "link_traversals" not in arrays
    # a file written before the option existed is exactly such a file: it loads as "first"
    em.save(tmp_path / "old.npz")
    back = ExperienceMap.load(tmp_path / "old.npz")
    assert back.config.link_update == "first" and back.config == em.config


def test_average_save_load_round_trip_and_resume(tmp_path):
    em, ref = three_experiences("average"), three_experiences("average")
    drive_0_to_1_with_a_left_turn(em)
    drive_0_to_1_with_a_left_turn(ref)
    em.save(tmp_path / "m.npz")
    back = ExperienceMap.load(tmp_path / "m.npz")
    assert back.config.link_update == "average"
    assert back.link_traversals.tolist() == [2, 1, 1]
    np.testing.assert_array_equal(back.links[1], em.links[1])
    for m in (back, ref):  # a resumed map averages on exactly as the uninterrupted one
        m.on_odo(0.0, math.pi, 1.0)
        m.update((0, 0, 0), 0, 1)
    np.testing.assert_array_equal(back.links[1], ref.links[1])
    np.testing.assert_array_equal(back.poses, ref.poses)
    assert back.link_traversals.tolist() == ref.link_traversals.tolist() == [3, 1, 1]


def test_average_file_with_bad_traversals_is_refused(tmp_path):
    em = three_experiences("average")
    arrays = em.to_arrays()
    missing = {k: v for k, v in arrays.items() if k != "link_traversals"}
    with pytest.raises(CorruptFileError, match="link_traversals"):
        ExperienceMap.from_arrays(missing)
    with pytest.raises(CorruptFileError, match="link_traversals"):
        ExperienceMap.from_arrays({**arrays, "link_traversals": np.zeros(3, dtype=np.int64)})


def test_graph_weights_follow_the_averaged_link():
    em = three_experiences("average")
    g = em.graph
    drive_0_to_1_with_a_left_turn(em)
    assert g.edges[0, 1]["w_t"] == pytest.approx(R2, abs=1e-12)
    assert g.edges[1, 0]["w_r"] == pytest.approx(math.pi / 4, abs=1e-12)


def test_inverse_of_the_inverse_is_the_link():
    link = (1.3, 0.4, -2.0, 0.7)
    inv = invert_se2_link(link)
    np.testing.assert_allclose(inv, (1.3, 0.4 + math.pi + 2.0 - 2 * math.pi, 2.0, 0.7), atol=1e-12)
    np.testing.assert_allclose(invert_se2_link(inv), link, atol=1e-12)
    # averaging a link with itself changes nothing
    np.testing.assert_allclose(average_se2_link(link, link, 5), link, atol=1e-12)


@given(st.one_of(st.text(max_size=8), st.integers(), st.none(), st.booleans(), st.floats()))
def test_bad_link_update_is_refused(value):
    if value in ("first", "average"):
        return
    with pytest.raises(ConfigError, match="link_update"):
        MapConfig(link_update=value)


def test_average_on_an_se3_map_is_refused():
    with pytest.raises(ConfigError, match="SE2Geometry"):
        ExperienceMap(MapConfig(pc_shape=(10, 10, 10, 10, 10, 10), offset_axes=(), link_update="average"), SE3Geometry())


angle = st.floats(-3.1, 3.1)
link_st = st.tuples(st.floats(0.0, 5.0), angle, angle, st.floats(0.0, 100.0))


@given(link_st, link_st, st.integers(1, 1000))
def test_mean_lies_between_old_and_new_and_inverse_round_trips(old, new, n):
    """Invariants: inverting twice is the identity; the new mean's displacement is on the segment
    from the old mean's to the observation's, at 1 / (n + 1) of the way."""
    np.testing.assert_allclose(invert_se2_link(invert_se2_link(old)), old, atol=1e-9)
    d, h, _, t = average_se2_link(old, new, n)
    xy0 = np.array([old[0] * math.cos(old[1]), old[0] * math.sin(old[1])])
    xy1 = np.array([new[0] * math.cos(new[1]), new[0] * math.sin(new[1])])
    np.testing.assert_allclose([d * math.cos(h), d * math.sin(h)], xy0 + (xy1 - xy0) / (n + 1), atol=1e-9)
    assert min(old[3], new[3]) - 1e-9 <= t <= max(old[3], new[3]) + 1e-9


@given(st.sampled_from([math.nan, math.inf, -math.inf]), st.integers(0, 3))
def test_non_finite_links_are_refused(bad, i):
    link = [1.0, 0.0, 0.0, 1.0]
    link[i] = bad
    with pytest.raises(InvalidInputError):
        invert_se2_link(link)
    with pytest.raises(InvalidInputError):
        average_se2_link(link, [1.0, 0.0, 0.0, 1.0], 1)


@given(st.one_of(st.integers(max_value=0), st.floats(0.1, 0.9), st.booleans()))
def test_bad_traversal_counts_are_refused(n):
    with pytest.raises(InvalidInputError, match="n_before"):
        average_se2_link([1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], n)


def test_wrong_length_links_are_refused():
    with pytest.raises(ShapeError):
        average_se2_link([1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 1.0], 1)
