"""Tactile place recognition of Ch.3 (issue 24): the sequence matcher, its calibration and the onset fix.

Covers :mod:`cansim.frontends.tactile_sequence` (hand-built image streams whose right
answer is known), :meth:`whisker_io.contact.contact_angle.ContactAngleParams.ch3` against
the signal model's truth, the study's recognition switch and the typed errors of the
new entry points (hypothesis).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cansim.errors import CansimError
from cansim.frontends.tactile_sequence import (
    TactileSequenceConfig,
    TactileSequenceMatcher,
    calibrate_threshold,
    sequence_distances,
)
from whisker_io.contact.contact_angle import CH3_DETECTION, ContactAngleParams, contact_angle
from whisker_io.errors import InvalidInputError, ShapeError
from whisker_io.sim.signals import WhiskContact, simulate_whisk_cycle

HYP = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _route(n: int, seed: int = 0) -> np.ndarray:
    """``n`` places whose images are random and so all distinct (Eq 3.1 between them is large)."""
    return np.random.default_rng(seed).integers(1, 256, size=(n, 3, 6)).astype(np.uint8)


# ----------------------------------------------------------------- the matcher on streams with a known answer
def test_second_pass_gets_the_first_pass_ids_after_the_sequence_and_the_consistency_wait():
    L, cons = 4, 2
    places = _route(40)
    m = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=L, exclude_recent=10, min_consistent=cons, min_informative=0))
    first = [m.match(img) for img in places]
    assert [r.template_id for r in first] == list(range(40)) and all(r.is_new for r in first)
    second = [m.match(img) for img in places]
    # cycle t of the second pass compares places t-3..t with themselves: a match from t = L-1 on,
    # reported once the best candidates of `cons` consecutive cycles advanced in step: t >= L-1 + cons-1
    start = L - 1 + cons - 1
    assert all(r.is_new for r in second[:start])
    assert [r.template_id for r in second[start:]] == list(range(start, 40))
    assert all(r.error == 0.0 for r in second[start:])
    assert len(m) == 40 + start and m.n_cycles == 80


def test_a_single_coincident_image_or_a_short_run_never_matches():
    places = _route(60, seed=1)
    m = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=3, exclude_recent=5, min_consistent=1, min_informative=0))
    for img in places:
        m.match(img)
    # the image of place 10 again, between fresh images: its 3-sequence differs in two images
    fresh = _route(3, seed=2)
    results = [m.match(img) for img in (fresh[0], fresh[1], places[10], fresh[2])]
    assert all(r.is_new for r in results)


def test_blank_sequences_are_not_evidence_of_a_place():
    blank = np.zeros((3, 6), dtype=np.uint8)
    m = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=4, exclude_recent=5, min_consistent=1, min_informative=2))
    ids = [m.match(blank).template_id for _ in range(30)]
    assert ids == list(range(30))  # blank after blank: never a match, whatever the distance (0)
    # without the informativeness requirement the same stream matches itself as soon as it can
    lax = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=4, exclude_recent=5, min_consistent=1, min_informative=0, distinct_ratio=1.0))
    assert not all(lax.match(blank).is_new for _ in range(30))


def test_an_ambiguous_periodic_route_is_rejected_by_the_distinctiveness_test():
    period = _route(6, seed=3)
    stream = np.concatenate([period] * 8)  # the same 6 images again and again: every period matches equally
    # (without tracking: a track acquired while only one period was stored would be followed)
    cfg = TactileSequenceConfig(sequence_length=4, exclude_recent=12, min_consistent=1, min_informative=0, distinct_cycles=3, track=False)
    strict = TactileSequenceMatcher(cfg)
    strict_new = [strict.match(img).is_new for img in stream]
    # candidates of cycle t: j = 3 .. t - 13; the first j in phase with t is at most 3 + 5, its twin 6
    # later: two equally good candidates for every t >= 3 + 5 + 6 + 13 = 27
    assert all(strict_new[27:])
    loose = TactileSequenceMatcher(dataclasses.replace(cfg, distinct_ratio=1.0))
    loose_new = [loose.match(img).is_new for img in stream]
    assert not any(loose_new[27:])


def test_a_recognised_route_is_followed_along_a_uniform_wall():
    # distinct places, then 10 cycles along a uniform wall (the same image), then distinct places again
    wall = np.full((10, 3, 6), 90, dtype=np.uint8)
    lap = np.concatenate([_route(20, seed=5), wall, _route(20, seed=6)])
    cfg = TactileSequenceConfig(sequence_length=4, exclude_recent=10, min_consistent=2, min_informative=0, distinct_cycles=3)
    for track in (False, True):
        m = TactileSequenceMatcher(dataclasses.replace(cfg, track=track))
        for img in lap:
            m.match(img)
        second = [m.match(img) for img in lap]
        # cycle 23 of the lap on: its 4-window lies on the wall, where every candidate 3 or more cycles away is as good
        on_wall = [r.is_new for r in second[24:30]]
        if track:  # followed from the distinct approach: the first lap's ids throughout
            assert [r.template_id for r in second[4:]] == list(range(4, len(lap)))
        else:  # acquiring a place there is refused: new ids on the wall
            assert all(on_wall)


def test_match_all_equals_matching_one_by_one():
    stream = np.concatenate([_route(25, seed=4)] * 2)
    cfg = TactileSequenceConfig(sequence_length=3, exclude_recent=8, min_consistent=2, min_informative=0)
    one = TactileSequenceMatcher(cfg)
    ids = [one.match(img).template_id for img in stream]
    np.testing.assert_array_equal(TactileSequenceMatcher(cfg).match_all(stream), ids)


# ----------------------------------------------------------------- distances and calibration by hand
def test_sequence_distances_against_hand_computed_eq_3_1():
    a = np.zeros((3, 3, 6), dtype=np.uint8)
    a[1, 0, 0] = 16  # S(a0, a1) = sqrt(16) = 4
    a[2, 2, 5] = 9  # S(a0, a2) = 3, S(a1, a2) = 4 + 3 = 7
    d1 = sequence_distances(a, 1)
    np.testing.assert_allclose(d1, [[0, 4, 3], [4, 0, 7], [3, 7, 0]])
    d2 = sequence_distances(a, 2)
    assert np.all(np.isinf(d2[0])) and np.all(np.isinf(d2[:, 0]))
    # D[2, 1] = (S(a2, a1) + S(a1, a0)) / 2 = (7 + 4) / 2; D[1, 2] the same pairs; D[1, 1] = D[2, 2] = 0
    np.testing.assert_allclose(d2[1:, 1:], [[0.0, 5.5], [5.5, 0.0]])


def test_calibrated_threshold_is_the_lower_quantile_of_the_different_place_distances():
    diff = np.arange(1000, dtype=np.float64)  # 0..999
    assert calibrate_threshold(diff, 0.01) == 9.0  # lower 1 % quantile: index floor(0.01 * 999) = 9
    assert calibrate_threshold(np.r_[diff, np.inf, np.nan], 0.01) == 9.0  # non-finite values are ignored
    assert np.mean(diff <= calibrate_threshold(diff, 0.05)) <= 0.05 + 1 / 1000


# ----------------------------------------------------------------- onset with the Ch.3 contact threshold
@pytest.mark.parametrize("angle_deg, radial_m", [(40.0, 0.08), (44.0, 0.095), (46.0, 0.095)])
def test_ch3_onset_finds_the_light_late_contacts_the_ch5_pipeline_misses(angle_deg, radial_m):
    # a low wall touched late in the protraction bends the whisker by 100-450 counts, under the
    # Ch.5 pipeline's 500-count prominence; Sec 3.2.2's 80-count threshold sees it at the right angle
    (rec,), _ = simulate_whisk_cycle([WhiskContact(math.radians(angle_deg), radial_m, 0.1)], seed=4)
    assert contact_angle(rec, ContactAngleParams("onset")) is None
    found = contact_angle(rec, ContactAngleParams.ch3("onset"))
    assert found == pytest.approx(math.radians(angle_deg), abs=math.radians(0.5))
    (free,), _ = simulate_whisk_cycle([None], seed=4)
    assert contact_angle(free, ContactAngleParams.ch3("onset")) is None  # noise alone is no contact
    assert ContactAngleParams.ch3("onset").detection == CH3_DETECTION
    assert ContactAngleParams.ch3("max_angle") == ContactAngleParams("max_angle", detection=CH3_DETECTION)


# ----------------------------------------------------------------- the study's recognitions
def test_study_recognitions_feed_ratslam_as_documented():
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig
    from cansim.frontends.tactile import TactileTemplateConfig
    from cansim.studies import ch3_maze as study
    from whisker_io.sim.ch3_scene import MazeRoute, ch3_terrain

    settings_ = dataclasses.replace(study.QUICK, loops=(1, 1))
    rec = study.simulate(MazeRoute(), ch3_terrain(), settings_, "open_loop", 7)
    # thesis_ch3: exactly RatSLAM with Table 3.1 and the tactile front end on the raw images
    slam, ids = study.run_slam(rec, "threshold", 6.0, 0.1, "thesis_ch3")
    ref = RatSLAM(RatSLAMConfig.thesis_ch3(frontend=TactileTemplateConfig(match_threshold=6.0), inject_energy=0.1))
    np.testing.assert_array_equal(ids, ref.run(rec.run.vtrans, rec.run.vrot, rec.run.dt, rec.observations("threshold")).exp_ids)
    # sequence: one view per shown whisk cycle, None where a cycle is shown again or none is complete
    views = study.sequence_view_ids(rec, "threshold", study.SEQUENCE)
    shown = rec.image_index
    for k, v in enumerate(views):
        assert (v is None) == (shown[k] < 0 or (k > 0 and shown[k] == shown[k - 1]))
    assert len({v for v in views if v is not None}) <= len(rec.cycles())
    # the reference recognition: a revisited cycle takes the id of the first cycle at its true place
    truth_views = study.true_place_view_ids(rec)
    cycles, poses = rec.cycles(), rec.whisk_poses
    first_cycle: dict[int, int] = {}
    for k, v in enumerate(truth_views):
        if v is None:
            continue
        j = int(shown[k])
        if v in first_cycle:
            i = first_cycle[v]
            assert math.hypot(*(poses[j, :2] - poses[i, :2])) < 0.015 and j - i >= study.SEQUENCE.exclude_recent
        else:
            first_cycle[v] = j
    assert len(first_cycle) < len(cycles)  # the second loop revisits the first
    with pytest.raises(ValueError, match="recognition"):
        study.run_slam(rec, "threshold", 6.0, 0.1, "no such")


# ----------------------------------------------------------------- typed errors and invariants (hypothesis)
@HYP
@given(st.sampled_from(["sequence_length", "match_threshold", "min_informative", "exclude_recent", "min_consistent", "distinct_ratio",
                        "distinct_cycles"]),
       st.one_of(st.just(-1), st.just(0), st.just(1.5), st.just(math.nan), st.just(math.inf), st.just(2.0), st.just("8"), st.none()))
def test_bad_configs_raise_typed_errors(field, value):
    try:
        TactileSequenceConfig(**{field: value})
    except CansimError:
        return
    # accepted: the value is valid for the field
    ok = {
        "sequence_length": lambda v: isinstance(v, int) and v >= 1,
        "match_threshold": lambda v: isinstance(v, (int, float)) and math.isfinite(v) and v >= 0,
        "min_informative": lambda v: isinstance(v, int) and 0 <= v <= 8,
        "exclude_recent": lambda v: isinstance(v, int) and v >= 0,
        "min_consistent": lambda v: isinstance(v, int) and v >= 1,
        "distinct_ratio": lambda v: isinstance(v, (int, float)) and 0 <= v <= 1,
        "distinct_cycles": lambda v: isinstance(v, int) and v >= 1,
    }[field]
    assert ok(value) and not isinstance(value, bool)


@HYP
@given(st.sampled_from(["shape", "float", "negative", "big", "nan"]))
def test_bad_images_raise_typed_errors_and_leave_the_matcher_unchanged(fault):
    m = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=2, exclude_recent=2, min_consistent=1, min_informative=0))
    for img in _route(6):
        m.match(img)
    before = (len(m), m.n_cycles)
    bad = {"shape": np.zeros((6, 3), np.uint8), "float": np.zeros((3, 6)), "negative": np.full((3, 6), -1),
           "big": np.full((3, 6), 256), "nan": np.full((3, 6), np.nan)}[fault]
    with pytest.raises((ShapeError, InvalidInputError)):
        m.match(bad)
    assert (len(m), m.n_cycles) == before
    with pytest.raises((ShapeError, InvalidInputError)):
        m.match_all(bad[None])
    with pytest.raises((ShapeError, InvalidInputError)):
        sequence_distances(bad[None], 1)


@HYP
@given(st.lists(st.integers(0, 5), min_size=1, max_size=80), st.integers(1, 5), st.integers(0, 10), st.integers(1, 3))
def test_ids_are_new_or_earlier_and_errors_never_nan(stream, L, exclude, cons):
    palette = _route(6, seed=9)
    palette[0] = 0  # one blank image
    m = TactileSequenceMatcher(TactileSequenceConfig(sequence_length=L, exclude_recent=exclude, min_consistent=cons, min_informative=0))
    handed = 0
    for i in stream:
        r = m.match(palette[i])
        assert not math.isnan(r.error)
        if r.is_new:
            assert r.template_id == handed
            handed += 1
        else:
            assert 0 <= r.template_id < handed and r.error <= m.config.match_threshold
    assert len(m) == handed


@HYP
@given(st.one_of(st.just([]), st.just([math.nan]), st.just([math.inf])), st.floats(-1.0, 2.0))
def test_calibration_refuses_empty_distributions_and_bad_rates(values, rate):
    with pytest.raises(InvalidInputError):
        calibrate_threshold(values, 0.01)
    if not 0.0 < rate < 1.0:
        with pytest.raises(InvalidInputError):
            calibrate_threshold([1.0, 2.0], rate)
