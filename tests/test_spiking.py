"""Spiking attractor populations: neuron model, connectivity, backends, path integration, demo."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cansim.axes import Axis
from cansim.errors import CansimError, ConfigError, InvalidInputError, ShapeError, ZeroActivityError
from cansim.params import AttractorParams
from cansim.population import Population
from cansim.spiking.neurons import MAX_REFRACTORY_STEPS
from cansim.spiking import (
    HD_RING_ATTRACTOR,
    NeuronParams,
    RecurrentKernel,
    SpikeCountDecoder,
    SpikingParams,
    SpikingPopulation,
    analytic_lif_rate_hz,
    calibrate_velocity_lead,
    spiking_from_rate,
)

HSET = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])
RING = (Axis.angle("heading", 360),)
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def wrap_deg(x):
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


def single_neuron(params: NeuronParams, dt_s: float) -> SpikingPopulation:
    p = SpikingParams(attractor=AttractorParams(exc_width=1, inh_width=1), neurons=params, recurrent_weight=0.0, global_weight=0.0)
    return SpikingPopulation((Axis.linear("x", 1, 1.0),), p, dt_s=dt_s, seed=0, backend="numpy")


# ------------------------------------------------------------------ neuron model
@pytest.mark.parametrize("current", [1.1, 1.5, 3.0, 8.0])
def test_single_lif_rate_equals_analytic_rate(current):
    nrn = NeuronParams(tau_mem_s=0.02, tau_syn_s=0.002, refractory_s=0.002, bias_current=0.0, noise_sigma=0.0)
    # hand-derived: time to charge from reset 0 to threshold 1 towards v_inf = current
    expected = 1.0 / (0.002 + 0.02 * math.log(current / (current - 1.0)))
    assert analytic_lif_rate_hz(nrn, current) == pytest.approx(expected, rel=1e-12)
    dt = 1e-4
    pop = single_neuron(nrn, dt)
    pop.run(2000, current=current)  # 0.2 s: the synaptic current reaches its steady state
    times = [k * dt for k in range(30000) if len(pop.step(current=current))]
    assert len(times) > 10
    measured = (len(times) - 1) / (times[-1] - times[0])
    assert measured == pytest.approx(expected, rel=0.02)


def test_lif_below_rheobase_is_silent_and_analytic_rate_zero():
    nrn = NeuronParams(bias_current=0.0, noise_sigma=0.0)
    pop = single_neuron(nrn, 1e-3)
    assert sum(len(s) for s in pop.run(3000, current=0.99)) == 0
    assert analytic_lif_rate_hz(nrn, 0.99) == 0.0
    assert pop.v.max() < 1.0


def test_poisson_rate_matches_dead_time_formula():
    # p = gain * I * dt per free step, one dead step after each spike: rate = p / (1 + p) / dt
    nrn = NeuronParams(model="poisson", poisson_gain_hz=100.0, bias_current=0.0, refractory_s=0.001)
    p = SpikingParams(attractor=AttractorParams(exc_width=1, inh_width=1), neurons=nrn, recurrent_weight=0.0, global_weight=0.0)
    pop = SpikingPopulation((Axis.linear("x", 2000, 1.0),), p, dt_s=0.001, seed=4, backend="numba")
    pop.run(50, current=0.5)
    spikes = sum(len(s) for s in pop.run(1000, current=0.5))
    pr = 100.0 * 0.5 * 0.001 * (1.0 - math.exp(-50 * 0.001 / 0.005))  # I after 50 steps of tau_syn 5 ms ~ 0.5
    expected = 0.05 / 1.05 / 0.001
    assert pr == pytest.approx(0.05, rel=1e-4)
    rate = spikes / (2000 * 1.0)
    assert rate == pytest.approx(expected, rel=0.03)  # ~95k spikes: 3 % is > 9 standard errors


# ---------------------------------------------------------------- connectivity
def _gauss(width, sigma):
    d = np.arange(width) - width // 2
    k = np.exp(-(d**2) / (2.0 * sigma**2))
    return k / k.sum()


def test_ring_weights_equal_hand_built_difference_of_kernels():
    n, w_rec, w_glob = 40, 7.0, 0.3
    ap = AttractorParams(exc_width=7, exc_sigma=1.5, inh_width=5, inh_sigma=2.0)
    ke, ki = _gauss(7, 1.5), _gauss(5, 2.0)
    ref = np.zeros((n, n))
    for j in range(n):  # scatter a spike of cell j: excitation, then inhibition of the excited profile
        e = np.zeros(n)
        for a, wa in enumerate(ke):
            e[(j + a - 3) % n] += wa
        inh = np.zeros(n)
        for i in range(n):
            for b, wb in enumerate(ki):
                inh[(i + b - 2) % n] += e[i] * wb
        ref[:, j] = w_rec * (e - inh) - w_glob
    kern = RecurrentKernel.from_params(ap, (n,), w_rec)
    np.testing.assert_allclose(kern.dense_matrix(w_glob), ref, atol=1e-14)
    assert abs(kern.weights.sum()) < 1e-12  # normalised kernels: excitation and inhibition balance


def test_kernel_wider_than_grid_folds_onto_it():
    n = 4
    kern = RecurrentKernel.from_params(AttractorParams(), (n,), 1.0)  # 7 + 5 - 1 = 11 taps on 4 cells
    assert kern.weights.shape == (n,)
    wide = RecurrentKernel.from_params(AttractorParams(), (400,), 1.0).weights
    folded = np.zeros(n)
    for k, w in enumerate(wide):
        folded[(k - 5) % n] += w
    np.testing.assert_allclose(kern.dense_matrix()[:, 0], folded, atol=1e-15)


def test_shifted_kernel_is_roll_and_linear_split():
    kern = RecurrentKernel.from_params(HD_RING_ATTRACTOR, (90,), 1.0)
    m0 = kern.dense_matrix()
    np.testing.assert_allclose(kern.shifted([2.0]).dense_matrix(), np.roll(m0, 2, axis=0), atol=1e-15)
    np.testing.assert_allclose(
        kern.shifted([-1.25]).dense_matrix(), 0.25 * np.roll(m0, -2, axis=0) + 0.75 * np.roll(m0, -1, axis=0), atol=1e-15
    )


def test_3d_connectivity_is_product_structure():
    shape = (6, 5, 7)
    ap = AttractorParams(exc_width=3, exc_sigma=1.0, inh_width=3, inh_sigma=1.5)
    kern = RecurrentKernel.from_params(ap, shape, 1.0)
    ke, ki = _gauss(3, 1.0), _gauss(3, 1.5)
    e1 = [np.zeros(n) for n in shape]
    c1 = [np.zeros(n) for n in shape]
    for ax, n in enumerate(shape):
        for a, wa in enumerate(ke):
            e1[ax][(a - 1) % n] += wa
        full = np.convolve(ke, ki)
        for a, wa in enumerate(full):
            c1[ax][(a - 2) % n] += wa
    ref = np.einsum("i,j,k->ijk", *e1) - np.einsum("i,j,k->ijk", *c1)
    np.testing.assert_allclose(kern.dense_matrix()[:, 0].reshape(shape), ref, atol=1e-15)


# --------------------------------------------------------------------- backends
@st.composite
def spiking_cases(draw):
    ndim = draw(st.integers(1, 3))
    shape = tuple(draw(st.integers(1, 9 if ndim > 1 else 60)) for _ in range(ndim))
    model = draw(st.sampled_from(["lif", "poisson"]))
    ap = AttractorParams(
        exc_width=draw(st.sampled_from([1, 3, 5, 7])), exc_sigma=draw(st.floats(0.5, 3.0)),
        inh_width=draw(st.sampled_from([1, 3, 5])), inh_sigma=draw(st.floats(0.5, 3.0)),
    )
    nrn = NeuronParams(
        model=model, bias_current=draw(st.floats(0.5, 1.2)), noise_sigma=draw(st.floats(0.0, 0.4)),
        tau_syn_s=draw(st.floats(0.001, 0.02)), refractory_s=draw(st.sampled_from([0.001, 0.002, 0.0035])),
        poisson_gain_hz=draw(st.floats(10.0, 400.0)),
    )
    p = SpikingParams(attractor=ap, neurons=nrn, recurrent_weight=draw(st.floats(0.0, 150.0)),
                      global_weight=draw(st.floats(0.0, 2.0)), velocity_lead_s=draw(st.floats(-0.02, 0.02)))
    return shape, p, draw(st.integers(0, 2**31 - 1))


@settings(max_examples=20, **HSET)
@given(case=spiking_cases())
def test_numba_gives_the_same_spikes_as_numpy(case):
    shape, params, seed = case
    axes = tuple(Axis.angle(f"a{i}", n) for i, n in enumerate(shape))
    pops = [SpikingPopulation(axes, params, seed=seed, backend=b) for b in ("numpy", "numba")]
    drive = np.random.default_rng(seed)
    for k in range(150):
        vel = drive.normal(0.0, 30.0, len(shape)) if k % 4 else None
        cur = drive.normal(0.3, 0.5, shape) if k % 7 == 0 else None
        a, b = (p.step(vel, cur) for p in pops)
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(pops[0].v, pops[1].v)
    np.testing.assert_array_equal(pops[0].synaptic_current, pops[1].synaptic_current)


def test_same_seed_same_spikes_other_seed_other_spikes():
    p = SpikingParams(attractor=HD_RING_ATTRACTOR)
    runs = [SpikingPopulation(RING, p, seed=s).run(400) for s in (1, 1, 2)]
    assert all(np.array_equal(x, y) for x, y in zip(runs[0], runs[1]))
    assert not all(np.array_equal(x, y) for x, y in zip(runs[0], runs[2]))


# ------------------------------------------------------------ attractor behaviour
def test_bump_forms_from_noise_and_stays_within_5_deg_for_10_s():
    pop = SpikingPopulation(RING, SpikingParams(attractor=HD_RING_ATTRACTOR), seed=11)
    dec = SpikeCountDecoder(RING, window_steps=100, half_width=10)
    assert pop.v.max() == 0.0  # starts at rest: the packet must come from the noise
    for _ in range(1000):
        dec.add(pop.step())
    counts = dec.counts
    centre = dec.decode()[0]
    near = np.abs(wrap_deg(np.arange(360) - centre)) <= 15
    assert counts[near].sum() > 0.9 * counts.sum() > 0  # one localised packet
    headings = []
    for k in range(10000):
        dec.add(pop.step())
        if k % 100 == 99:
            headings.append(dec.decode()[0])
    assert np.abs(wrap_deg(np.array(headings) - centre)).max() < 5.0


@pytest.fixture(scope="module")
def calibrated_ring():
    ring = Population.head_direction(360, params=HD_RING_ATTRACTOR, backend="numba")
    spk = spiking_from_rate(ring, seed=2, calibrate_speeds_cells_per_s=[3, 6, 10, 20, 40, 70, 110, 160, 240])
    return ring, spk


@pytest.mark.slow
def test_path_integration_60_s_tracks_truth_and_rate_ring(calibrated_ring):
    ring, spk = calibrated_ring
    dt = spk.dt_s
    t = np.arange(60000) * dt
    omega = np.radians(70.0 * np.sin(2 * np.pi * t / 9.0) - 45.0 * np.cos(2 * np.pi * t / 3.7) + 15.0 * np.sin(2 * np.pi * t / 31.0))
    true = np.degrees(np.cumsum(omega) * dt)
    ring.reset_cell([0])
    spk.reset()
    spk.kick([0.0])
    spk.run(300)
    dec = SpikeCountDecoder(RING, window_steps=40, half_width=10)
    err_true, err_rate = [], []
    for k in range(len(t)):
        dec.add(spk.step(omega[k]))
        if k % 20 == 19:
            rate_deg = ring.step(velocity=float(omega[k - 19 : k + 1].mean()), dt=20 * dt)[0]
            spk_deg = dec.decode()[0]
            err_true.append(wrap_deg(spk_deg - true[k]))
            err_rate.append(wrap_deg(spk_deg - rate_deg))
    assert np.ptp(true) > 300  # the trajectory really turns
    assert np.sqrt(np.mean(np.square(err_true))) < 15.0
    assert np.sqrt(np.mean(np.square(err_rate))) < 10.0


def test_calibration_makes_packet_speed_match_command(calibrated_ring):
    from cansim.spiking import measure_packet_speed

    _, spk = calibrated_ring
    for speed in (25.0, 90.0):
        got = measure_packet_speed(spk, [-math.radians(speed)], duration_s=3.0)
        assert got == pytest.approx(-speed, rel=0.08)


# ------------------------------------------------------------------ correspondence
def test_spiking_from_rate_uses_the_rate_population_axes_and_kernels():
    rate = Population.openratslam(8, 6)
    spk = spiking_from_rate(rate, backend="numpy")
    assert spk.axes == rate.axes and spk.shape == (8, 8, 6)
    assert spk.params.attractor == rate.params
    ref = RecurrentKernel.from_params(rate.params, rate.shape, spk.params.recurrent_weight)
    np.testing.assert_array_equal(spk.kernel.weights, ref.weights)
    assert spk.params.neurons.bias_current == pytest.approx(0.8 - 2e-5 * 100.0)
    with pytest.raises(ConfigError):
        spiking_from_rate("not a population")


def test_poisson_population_forms_a_packet():
    p = SpikingParams(attractor=HD_RING_ATTRACTOR, neurons=NeuronParams(model="poisson", poisson_gain_hz=60.0, bias_current=0.2))
    pop = SpikingPopulation(RING, p, seed=3)
    dec = SpikeCountDecoder(RING, window_steps=500, half_width=10)
    for _ in range(1500):
        dec.add(pop.step())
    c = dec.counts
    near = np.abs(wrap_deg(np.arange(360) - dec.decode()[0])) <= 20
    assert c[near].sum() > 0.8 * c.sum() > 0


# ------------------------------------------------------------------ decoding
def test_decoder_population_vector_and_sliding_window():
    dec = SpikeCountDecoder(RING, window_steps=2, half_width=5)
    dec.add(np.array([10, 10, 10]))
    dec.add(np.array([12]))
    # circular mean of 3 spikes at 10 deg and 1 at 12 deg (hand: atan2 of the summed unit vectors)
    ang = math.degrees(math.atan2(3 * math.sin(math.radians(10)) + math.sin(math.radians(12)),
                                  3 * math.cos(math.radians(10)) + math.cos(math.radians(12))))
    assert dec.decode()[0] == pytest.approx(ang, abs=1e-9)
    assert dec.decode_physical()[0] == pytest.approx(math.radians(ang), abs=1e-9)
    dec.add(np.array([], dtype=np.int64))
    dec.add(np.array([], dtype=np.int64))
    assert dec.counts.sum() == 0
    with pytest.raises(ZeroActivityError):
        dec.decode()


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("field", ["tau_mem_s", "tau_syn_s", "refractory_s", "resistance", "poisson_gain_hz"])
def test_negative_time_constants_and_gains_are_config_errors(field):
    with pytest.raises(ConfigError, match=field):
        NeuronParams(**{field: -0.01})


def test_dt_larger_than_refractory_period_is_config_error():
    with pytest.raises(ConfigError, match="refractory"):
        SpikingPopulation(RING, SpikingParams(neurons=NeuronParams(refractory_s=0.001)), dt_s=0.002)


@settings(max_examples=40, **HSET)
@given(
    field=st.sampled_from(["tau_mem_s", "tau_syn_s", "refractory_s", "resistance", "poisson_gain_hz", "v_rest",
                           "v_reset", "v_threshold", "bias_current", "noise_sigma"]),
    value=st.one_of(st.just(math.nan), st.just(math.inf), st.just(-math.inf), st.floats(-1e6, 0.0)),
)
@example(field="tau_mem_s", value=10**400)  # was an OverflowError
@example(field="v_rest", value="0.5")  # a string was parsed as a number
def test_neuron_params_reject_bad_values_with_typed_errors(field, value):
    positive = {"tau_mem_s", "tau_syn_s", "refractory_s", "resistance", "poisson_gain_hz"}
    if not isinstance(value, float) or not math.isfinite(value):
        ok = False
    elif field in positive:
        ok = value > 0
    elif field == "v_threshold":
        ok = value > 0.0  # above the default reset 0
    elif field == "noise_sigma":
        ok = value >= 0
    else:  # v_rest, bias_current, v_reset (below the default threshold 1): any finite value
        ok = True
    if ok:
        assert getattr(NeuronParams(**{field: value}), field) == value
    else:
        with pytest.raises(ConfigError):
            NeuronParams(**{field: value})


@settings(max_examples=40, **HSET)
@given(
    dt=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1.0, 0.0)),
    w=st.floats(allow_nan=True, allow_infinity=True),
    seed=st.one_of(st.integers(-5, -1), st.just(1.5), st.just(True)),
)
@example(dt=1e-320, w=0.0, seed=-1)  # refractory_s / dt_s overflowed: OverflowError
def test_population_constructor_rejects_bad_arguments(dt, w, seed):
    refractory_s = NeuronParams().refractory_s
    if not (math.isfinite(dt) and 0 < dt <= 0.002 and refractory_s / dt <= MAX_REFRACTORY_STEPS):
        with pytest.raises(ConfigError):
            SpikingPopulation(RING, SpikingParams(), dt_s=dt)
    if not (math.isfinite(w) and w >= 0):
        with pytest.raises(ConfigError):
            SpikingParams(recurrent_weight=w)
        with pytest.raises(ConfigError):
            SpikingParams(global_weight=w)
    with pytest.raises(ConfigError):
        SpikingPopulation(RING, SpikingParams(), seed=seed)


@pytest.fixture(scope="module")
def small_pop():
    return SpikingPopulation((Axis.angle("a", 12), Axis.linear("b", 5, 0.1)), SpikingParams(), seed=1, backend="numpy")


@settings(max_examples=40, **HSET, )
@given(
    bad=st.sampled_from([math.nan, math.inf, -math.inf]),
    where=st.integers(0, 59),
    kind=st.sampled_from(["current", "velocity", "shape_current", "shape_velocity"]),
)
def test_step_rejects_non_finite_or_misshaped_input_and_keeps_state(small_pop, bad, where, kind):
    small_pop.run(3, current=1.5)
    before = (small_pop.v, small_pop.synaptic_current, small_pop.last_spikes, small_pop.time_s)
    cur = np.ones(small_pop.shape)
    vel = np.zeros(2)
    if kind == "current":
        cur.flat[where] = bad
        err, kw = InvalidInputError, {"current": cur}
    elif kind == "velocity":
        vel[where % 2] = bad
        err, kw = InvalidInputError, {"velocity": vel}
    elif kind == "shape_current":
        err, kw = ShapeError, {"current": np.ones(where + 1) if where + 1 != 60 else np.ones((2, 2))}
    else:
        err, kw = ShapeError, {"velocity": np.zeros(3 + where % 3)}
    with pytest.raises(err):
        small_pop.step(**kw)
    after = (small_pop.v, small_pop.synaptic_current, small_pop.last_spikes, small_pop.time_s)
    for x, y in zip(before, after):
        np.testing.assert_array_equal(x, y)


@settings(max_examples=30, **HSET)
@given(
    spikes=st.lists(st.integers(-1000, 1000), min_size=1, max_size=8),
    window=st.integers(-3, 0),
)
def test_decoder_rejects_bad_spikes_and_windows(spikes, window):
    with pytest.raises(InvalidInputError):
        SpikeCountDecoder(RING, window_steps=window)
    dec = SpikeCountDecoder(RING, window_steps=3)
    arr = np.array(spikes)
    if arr.min() < 0 or arr.max() >= 360:
        with pytest.raises(InvalidInputError):
            dec.add(arr)
        assert dec.counts.sum() == 0
    else:
        dec.add(arr)
        assert dec.counts.sum() == len(spikes)
    with pytest.raises(InvalidInputError):
        dec.add(np.array([1.5]))


@settings(max_examples=20, **HSET)
@given(speeds=st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(0.0), st.just(-3.0)), min_size=0, max_size=4))
def test_calibration_rejects_bad_speeds(speeds):
    arr = np.array(speeds, dtype=float)
    if arr.size and np.isfinite(arr).all() and (arr > 0).all() and len(set(speeds)) == len(speeds):
        return
    with pytest.raises(InvalidInputError):
        calibrate_velocity_lead(RING, SpikingParams(), speeds)


@settings(max_examples=20, **HSET)
@given(centre=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=3),
       current=st.floats(allow_nan=True, allow_infinity=True))
def test_kick_and_analytic_rate_reject_bad_values(centre, current):
    pop = SpikingPopulation(RING, SpikingParams(), backend="numpy")
    if len(centre) != 1:
        with pytest.raises(ShapeError):
            pop.kick(centre, 1.0)
    elif not (math.isfinite(centre[0]) and math.isfinite(current)):
        with pytest.raises(InvalidInputError):
            pop.kick(centre, current)
        with pytest.raises(InvalidInputError):
            analytic_lif_rate_hz(NeuronParams(), current if not math.isfinite(current) else math.nan)
    assert pop.synaptic_current.sum() == pytest.approx(0.0) or len(centre) == 1


def test_bad_lead_table_and_model_are_config_errors():
    for table in (((1.0, 0.01), (0.5, 0.01)), ((math.nan, 0.01),), ((1.0, 2.0, 3.0),), "junk"):
        with pytest.raises(ConfigError):
            SpikingParams(lead_table=table)
    with pytest.raises(ConfigError):
        NeuronParams(model="hodgkin-huxley")
    with pytest.raises(ConfigError):
        NeuronParams(v_reset=1.0, v_threshold=1.0)
    with pytest.raises(ConfigError):
        SpikingPopulation(RING, SpikingParams(), backend="opencl")
    assert issubclass(ConfigError, CansimError)
    with pytest.raises(InvalidInputError):
        SpikingPopulation(RING).run(-1)


# ------------------------------------------------------------------ demo
@pytest.mark.slow  # the whole demo, ~3 s (fast loop <= 4 min)
def test_spiking_ring_demo_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("spiking_ring", EXAMPLES / "spiking_ring.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--quick", "--no-progress", "--out", str(tmp_path)]) == 0
    metrics = json.loads((tmp_path / "spiking_ring_metrics.json").read_text())
    assert metrics["duration_s"] == 10.0 and metrics["n_neurons"] == 360
    assert metrics["rms_vs_true_deg"] < 15.0 and metrics["rms_vs_rate_deg"] < 10.0
    assert (tmp_path / "spiking_ring.png").stat().st_size > 20_000
    import nir

    from cansim.spiking import from_nir

    back = from_nir(nir.read(tmp_path / "spiking_ring.nir"))
    assert back.size == 360 and back.params.lead_table


@settings(max_examples=20, **HSET)
@given(
    shift=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=3),
    weight=st.floats(allow_nan=True, allow_infinity=True),
)
def test_kernel_and_correspondence_reject_bad_values(shift, weight):
    kern = RecurrentKernel.from_params(AttractorParams(), (20,), 1.0)
    if len(shift) != 1:
        with pytest.raises(ShapeError):
            kern.shifted(shift)
    elif not math.isfinite(shift[0]):
        with pytest.raises(InvalidInputError):
            kern.shifted(shift)
    else:
        assert kern.shifted(shift).weights.sum() == pytest.approx(kern.weights.sum(), abs=1e-12)
    if not (math.isfinite(weight) and weight >= 0):
        with pytest.raises(ConfigError):
            RecurrentKernel.from_params(AttractorParams(), (20,), weight)
        with pytest.raises(ConfigError):
            spiking_from_rate(Population.head_direction(20), recurrent_weight=weight, backend="numpy")


@settings(max_examples=10, **HSET)
@given(axis=st.integers(-3, 5), duration=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(0.05)),
       name=st.sampled_from(["duration_s", "settle_s", "bin_s"]))
@example(axis=0, duration=1e308, name="bin_s")  # bin_s / dt_s overflowed: OverflowError
@example(axis=0, duration=1e308, name="settle_s")
@example(axis=0, duration="1", name="duration_s")  # was a TypeError
def test_measure_packet_speed_rejects_bad_arguments(axis, duration, name):
    from cansim.spiking import measure_packet_speed
    from cansim.spiking.calibration import MAX_MEASURE_STEPS

    pop = SpikingPopulation(RING, SpikingParams(attractor=HD_RING_ATTRACTOR))
    if axis != 0:
        with pytest.raises(InvalidInputError):
            measure_packet_speed(pop, [0.1], axis)
    # the duration must cover three default bins of 0.1 s; no time may span more than MAX_MEASURE_STEPS steps
    low = 0.3 if name == "duration_s" else 0.0
    if not (isinstance(duration, float) and math.isfinite(duration) and low <= duration <= MAX_MEASURE_STEPS * pop.dt_s):
        with pytest.raises(InvalidInputError):
            measure_packet_speed(pop, [0.1], 0, **{name: duration})


@pytest.mark.parametrize("kwargs", [{"sigma_cells": 1e-300}, {"sigma_cells": 0.0}, {"sigma_cells": 1e9},
                                    {"current": 1 + 2j}, {"center": ["a"]}])
def test_kick_refuses_what_would_make_nan_and_leaves_the_state(kwargs):
    """kick(sigma_cells=1e-300) gave a NaN synaptic current (issue 25)."""
    from cansim.errors import CansimError

    sp = spiking_from_rate(Population.head_direction(36))
    before = sp._i.copy()
    with pytest.raises(CansimError):
        sp.kick(**{"center": [10.0], **kwargs})
    np.testing.assert_array_equal(sp._i, before)
    sp.kick([10.0], sigma_cells=0.05)  # the narrowest accepted bump is finite
    assert np.isfinite(sp._i).all() and sp._i.max() > 0


@pytest.mark.parametrize("velocity", [1 + 2j, "fast", [np.nan], [1.0, 2.0]])
def test_step_refuses_complex_text_nan_or_misshaped_velocity(velocity):
    """step(velocity=1+2j) reached float() (issue 25)."""
    from cansim.errors import CansimError

    sp = spiking_from_rate(Population.head_direction(36))
    with pytest.raises(CansimError):
        sp.step(velocity=velocity)
