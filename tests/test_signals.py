"""Tests of the tapered-cantilever signal model (Eq 2.33-2.38) and the whisking controllers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from whisker_io.array.control import RCP, OpenLoop, RetractAtMax, WhiskPattern, contact_threshold_from_noise
from whisker_io.errors import CansimError, InvalidInputError
from whisker_io.sim.signals import (
    SignalParams,
    WhiskContact,
    bending_stiffness,
    add_sensor_noise,
    deflection_counts,
    free_whisking_threshold_counts,
    radial_distance_from_stiffness,
    simulate_rod_contact,
    simulate_whisk_cycle,
)

QUIET = SignalParams(noise_std_counts=0.0, angle_noise_std_rad=0.0, quantize=False)


def _stiffness_by_quadrature(a: float, L: float, p: SignalParams) -> float:
    """dM/dtheta = a^2 / C(a), C(a) = int_0^a (a-x)^2 / (E I(x)) dx (Eq 2.33-2.34 integrated twice)."""

    def integrand(x: float) -> float:
        r = p.base_radius_m + (p.tip_radius_m - p.base_radius_m) * x / L
        return (a - x) ** 2 / (p.youngs_modulus_pa * math.pi * r**4 / 4.0)

    compliance, _ = quad(integrand, 0.0, a)
    return a * a / compliance


@pytest.mark.parametrize("tip", [0.3e-3, 0.0, 1.0e-3])
@pytest.mark.parametrize("a_frac", [0.2, 0.5, 0.9])
def test_stiffness_matches_beam_integral(tip, a_frac):
    p = SignalParams(tip_radius_m=tip)
    L = 0.1
    a = a_frac * L
    assert float(bending_stiffness(a, L, p)) == pytest.approx(_stiffness_by_quadrature(a, L, p), rel=1e-6)


def test_stiffness_closed_forms_eq_2_38_and_uniform_rod():
    E, rb, L, d = 3.0e9, 1.0e-3, 0.1, 0.04
    I = math.pi * rb**4 / 4
    cone = SignalParams(youngs_modulus_pa=E, base_radius_m=rb, tip_radius_m=0.0)
    rod = SignalParams(youngs_modulus_pa=E, base_radius_m=rb, tip_radius_m=rb)
    # Eq 2.38: d = 3EI L / (3EI + dM/dtheta L)  <=>  dM/dtheta = 3EI (L - d) / (d L)
    assert float(bending_stiffness(d, L, cone)) == pytest.approx(3 * E * I * (L - d) / (d * L), rel=1e-12)
    assert float(radial_distance_from_stiffness(3 * E * I * (L - d) / (d * L), L, cone)) == pytest.approx(d)
    assert float(bending_stiffness(d, L, rod)) == pytest.approx(3 * E * I / d, rel=1e-12)  # "3EI/a"
    a = np.linspace(0.01, 0.1, 10)
    np.testing.assert_allclose(radial_distance_from_stiffness(bending_stiffness(a, L), L), a, rtol=1e-12)


def test_deflection_grows_with_rotation_past_contact_and_saturates():
    theta_c = math.radians(-10)
    contact = WhiskContact(theta_c, 0.06, 0.1)
    angles = np.linspace(math.radians(-50), math.radians(50), 1001)[None, :]
    x, y = deflection_counts(angles, [contact], QUIET)
    gk = QUIET.gain_counts_per_nm * float(bending_stiffness(0.06, 0.1, QUIET))
    expected = np.minimum(gk * np.maximum(angles[0] - theta_c, 0.0), QUIET.adc_max_counts)
    np.testing.assert_allclose(y[0], expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(x[0], 0.0, atol=1e-9)  # squarely facing normal: no x-deflection
    assert y[0].max() == QUIET.adc_max_counts


def test_contacts_nearer_the_base_are_stiffer():
    angles = np.full((4, 1), math.radians(5.0))
    contacts = [WhiskContact(0.0, a, 0.1) for a in (0.03, 0.05, 0.07, 0.09)]
    _, y = deflection_counts(angles, contacts, QUIET)
    assert np.all(np.diff(y[:, 0]) < 0)


@pytest.mark.parametrize("tilt_deg", [-60.0, -20.0, 15.0, 45.0])
def test_normal_splits_deflection_with_eq_6_14_slope(tilt_deg):
    theta_c = math.radians(12.0)
    tilt = math.radians(tilt_deg)
    # normal in the base frame: rotate the facing normal Rz(theta_c) x about the shaft toward z
    n = np.array([math.cos(theta_c) * math.cos(tilt), math.sin(theta_c) * math.cos(tilt), math.sin(tilt)])
    contact = WhiskContact(theta_c, 0.05, 0.1, normal=n)
    angles = np.array([[theta_c + math.radians(3.0)]])
    x, y = deflection_counts(angles, [contact], QUIET)
    magnitude = QUIET.gain_counts_per_nm * float(bending_stiffness(0.05, 0.1, QUIET)) * math.radians(3.0)
    assert y[0, 0] == pytest.approx(magnitude * math.cos(tilt) ** 2)
    assert x[0, 0] == pytest.approx(magnitude * math.cos(tilt) * math.sin(tilt))
    assert y[0, 0] / x[0, 0] == pytest.approx(1.0 / math.tan(tilt))
    assert contact.slope == pytest.approx(1.0 / math.tan(tilt))


def test_normal_not_opposing_protraction_gives_no_deflection():
    contact = WhiskContact(0.0, 0.05, 0.1, normal=[-1.0, 0.0, 0.2])
    x, y = deflection_counts(np.array([[0.3]]), [contact], QUIET)
    assert x[0, 0] == 0.0 and y[0, 0] == 0.0


def test_free_whisking_is_noise_only_and_seeded():
    p = SignalParams()
    recs, truths = simulate_whisk_cycle([None] * 3, OpenLoop(WhiskPattern(1.0)), p, seed=42)
    assert truths == [None, None, None]
    y = np.concatenate([r.y_counts for r in recs])
    assert abs(y.mean()) < 0.2 and y.std() == pytest.approx(p.noise_std_counts, rel=0.05)
    assert np.all(np.abs(y) < 8 * p.noise_std_counts)
    assert np.all(y == np.rint(y))  # integer ADC counts
    again, _ = simulate_whisk_cycle([None] * 3, OpenLoop(WhiskPattern(1.0)), p, seed=42)
    other, _ = simulate_whisk_cycle([None] * 3, OpenLoop(WhiskPattern(1.0)), p, seed=43)
    assert np.array_equal(recs[1].y_counts, again[1].y_counts)
    assert not np.array_equal(recs[1].y_counts, other[1].y_counts)


def test_open_loop_pattern_is_the_full_range_cosine():
    pat = WhiskPattern(frequency_hz=0.5)
    th = OpenLoop(pat).command(2)
    assert th.shape == (2, 4000)
    assert th[0, 0] == pytest.approx(math.radians(-50))
    assert th[0, 2000] == pytest.approx(math.radians(50))
    assert th[0, 1000] == pytest.approx(0.0, abs=1e-12)


def test_truth_onset_is_first_sample_past_contact_angle():
    recs, truths = simulate_whisk_cycle([WhiskContact(math.radians(20.0), 0.05, 0.1)], OpenLoop(), QUIET, seed=0)
    t = truths[0]
    th = WhiskPattern().angles()
    assert th[t.onset_index] > math.radians(20.0) >= th[t.onset_index - 1]
    assert recs[0].y_counts[t.onset_index - 1] == 0.0 and recs[0].y_counts[t.onset_index] > 0.0


def test_retract_at_max_stops_protraction_at_saturation():
    pat = WhiskPattern(1.0)
    contacts = [WhiskContact(math.radians(-20.0), a, 0.1) for a in (0.03, 0.05)] + [None]
    recs, truths = simulate_whisk_cycle(contacts, RetractAtMax(pat), SignalParams(), seed=1)
    max_angles = [r.angle_rad.max() for r in recs]
    # nearer the base saturates after a smaller rotation past contact -> retracts earlier
    assert max_angles[0] < max_angles[1] < math.radians(50.0)
    assert max_angles[2] == pytest.approx(math.radians(50.0), abs=math.radians(0.5))
    for r in recs[:2]:
        assert r.y_counts.max() <= 2047
        assert r.angle_rad[-1] == pytest.approx(math.radians(-50.0), abs=math.radians(0.5))
    # the rotation past contact at the top equals the rotation that saturates the sensor
    gk = SignalParams().gain_counts_per_nm * float(bending_stiffness(0.03, 0.1))
    assert max_angles[0] - math.radians(-20.0) == pytest.approx(2000.0 / gk, abs=math.radians(1.0))


def test_rcp_reduces_amplitude_after_contact_keeps_start_angle():
    pat = WhiskPattern(1.0)
    ctrl = RCP(pat)
    contact = [WhiskContact(math.radians(0.0), 0.05, 0.1), None]
    simulate_whisk_cycle(contact, ctrl, seed=0)
    amp = ctrl.amplitudes_rad.copy()
    assert amp[0] < pat.amplitude_rad and amp[1] == pytest.approx(pat.amplitude_rad)
    recs, _ = simulate_whisk_cycle([None, None], ctrl, seed=1)
    assert recs[0].angle_rad.max() == pytest.approx(pat.retraction_rad + amp[0], abs=math.radians(0.3))
    assert recs[0].angle_rad[0] == pytest.approx(pat.retraction_rad, abs=math.radians(0.3))
    assert ctrl.amplitudes_rad[0] == pytest.approx(pat.amplitude_rad)  # free cycle restores the amplitude


def test_contact_threshold_is_twenty_sigma_of_free_whisking():
    recs, _ = simulate_whisk_cycle([None] * 4, seed=5)
    thr = contact_threshold_from_noise(np.concatenate([r.y_counts for r in recs]))
    assert thr == pytest.approx(20 * SignalParams().noise_std_counts, rel=0.05)


@pytest.mark.parametrize("noise", [2.0, 4.0, 10.0])
def test_free_whisking_threshold_follows_the_sensor_noise(noise):
    # free whisking deflects nothing: the y signal is the sensor noise alone, so 20 sigma
    p = SignalParams(noise_std_counts=noise, quantize=False)
    thr = free_whisking_threshold_counts(WhiskPattern(), p, [f"W{i}" for i in range(18)], np.random.default_rng(1))
    assert thr == pytest.approx(20 * noise, rel=0.05)


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(["modules", "pattern", "params"]),
       st.one_of(st.none(), st.just([]), st.just(""), st.integers(), st.text(max_size=3), st.floats(allow_nan=True)))
def test_free_whisking_threshold_bad_input_is_typed(which, bad):
    args = {"pattern": WhiskPattern(), "params": SignalParams(), "modules": ["W0", "W1"]}
    args[which] = bad
    with pytest.raises(CansimError):
        free_whisking_threshold_counts(args["pattern"], args["params"], args["modules"], np.random.default_rng(0))


def test_rod_mode_peak_and_period_depend_on_speed_and_distance():
    p = SignalParams.evans2013()
    kw = dict(params=p, seed=0)
    slow, t_slow = simulate_rod_contact(0.1, 0.185, 0.036, **kw)
    fast, t_fast = simulate_rod_contact(0.1, 0.185, 0.216, **kw)
    assert np.ptp(slow.angle_rad) < math.radians(0.5)  # the whisker is still
    assert t_fast.peak_y_counts > t_slow.peak_y_counts  # braking overshoot grows with speed
    assert (t_fast.peak_index - t_fast.onset_index) < (t_slow.peak_index - t_slow.onset_index)
    near, t_near = simulate_rod_contact(0.08, 0.185, 0.1, **kw)
    far, t_far = simulate_rod_contact(0.17, 0.185, 0.1, **kw)
    assert (t_near.peak_index - t_near.onset_index) < (t_far.peak_index - t_far.onset_index)
    assert t_slow.onset_index == round(0.25 * 2000) + 1


@pytest.mark.parametrize(
    "call",
    [
        lambda: WhiskContact(0.0, 0.12, 0.1),
        lambda: WhiskContact(0.0, -0.01, 0.1),
        lambda: WhiskContact(0.0, 0.05, 0.1, normal=[np.nan, 0, 0]),
        lambda: WhiskPattern(frequency_hz=0.0),
        lambda: WhiskPattern(frequency_hz=12.0),
        lambda: SignalParams(youngs_modulus_pa=-1.0),
        lambda: SignalParams(tip_radius_m=2e-3),
        lambda: simulate_whisk_cycle([]),
        lambda: simulate_whisk_cycle([None], OpenLoop(WhiskPattern(sample_rate_hz=1000.0))),
        lambda: simulate_rod_contact(0.05, 0.1, -0.1),
    ],
)
def test_bad_input_raises_typed_error(call):
    with pytest.raises(InvalidInputError):
        call()


def test_slip_drops_deflection_for_the_rest_of_the_cycle():
    slip = math.radians(8.0)
    contact = WhiskContact(math.radians(-10.0), 0.07, 0.1, slip_rad=slip)
    recs, truths = simulate_whisk_cycle([contact], OpenLoop(WhiskPattern(1.0)), QUIET, seed=0)
    y, th = recs[0].y_counts, recs[0].angle_rad
    gk = QUIET.gain_counts_per_nm * float(bending_stiffness(0.07, 0.1, QUIET))
    k_slip = int(np.argmax(th - math.radians(-10.0) >= slip))
    assert y.max() == pytest.approx(gk * (th[k_slip - 1] - math.radians(-10.0)))
    assert np.all(y[k_slip:] == 0.0) and truths[0].peak_index == k_slip - 1
    with pytest.raises(InvalidInputError):
        WhiskContact(0.0, 0.05, 0.1, slip_rad=0.0)


# ------------------------------------------------- issue 17: typed errors
@pytest.mark.parametrize("kwargs", [{"angle_rad": "0.3"}, {"radial_distance_m": None}, {"whisker_length_m": "x"},
                                    {"normal": [1.0, 0.0]}, {"normal": [[1, 0], [0]]}, {"slip_rad": "inf"},
                                    {"normal": [0.0, 0.0, 0.0]}, {"angle_rad": math.inf}])
def test_whisk_contact_bad_values_are_typed(kwargs):
    args = dict(angle_rad=0.3, radial_distance_m=0.05, whisker_length_m=0.1) | kwargs
    with pytest.raises(InvalidInputError):
        WhiskContact(**args)


@pytest.mark.parametrize("kwargs", [{"youngs_modulus_pa": "3e9"}, {"noise_std_counts": None}, {"base_radius_m": 0.0}])
def test_signal_params_bad_values_are_typed(kwargs):
    with pytest.raises(InvalidInputError):
        SignalParams(**kwargs)


@pytest.mark.parametrize("kwargs", [{"frequency_hz": "1"}, {"frequency_hz": 0.0}, {"retraction_rad": None},
                                    {"sample_rate_hz": math.nan}])
def test_whisk_pattern_bad_values_are_typed(kwargs):
    with pytest.raises(InvalidInputError):
        WhiskPattern(**kwargs)


def test_controllers_reject_a_non_pattern_and_bad_thresholds():
    with pytest.raises(InvalidInputError, match="WhiskPattern"):
        RCP(pattern=None)
    with pytest.raises(InvalidInputError, match="WhiskPattern"):
        RetractAtMax(pattern="fast")
    with pytest.raises(InvalidInputError):
        RetractAtMax(threshold_counts="2000")


def test_rod_contact_refuses_a_push_that_never_ends():
    # 1e-320 m/s: the push would take ~1e300 s (used to overflow int())
    with pytest.raises(InvalidInputError, match="speed_m_s"):
        simulate_rod_contact(0.05, 0.1, speed_m_s=1e-320)
    with pytest.raises(InvalidInputError):
        simulate_rod_contact(0.05, 0.1, speed_m_s="fast")
    # a huge lead or tail: int(round(lead_s * fs)) of inf was an OverflowError before the length check
    for kw in ({"lead_s": 1e308}, {"tail_s": 1e308}, {"lead_s": 1e6}):
        with pytest.raises(InvalidInputError, match="lead_s"):
            simulate_rod_contact(0.05, 0.1, 0.1, **kw)


def _numpy_cycle(contacts, angles, params, seed):
    """The cycle as the numpy functions compose it, with the noise drawn as three separate (n, T) arrays."""
    rng = np.random.default_rng(seed)
    noise = tuple(rng.standard_normal(angles.shape) for _ in range(3))
    x0, y0 = deflection_counts(angles, contacts, params)
    return add_sensor_noise(x0, y0, angles, noise, params), y0


_contact = st.one_of(
    st.none(),
    st.builds(
        lambda ang, frac, L, nrm, slip: WhiskContact(math.radians(ang), frac * L, L, normal=nrm, slip_rad=slip),
        st.floats(-60, 60), st.floats(0.02, 1.0), st.sampled_from([0.06, 0.1, 0.16]),
        st.tuples(*(st.floats(-1, 1),) * 3).filter(lambda v: 0.1 < math.hypot(*v)),
        st.one_of(st.just(math.inf), st.floats(0.01, 1.0))),
)


@settings(max_examples=40, deadline=None)
@given(st.lists(_contact, min_size=1, max_size=6), st.integers(0, 2**31), st.booleans(), st.floats(0.0, 8.0),
       st.sampled_from([500.0, 2047.0]))
def test_cycle_is_the_numpy_composition_bit_for_bit(contacts, seed, quantize, noise_std, adc_max):
    """The compiled one-pass synthesis and the one noise draw of (3, n, T) give the same bits as
    deflection_counts + add_sensor_noise with three (n, T) draws from the same seed; the truths
    are the argmax formulas on the noise-free y."""
    p = SignalParams(noise_std_counts=noise_std, quantize=quantize, adc_max_counts=adc_max)
    ctrl = OpenLoop(WhiskPattern(2.0, sample_rate_hz=p.sample_rate_hz))
    recs, truths = simulate_whisk_cycle(contacts, ctrl, p, seed=seed)
    angles = ctrl.command(len(contacts))
    (x, y, th), y0 = _numpy_cycle(contacts, angles, p, seed)
    for i, r in enumerate(recs):
        assert r.x_counts.tobytes() == x[i].tobytes()
        assert r.y_counts.tobytes() == y[i].tobytes()
        assert r.angle_rad.tobytes() == th[i].tobytes()
    for i, (c, t) in enumerate(zip(contacts, truths)):
        past = angles[i] > c.angle_rad if c is not None else None
        if c is None or not past.any() or not np.any(y0[i]):
            assert t is None
            continue
        assert t.onset_index == int(np.argmax(past))
        assert t.peak_index == int(np.argmax(np.abs(y0[i])))
        assert t.peak_y_counts == y0[i, t.peak_index]


def test_retract_at_max_cycle_is_the_numpy_composition():
    """A controller that re-commands the cycle (retract at the sensor limit) gets the same noise again."""
    contacts = [WhiskContact(0.0, 0.02, 0.1), None, WhiskContact(0.3, 0.09, 0.16)]
    ctrl = RetractAtMax(WhiskPattern(1.0))
    recs, _ = simulate_whisk_cycle(contacts, ctrl, None, seed=5)
    angles = OpenLoop(WhiskPattern(1.0)).command(3)
    (_, y_first, _), _ = _numpy_cycle(contacts, angles, SignalParams(), 5)
    angles2 = RetractAtMax(WhiskPattern(1.0)).respond(angles, y_first)
    assert not np.array_equal(angles2, angles)  # the controller did react
    (x, y, th), _ = _numpy_cycle(contacts, angles2, SignalParams(), 5)
    assert all(np.array_equal(r.y_counts, y[i]) and np.array_equal(r.angle_rad, th[i]) for i, r in enumerate(recs))


@pytest.mark.parametrize("kwargs,says", [
    (dict(angle_rad=30.0, radial_distance_m=0.05, whisker_length_m=0.1), r"30 deg = 0.5236 rad"),
    (dict(angle_rad=-4.0, radial_distance_m=0.05, whisker_length_m=0.1), r"within \+-pi rad"),
    (dict(angle_rad=0.3, radial_distance_m=50.0, whisker_length_m=90.0), r"90 mm = 0.09 m"),
])
def test_a_contact_in_degrees_or_millimetres_is_refused_naming_the_unit(kwargs, says):
    """Degrees and millimetres gave no contact and empty features, silently (a user's pass, session 47)."""
    from whisker_io.sim.signals import WhiskContact

    with pytest.raises(InvalidInputError, match=says):
        WhiskContact(**kwargs)
    WhiskContact(angle_rad=math.pi, radial_distance_m=1.0, whisker_length_m=1.0)  # the bounds themselves are taken
