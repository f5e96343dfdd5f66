"""Recognition by leaky integration (Sec 5.2.2.2, 6.1.2.4) on hand-made experience histories."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from maps.recognition import (
    LeakyIntegrator, confidence, decide, first_crossing, integrated_confidence, recognise, relocalisation_targets,
)
from whisker_io.errors import ConfigError, InvalidInputError, ShapeError

P = LeakyIntegrator(impulse=1.0, decay=0.5, dt=1.0)


def test_targets_from_an_appended_history():
    # experiences 0-2 belong to object 0, 3-4 to object 1, 5-6 are the unknown object's own
    exp_object = np.array([0, 0, 0, 1, 1, -1, -1])
    exp_ids = np.array([5, 6, 1, 6, 3, 2, 2])
    reloc = np.array([False, False, True, False, True, True, False])
    assert relocalisation_targets(exp_ids, reloc, exp_object).tolist() == [-1, -1, 0, -1, 1, 0, -1]


def test_leaky_integrator_and_integral_by_hand():
    c = confidence(np.array([0, 0, -1, 1, 0]), 2, P)
    # object 0: 1, 1.5, 0.75, 0.375, 1.1875; object 1: 0, 0, 0, 1, 0.5
    np.testing.assert_allclose(c[:, 0], [1, 1.5, 0.75, 0.375, 1.1875])
    np.testing.assert_allclose(c[:, 1], [0, 0, 0, 1, 0.5])
    ic = integrated_confidence(c, P)
    np.testing.assert_allclose(ic[:, 0], [1, 2.5, 3.25, 3.625, 4.8125])
    np.testing.assert_allclose(ic[:, 1], [0, 0, 0, 1, 1.5])
    assert first_crossing(ic[:, 0], 3.0) == 2 and first_crossing(ic[:, 1], 3.0) is None


def test_steady_state_of_the_defaults_is_four():
    c = confidence(np.zeros(200, dtype=int), 1)
    assert c[-1, 0] == pytest.approx(4.0)  # impulse / (1 - decay), the 3-4 of Fig 6.4


def test_rc_spike_vs_ic_persistence():
    # object 1 gets a burst of 3 false re-localisations; object 0 a steady trickle
    targets = np.array([1, 1, 1] + [0, -1] * 20)
    r = recognise(targets, 2, correct=0, rc_threshold=1.6, ic_threshold=15.0, params=P)
    # c_1: 1, 1.5, 1.75 (spike) then halves; c_0 tends to 4/3 and never reaches 1.6
    assert r.rc_identity == 1 and r.max_confidence[1] == pytest.approx(1.75)
    # IC_1 tends to 1 + 1.5 + 1.75 * (1 + 1/2 + ...) = 6 < 15; IC_0 grows by ~2/3 per step
    assert r.ic_identity == 0 and r.correct_first and r.final_ic[1] == pytest.approx(6.0, abs=1e-6)


def test_im_and_srt_by_hand_with_censoring():
    # correct object 0 re-localised every step, object 1 every other step
    targets = np.array([0, 1] * 10)
    r = recognise(targets, 2, correct=0, rc_threshold=10.0, ic_threshold=5.0, params=P)
    c = confidence(targets, 2, P)
    ic = integrated_confidence(c, P)
    t0, t1 = first_crossing(ic[:, 0], 5.0), first_crossing(ic[:, 1], 5.0)
    # IC_0: 1, 1.5, 2.75, 3.375, 4.6875, 5.34375 (t = 5); IC_1 lags one step: crosses at t = 6
    assert (t0, t1) == (5, 6)
    np.testing.assert_allclose(ic[:6, 0], [1, 1.5, 2.75, 3.375, 4.6875, 5.34375])
    assert r.srt == t0 and r.im == t1 - t0 and r.correct_crossed and r.incorrect_crossed
    never = recognise(np.array([0] * 10), 2, correct=0, ic_threshold=3.0, params=P)
    assert not never.incorrect_crossed and never.im == 10 - never.srt  # censored at the end of the run
    fail = recognise(np.array([1] * 10), 2, correct=0, ic_threshold=3.0, params=P)
    assert not fail.correct_crossed and fail.srt == 10 and fail.im < 0 and not fail.correct_first


def test_decide_prefers_the_earliest_crossing():
    tr = np.array([[0, 0], [1, 3], [5, 4]], dtype=float)
    assert decide(tr, 3.0) == 1 and decide(tr, 4.5) == 0 and decide(tr, 9.0) is None


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(-1, 2), min_size=1, max_size=60), st.floats(0.0, 0.99), st.floats(0.1, 5.0))
def test_confidence_invariants(targets, decay, impulse):
    p = LeakyIntegrator(impulse=impulse, decay=decay)
    c = confidence(np.array(targets), 3, p)
    assert np.all(c >= 0) and np.all(c <= impulse / (1 - decay) + 1e-9)
    ic = integrated_confidence(c, p)
    assert np.all(np.diff(ic, axis=0) >= -1e-12)  # the integral never falls


def test_bad_input_is_typed():
    with pytest.raises(ConfigError):
        LeakyIntegrator(decay=1.0)
    with pytest.raises(ConfigError):
        LeakyIntegrator(impulse=math.nan)
    with pytest.raises(InvalidInputError):
        confidence(np.array([0, 3]), 2)
    with pytest.raises(ShapeError):
        confidence(np.zeros((2, 2), dtype=int), 2)
    with pytest.raises(InvalidInputError):
        recognise(np.array([0]), 2, correct=2)
    with pytest.raises(InvalidInputError, match="with_explored"):
        relocalisation_targets(np.array([9]), np.array([True]), np.array([0, 1]))
    with pytest.raises(InvalidInputError, match="exp_ids must be experience ids >= 0"):  # was read as "no impulse"
        relocalisation_targets(np.array([0, -3]), np.array([False, True]), np.array([0, 1]))
    with pytest.raises(InvalidInputError, match="exp_object must hold object indices"):
        relocalisation_targets(np.array([0]), np.array([True]), np.array([-2, 1]))


# ------------------------------------------------ several impulses per iteration (one model per map)
def test_leaky_step_by_hand_with_two_objects_at_once():
    from maps.recognition import confidence_from_impulses, leaky_step

    p = LeakyIntegrator(impulse=1.0, decay=0.5)
    np.testing.assert_allclose(leaky_step(np.array([2.0, 0.0, 1.0]), np.array([True, True, False]), p), [2.0, 1.0, 0.5])
    imp = np.array([[1, 1], [0, 1], [0, 0], [2, 0]])
    # hand: [1,1] -> [0.5,1.5] -> [0.25,0.75] -> [2.125,0.375]
    np.testing.assert_allclose(confidence_from_impulses(imp, p), [[1, 1], [0.5, 1.5], [0.25, 0.75], [2.125, 0.375]])


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(-1, 2), min_size=1, max_size=30))
def test_confidence_from_impulses_equals_confidence_for_single_targets(targets):
    from maps.recognition import confidence_from_impulses

    t = np.array(targets)
    imp = np.zeros((len(t), 3), dtype=bool)
    imp[np.arange(len(t))[t >= 0], t[t >= 0]] = True
    np.testing.assert_allclose(confidence_from_impulses(imp), confidence(t, 3))


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.just(np.array([np.nan, 0.0])), st.just(np.array([-1.0, 0.0])), st.just(np.zeros(3)),
                 st.just(np.zeros((2, 2)))),
       st.one_of(st.just(np.array([True, False])), st.just(np.array([-1, 0])), st.just(np.array([0.5, 0.0]))))
def test_leaky_step_bad_input_is_typed(level, impulses):
    from cansim.errors import CansimError
    from maps.recognition import leaky_step

    good = level.shape == (2,) and np.isfinite(level).all() and (level >= 0).all() and impulses.dtype.kind == "b"
    if good:
        assert leaky_step(level, impulses).shape == (2,)
    else:
        with pytest.raises(CansimError):
            leaky_step(level, impulses)


@settings(max_examples=60, deadline=None)
@given(trace=st.one_of(st.just(np.array(0.0)), st.just(np.zeros(3)), st.just(np.zeros((2, 2, 2))),
                       st.just(np.array([[np.nan, 1.0]])), st.just("abc"), st.just([[1, "x"]])),
       threshold=st.one_of(st.just(0.0), st.just(math.nan), st.just("t")))
def test_decide_refuses_what_is_not_an_n_by_objects_trace(trace, threshold):
    """decide(np.array(0.), 0.0) raised IndexError (issue 25): a trace that is not (n, n_objects) is a typed error."""
    with pytest.raises((ShapeError, InvalidInputError)):
        decide(trace, threshold)


@pytest.mark.parametrize("c", [np.array([[1.0, -0.5]]), np.array([[np.nan, 1.0]]), np.array([np.inf]), np.array(2.0),
                               [["a"]]])
def test_integrated_confidence_refuses_negative_nan_or_shapeless_confidence(c):
    """It accepted negative or NaN confidence (issue 25)."""
    with pytest.raises((InvalidInputError, ShapeError)):
        integrated_confidence(c)
