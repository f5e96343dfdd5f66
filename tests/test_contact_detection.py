"""Tests of contact detection (Sec 5.1.1.1.1), the Ch.3 angle alternatives and contact features."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whisker_io.contact.detection import (
    DetectedContact,
    DetectionParams,
    detect_contact,
    detect_contacts,
    max_angle,
    moving_average,
    threshold_contact_angle,
)
from whisker_io.contact.features import FEATURE_NAMES, contact_features, whisk_features
from whisker_io.array.control import OpenLoop, RetractAtMax, WhiskPattern
from whisker_io.errors import InvalidInputError
from whisker_io.records.whisk_record import WhiskRecord
from whisker_io.sim.signals import SignalParams, WhiskContact, bending_stiffness, simulate_rod_contact, simulate_whisk_cycle

FS = 2000.0


def _hinge_record(onset=600, rise=400, hold=300, slope=5.0, T=2400, sign=1.0, noise=0.0, seed=0, tail=0.0):
    """Flat, linear rise from ``onset`` (first deflected sample), flat top, linear fall, flat."""
    k = np.arange(T, dtype=float)
    up = np.clip(k - (onset - 1), 0, rise) * slope
    down = np.clip(k - (onset - 1 + rise + hold), 0, rise) * slope
    y = sign * (up - down) + tail * (k >= T - 200)
    y = y + np.random.default_rng(seed).normal(0, noise, T) if noise else y
    angle = -0.8 + 1.6 * k / T  # linear sweep, rad
    return WhiskRecord("A1", angle, np.zeros(T), y)


def test_hinge_signal_onset_peak_offset_exact():
    rec = _hinge_record()
    c = detect_contact(rec)
    assert isinstance(c, DetectedContact)
    assert c.onset_index == 600  # first deflected sample
    # peak: first sample whose smoothed value is within 20 counts of the 2000-count top. The
    # raw top starts at 999; the centred mean at k misses 0.05 n (n + 1) / 2 counts with
    # n = 1049 - k, which is <= 20 from n = 27, i.e. k = 1022
    assert c.peak_index == 1022
    assert c.offset_index == 600 - 1 + 400 + 300 + 400  # first sample back at zero
    assert c.sign == 1 and c.amplitude_counts == pytest.approx(2000.0)
    assert c.contact_angle_rad == pytest.approx(rec.angle_rad[600])
    assert c.onset_time_s == pytest.approx(600 / FS)


def test_negative_deflection_is_detected_with_sign():
    c = detect_contact(_hinge_record(sign=-1.0, noise=4.0))
    assert c.sign == -1 and abs(c.onset_index - 600) <= 4 and c.amplitude_counts > 1900
    assert detect_contact(_hinge_record(sign=-1.0), DetectionParams(signs=(1,))) is None


def test_thresholds_reject_small_narrow_and_unconfirmed_peaks():
    assert detect_contact(_hinge_record(slope=1.0, noise=4.0)) is None  # 400-count peak < 500 prominence
    wide = _hinge_record(rise=100, hold=100, slope=20.0)  # half-prominence width ~ 200 samples
    assert detect_contact(wide) is not None
    assert detect_contact(wide, DetectionParams(min_width_samples=300)) is None
    stuck = _hinge_record(hold=2000, T=3000)  # still deflected at the end: baseline = peak
    assert detect_contact(stuck) is None
    assert detect_contact(_hinge_record(noise=4.0, slope=0.0)) is None


def test_ch3_alternatives_max_and_threshold_angle():
    rec = _hinge_record(slope=10.0, rise=200)
    assert max_angle(rec) == pytest.approx(rec.angle_rad.max())
    # smoothed derivative of a 10 count/sample ramp rises linearly over the 100-sample
    # window starting 50 samples before the kink: 2500 counts/s = 1.25 count/sample
    # is crossed 12.5 samples into that window
    got = threshold_contact_angle(rec, threshold_counts_per_s=2500.0)
    k = 600 - 50 + 12
    assert rec.angle_rad[k - 2] <= got <= rec.angle_rad[k + 2]
    assert threshold_contact_angle(_hinge_record(slope=0.0, noise=4.0, seed=3)) is None


def _simulated_batch(controller_cls, frequency, L, rng, n_contacts=8, n_free=4):
    pat = WhiskPattern(frequency_hz=frequency)
    contacts = [
        WhiskContact(math.radians(rng.uniform(-40, 30)), a, L)
        for a in np.linspace(0.025, 0.9 * L, n_contacts)
    ] + [None] * n_free
    return simulate_whisk_cycle(contacts, controller_cls(pat), seed=int(rng.integers(2**31)))


def test_acceptance_detection_rate_onset_and_angle_across_distances_and_speeds():
    """>= 98 % of contacts found, no false contact, onset within 5 ms, angle within 2 deg."""
    rng = np.random.default_rng(2024)
    found = total = false = free = 0
    onset_err, angle_err = [], []
    for controller_cls in (OpenLoop, RetractAtMax):
        for frequency in (0.2, 0.5, 1.0, 2.0, 2.5):
            for L in (0.06, 0.1, 0.16):
                recs, truths = _simulated_batch(controller_cls, frequency, L, rng)
                for truth, det in zip(truths, detect_contacts(recs)):
                    if truth is None:
                        free += 1
                        false += det is not None
                        continue
                    if abs(truth.peak_y_counts) < 1000:  # too weak to be a contact for the thesis' 500-count rule
                        continue
                    total += 1
                    if det is not None:
                        found += 1
                        onset_err.append(abs(det.onset_index - truth.onset_index) / FS)
                        angle_err.append(abs(det.contact_angle_rad - truth.contact_angle_rad))
    assert free == 120 and false == 0
    assert total >= 200 and found / total >= 0.98
    assert max(onset_err) <= 5e-3
    assert math.degrees(max(angle_err)) <= 2.0


def test_rod_mode_contacts_are_detected():
    p = SignalParams.evans2013()
    rng = np.random.default_rng(7)
    errs = []
    for a in np.linspace(0.08, 0.18, 6):
        for speed in (0.036, 0.108, 0.216):
            rec, truth = simulate_rod_contact(a, 0.185, speed, p, seed=int(rng.integers(2**31)))
            det = detect_contact(rec)
            assert det is not None
            errs.append(abs(det.onset_index - truth.onset_index) / FS)
    assert np.median(errs) <= 2e-3 and max(errs) <= 10e-3


def test_batch_detection_equals_single():
    rng = np.random.default_rng(1)
    recs, _ = _simulated_batch(OpenLoop, 1.0, 0.1, rng)
    rod, _ = simulate_rod_contact(0.1, 0.185, 0.1, SignalParams.evans2013(), seed=2)
    mixed = recs + [rod]  # different lengths in one batch
    assert detect_contacts(mixed) == [detect_contact(r) for r in mixed]


def test_features_of_hinge_signal_hand_computed():
    rec = _hinge_record(onset=600, rise=1000, hold=200, slope=2.0, T=3000)
    c = detect_contact(rec)
    f = whisk_features(rec, c, 0.1)
    assert FEATURE_NAMES == ("CP", "CA", "DV", "DA", "AV", "AA", "WL")
    assert f[0] == pytest.approx((c.peak_index - 600) / FS)
    assert f[1] == pytest.approx(2000.0, abs=25.0)
    assert f[2] == pytest.approx(2.0 * FS, rel=0.06)  # 2 counts/sample = 4000 counts/s
    assert f[4] == pytest.approx(1.6 / 3000 * FS, rel=1e-9)  # linear sweep: 1.07 rad/s
    assert f[5] == pytest.approx(0.0, abs=1e-6)
    assert f[6] == 0.1


def test_features_encode_radial_distance_as_dv_over_av():
    """DV/AV ~ G k(a) (Birdwell's dM/dtheta, Eq 2.38) for unsaturated open-loop contacts."""
    L = 0.1
    a = np.array([0.06, 0.07, 0.08, 0.09])
    contacts = [WhiskContact(math.radians(20.0), ai, L) for ai in a]
    recs, _ = simulate_whisk_cycle(contacts, OpenLoop(WhiskPattern(1.0)), seed=3)
    dets = detect_contacts(recs)
    F = contact_features(recs, dets, [L] * 4)
    ratio = F[:, 2] / F[:, 4]
    gk = SignalParams().gain_counts_per_nm * bending_stiffness(a, L)
    assert np.all(np.diff(ratio) < 0)
    np.testing.assert_allclose(ratio, gk, rtol=0.15)


def test_feature_bad_input():
    rec = _hinge_record()
    c = detect_contact(rec)
    with pytest.raises(InvalidInputError):
        contact_features([rec], [None], [0.1])
    with pytest.raises(InvalidInputError):
        contact_features([rec], [c], [0.1, 0.2])
    with pytest.raises(InvalidInputError):
        contact_features([rec], [c], [np.nan])
    with pytest.raises(InvalidInputError):
        detect_contact("not a record")
    with pytest.raises(InvalidInputError):
        DetectionParams(smoothing_span=0)


def test_plot_whisk_marks_onset_and_offset(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from whisker_io.plots.signals import plot_whisk

    rec = _hinge_record(noise=4.0)
    c = detect_contact(rec)
    fig = plot_whisk(rec, c)
    vlines = [ln.get_xdata()[0] for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) == 2]
    assert c.onset_time_s in vlines and c.offset_time_s in vlines
    fig.savefig(tmp_path / "whisk.png")
    assert (tmp_path / "whisk.png").stat().st_size > 0
    plt.close("all")


def test_slipping_contact_offset_at_the_slip():
    """Fig 4.5b: the whisker slips off mid-protraction; the offset is where the deflection vanishes."""
    contact = WhiskContact(math.radians(-20.0), 0.05, 0.1, slip_rad=math.radians(15.0))
    recs, truths = simulate_whisk_cycle([contact], OpenLoop(WhiskPattern(1.0)), seed=5)
    det = detect_contact(recs[0])
    slip_index = truths[0].peak_index + 1
    assert abs(det.onset_index - truths[0].onset_index) <= 10
    assert abs(det.offset_index - slip_index) <= 10


# ------------------------------------------------- issue 17: typed errors
@pytest.mark.parametrize("span", [0, -3, 2.5, "100", None, True, math.nan, 1e300])
def test_smoothing_span_must_be_a_positive_whole_number(span):
    # span 0 used to reach scipy's uniform_filter1d as a RuntimeError
    with pytest.raises(InvalidInputError, match="span"):
        moving_average(np.ones(50), span)


def test_moving_average_hand_computed_and_bad_signal():
    np.testing.assert_allclose(moving_average([0.0, 0.0, 3.0, 0.0, 0.0], 3), [0.0, 1.0, 1.0, 1.0, 0.0])
    for bad in ([], [1.0, math.nan], "abc"):
        with pytest.raises(InvalidInputError):
            moving_average(bad, 3)


@pytest.mark.parametrize("kwargs", [{"smoothing_span": 0}, {"smoothing_span": True}, {"min_width_samples": "2"},
                                    {"min_prominence_counts": None}, {"signs": 1}, {"signs": (2,)}])
def test_detection_params_bad_values_are_typed(kwargs):
    with pytest.raises(InvalidInputError):
        DetectionParams(**kwargs)


@pytest.mark.parametrize("span", [10**9, 2**31 - 1, 100_001])
def test_a_smoothing_span_beyond_the_signal_is_refused_up_front(span):
    """smoothing_span=10**9 was accepted and then ran out of memory (issue 25)."""
    from whisker_io.contact.detection import moving_average

    with pytest.raises(InvalidInputError, match="too large"):
        moving_average(np.zeros(1000), span)
    assert moving_average(np.arange(5.0), 100).shape == (5,)  # a span longer than a short signal stays allowed


_signal = st.lists(st.one_of(st.floats(-3000, 3000), st.sampled_from([0.0, -0.0, 5.0])), min_size=2, max_size=300)


@settings(max_examples=80, deadline=None)
@given(_signal, st.sampled_from([1.0, -1.0]))
def test_prominence_bound_is_the_cumulative_minima_formula(values, sign):
    from whisker_io.contact._detection_numba import prominence_bound

    y = np.array(values)
    z = sign * y
    expected = z - np.maximum(np.minimum.accumulate(z), np.minimum.accumulate(z[::-1])[::-1])
    assert np.array_equal(prominence_bound(y, sign), expected)


@settings(max_examples=80, deadline=None)
@given(_signal, st.sampled_from([1.0, -1.0]), st.data())
def test_contact_extent_is_the_numpy_scan(values, sign, data):
    """The one-scan indices equal the whole-signal numpy formulas (runs above a level around the
    top, the last non-rise before the rise and the first non-fall after the fall)."""
    from whisker_io.contact._detection_numba import contact_extent

    y = np.array(values)
    z = sign * y
    top = data.draw(st.integers(0, y.size - 1))
    tol, half = data.draw(st.floats(0, 50)), data.draw(st.floats(0, 3000))

    def run(level):
        low = np.flatnonzero(z <= level)
        before, after = low[low < top], low[low > top]
        return (int(before[-1]) + 1 if before.size else 0), (int(after[0]) - 1 if after.size else z.size - 1)

    peak, plateau_end = run(z[top] - tol)
    rise_mid, fall_mid = run(z[top] - half)
    d = np.diff(z)
    stops = np.flatnonzero(d[:rise_mid] <= 0.0)
    ends = np.flatnonzero(d[fall_mid:] >= 0.0)
    expected = (peak, plateau_end, rise_mid, fall_mid, int(stops[-1]) + 1 if stops.size else 0,
                fall_mid + int(ends[0]) if ends.size else z.size - 1)
    got = contact_extent(y, sign, top, float(z[top] - tol), float(z[top] - half))
    assert tuple(int(v) for v in got) == expected


def test_detect_contacts_equals_detect_contact_per_record():
    """The batch (range pre-test across modules, smoothing in one call) finds what the one-record
    path finds, field for field, on contacts, free whisking and a negative deflection."""
    contacts = [WhiskContact(0.1 * i - 0.4, 0.02 + 0.01 * i, 0.1) if i % 3 else None for i in range(9)]
    recs, _ = simulate_whisk_cycle(contacts, OpenLoop(WhiskPattern(1.0)), seed=11)
    flipped = WhiskRecord("N1", recs[1].angle_rad, recs[1].x_counts, -recs[1].y_counts)
    recs = list(recs) + [flipped]
    p = DetectionParams(min_prominence_counts=80.0, confirm_threshold_counts=80.0)
    batch = detect_contacts(recs, p)
    single = [detect_contact(r, p) for r in recs]
    assert sum(d is not None for d in single) >= 5 and single[-1] is not None and single[-1].sign == -1
    assert batch == single


@settings(max_examples=80, deadline=None)
@given(st.lists(st.sampled_from([0.0, 1.0, 2.0, 3.0, -1.0]) | st.floats(-100, 100), min_size=0, max_size=60),
       st.sampled_from([1.0, -1.0]), st.floats(-50, 50))
def test_bounded_maxima_are_find_peaks_peaks(values, sign, level):
    """The compiled scan returns scipy's find_peaks peaks (flat tops included) with bound >= level."""
    from scipy.signal import find_peaks

    from whisker_io.contact._detection_numba import bounded_maxima

    y = np.array(values, dtype=np.float64)
    bound = np.linspace(-50, 50, y.size)
    peaks, _ = find_peaks(sign * y)
    assert bounded_maxima(y, sign, bound, level).tolist() == peaks[bound[peaks] >= level].tolist()


def test_warm_up_kernels_compiles_every_detection_scan():
    from whisker_io.contact import _detection_numba as k
    from whisker_io.contact.detection import warm_up_kernels

    warm_up_kernels()
    for fn in (k.prominence_bound, k.bounded_maxima, k.contact_extent):
        assert fn.signatures, fn.__name__  # compiled for float64 signals before any whisk
