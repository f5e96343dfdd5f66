"""The NIR graphs cansim writes, imported unmodified into snnTorch, Norse and Rockpool (issue 23 items 1-2).

Each consumer's own NIR reader imports the graph; the test steps the module it returns
and compares what it does with cansim's own simulation of the same graph
(:class:`cansim.spiking.NIRGraphSimulator`). The protocol is the issue's: a Gaussian input
current (sigma 3 cells, 2 threshold units) at 90 deg for 100 ms, then none; from 200 ms
after the kick on, the population vector of the spikes lies within 10 deg of 90 and at
least 70 % of the spikes within 30 cells of it; the bump is held within 5 deg of cansim's
for 1 s; its width and mean rate agree within 15 %. The population vector and the
widths are computed here, by hand, from the spike counts.

These tests need the optional extra ``nir-consumers`` (torch, snnTorch, nirtorch, Norse,
Rockpool); without it they are skipped with the reason, unless
``CANSIM_REQUIRE_NIR_CONSUMERS=1`` (set by ``.ci/run``), which turns the skip into a failure.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

nir = pytest.importorskip("nir")

from cansim.axes import Axis  # noqa: E402
from cansim.errors import ConfigError, InvalidInputError, ShapeError  # noqa: E402
from cansim.spiking import (  # noqa: E402
    HD_RING_ATTRACTOR,
    NeuronParams,
    NIRGraphSimulator,
    RotationRingParams,
    SpikingParams,
    SpikingPopulation,
    TurningCalibration,
    calibrate_turning,
    from_nir,
    ring_input,
    rotation_ring_graph,
    to_nir,
)
from cansim.spiking.nir_consumers import ConsumerRunner  # noqa: E402
from consumers import need as _need  # noqa: E402

DT = 1e-4
HSET = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])


FAST = [pytest.param("snntorch"), pytest.param("norse"), pytest.param("rockpool", marks=pytest.mark.slow)]
ALL = ["snntorch", "norse", "rockpool"]


# ------------------------------------------------------------------ helpers computed by hand
def _gauss_current(n: int, centre_cell: float, sigma_cells: float = 3.0, peak: float = 2.0) -> np.ndarray:
    d = (np.arange(n) - centre_cell + n / 2.0) % n - n / 2.0
    return peak * np.exp(-d * d / (2.0 * sigma_cells * sigma_cells))


def _pop_vector_deg(counts: np.ndarray) -> float:
    n = counts.size
    ang = 2.0 * np.pi * np.arange(n) / n
    return float(np.degrees(np.arctan2((counts * np.sin(ang)).sum(), (counts * np.cos(ang)).sum())) % 360.0)


def _circ_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def _fraction_within(counts: np.ndarray, centre_deg: float, cells: int) -> float:
    n = counts.size
    d = np.abs((np.arange(n) - centre_deg * n / 360.0 + n / 2.0) % n - n / 2.0)
    return float(counts[d <= cells].sum() / counts.sum())


def _width_cells(counts: np.ndarray) -> float:
    """Circular standard deviation of the spike counts around their mean (cells)."""
    n = counts.size
    ang = 2.0 * np.pi * np.arange(n) / n
    rbar = math.hypot((counts * np.cos(ang)).sum(), (counts * np.sin(ang)).sum()) / counts.sum()
    return math.sqrt(-2.0 * math.log(rbar)) * n / (2.0 * math.pi)


def _kick_run(step, n: int, make_input, hold_s: float = 1.0) -> dict:
    """Kick at 90 deg for 100 ms, then no input for ``hold_s``; spike counts by 100 ms window."""
    n_steps = int(round((0.1 + hold_s) / DT))
    per_window = int(round(0.1 / DT))
    kick = _gauss_current(n, 90.0 * n / 360.0)
    windows, acc = [], np.zeros(n)
    for k in range(n_steps):
        acc += step(make_input(kick if k < per_window else 0.0))
        if (k + 1) % per_window == 0:
            windows.append(acc)
            acc = np.zeros(n)
    return {"windows": np.array(windows)}  # window w covers [0.1 w, 0.1 (w + 1)) s


def _protocol_numbers(res: dict) -> dict:
    w = res["windows"]
    late = w[3:6].sum(axis=0)  # 200-500 ms after the kick ended (0.3-0.6 s)
    held = w[1:]  # every 100 ms window of the 1 s hold
    return {
        "pv_deg": _pop_vector_deg(late),
        "within_30": _fraction_within(late, _pop_vector_deg(late), 30),
        "held_deg": [_pop_vector_deg(x) if x.sum() else math.nan for x in held],
        "width_cells": _width_cells(w[1:].sum(axis=0)),
        "mean_rate_hz": float(w[1:].sum() / (w.shape[1] * 0.1 * len(held))),
    }


def _ring_population(n: int = 360) -> SpikingPopulation:
    """A noise-free ring whose bump fires at tens of Hz (see cansim.spiking.rotation_ring.RING_NEURONS)."""
    nrn = NeuronParams(noise_sigma=0.0, refractory_s=DT, bias_current=0.95)
    p = SpikingParams(attractor=HD_RING_ATTRACTOR, neurons=nrn, recurrent_weight=15.0, global_weight=0.1)
    return SpikingPopulation((Axis.angle("heading", n),), p, dt_s=DT, seed=0, backend="numba")


def _assert_like(got: dict, ref: dict, label: str) -> None:
    assert _circ_diff_deg(got["pv_deg"], 90.0) <= 10.0, (label, got)
    assert got["within_30"] >= 0.70, (label, got)
    for a, b in zip(got["held_deg"], ref["held_deg"]):
        assert _circ_diff_deg(a, b) <= 5.0 and _circ_diff_deg(a, 90.0) <= 10.0, (label, got["held_deg"], ref["held_deg"])
    assert abs(got["width_cells"] / ref["width_cells"] - 1.0) <= 0.15, (label, got["width_cells"], ref["width_cells"])
    assert abs(got["mean_rate_hz"] / ref["mean_rate_hz"] - 1.0) <= 0.15, (label, got["mean_rate_hz"], ref["mean_rate_hz"])


_REF: dict = {}


def _stationary_reference() -> tuple:
    if "stationary" not in _REF:
        g = to_nir(_ring_population())
        _REF["stationary"] = (g, _protocol_numbers(_kick_run(NIRGraphSimulator(g).step, 360, lambda u: np.broadcast_to(u, (360,)))))
    return _REF["stationary"]


# ------------------------------------------------------------------ cansim against itself
def test_cansims_simulation_of_the_graph_is_the_population_it_was_exported_from():
    pop = _ring_population()
    g, ref = _stationary_reference()
    back = from_nir(g)
    assert back.params == pop.params

    def step(u):
        z = np.zeros(360)
        z[back.step(current=u)] = 1.0
        return z

    got = _protocol_numbers(_kick_run(step, 360, lambda u: np.broadcast_to(u, (360,)) * 1.0))
    _assert_like(got, ref, "SpikingPopulation vs NIRGraphSimulator")


# ------------------------------------------------------------------ item 1: the stationary ring
@pytest.mark.slow  # 1.1 s of spiking in a torch module, ~4 s per toolchain (fast loop <= 4 min)
@pytest.mark.parametrize("consumer", FAST)
def test_consumer_holds_the_kicked_bump_like_cansim(consumer):
    _need(consumer)
    g, ref = _stationary_reference()
    runner = ConsumerRunner(g, consumer, dt_s=DT)
    got = _protocol_numbers(_kick_run(runner.step, 360, lambda u: np.broadcast_to(u, (360,)) * 1.0))
    _assert_like(got, ref, consumer)


def test_snntorchs_reader_takes_the_graph_as_written():
    """snnTorch's reader rewrites a neuron <-> weight two-node loop (and then feeds the input through the weight);
    the graphs cansim writes have none, so the reader leaves them as they are."""
    _need("snntorch")
    import contextlib
    import io

    import snntorch.import_nir

    for g in (to_nir(_ring_population(24)), rotation_ring_graph(RotationRingParams(n_cells=24, shift_cells=3))):
        edges, nodes = sorted(g.edges), sorted(g.nodes)
        with contextlib.redirect_stdout(io.StringIO()):
            snntorch.import_nir.import_from_nir(g)  # the graph itself, no copy
        assert sorted(g.edges) == edges and sorted(g.nodes) == nodes


# ------------------------------------------------------------------ item 2: path integration in the graph
PI_CELLS = 120  # the tests' smaller ring (the example writes 360 cells): a step costs the consumers ~1 ms
PI_SETTLE_S = 0.5  # after the kick, the bump's rate falls to its steady state over ~0.5 s; turning starts then
PI_SECONDS = 0.1 + PI_SETTLE_S + 0.8  # kick, settle, 0.8 s of turning (1.2 rad)
PI_START_S = 0.1 + PI_SETTLE_S


def _turn_run(step, n: int, omega_of_t, duration_s: float, start_s: float = PI_START_S) -> tuple[np.ndarray, np.ndarray]:
    """Kick at 90 deg for 100 ms, no input until ``start_s``, then turn with omega(t); heading every 20 ms from a
    50 ms spike window (unwrapped, from ``start_s`` on)."""
    kick = _gauss_current(n, 90.0 * n / 360.0)
    n_steps = int(round(duration_s / DT))
    decay = math.exp(-DT / 0.05)
    trace = np.zeros(n)
    times, heads = [], []
    for k in range(n_steps):
        t = k * DT
        om = omega_of_t(t) if t >= start_s else 0.0
        trace = trace * decay + step(ring_input(kick if t < 0.1 else 0.0, om, n))
        if (k + 1) % 200 == 0 and t >= start_s:
            times.append(t + DT)
            heads.append(_pop_vector_deg(trace) if trace.sum() else math.nan)
    return np.array(times), np.degrees(np.unwrap(np.radians(np.array(heads))))


def _turning_signal(t: float) -> float:
    """Not used to choose the ring's parameters: a sinusoid between 0 and 3 rad/s."""
    return 1.5 + 1.5 * math.sin(2.0 * math.pi * (t - PI_START_S) / 0.4)


def _integral_deg(times: np.ndarray) -> np.ndarray:
    """The integral of the turning signal from PI_START_S, in closed form (deg, plus an offset of 90)."""
    t = times - PI_START_S
    return 90.0 + np.degrees(1.5 * t + 1.5 * 0.4 / (2.0 * math.pi) * (1.0 - np.cos(2.0 * math.pi * t / 0.4)))


def _pi_reference() -> tuple:
    """The graph, the calibrated turning command and cansim's run of it (times, unwrapped headings)."""
    if "pi" not in _REF:
        params = RotationRingParams(n_cells=PI_CELLS)
        g = rotation_ring_graph(params)
        cal = calibrate_turning(params)
        command = lambda t: cal.command(_turning_signal(t))  # noqa: E731
        _REF["pi"] = (g, command, _turn_run(NIRGraphSimulator(g).step, PI_CELLS, command, PI_SECONDS))
    return _REF["pi"]


@pytest.mark.slow  # seconds of simulated turning (fast loop <= 4 min)
def test_cansims_rotation_ring_turns_with_the_angular_velocity():
    n = PI_CELLS
    g = rotation_ring_graph(RotationRingParams(n_cells=n))
    sim = NIRGraphSimulator(g)
    turned = {}
    for om in (+1.0, -1.0, 0.0):
        sim.reset()
        times, heads = _turn_run(sim.step, n, lambda t, om=om: om, PI_START_S + 0.5)
        turned[om] = heads[-1] - heads[0]
    # the bump moves with the sign of omega, the two directions alike, and stays without it
    assert turned[+1.0] > 10.0 and turned[-1.0] < -10.0, turned
    assert abs(turned[+1.0] + turned[-1.0]) <= 0.1 * turned[+1.0], turned
    assert abs(turned[0.0]) <= 1.0, turned
    _, _, (times, heads) = _pi_reference()
    turned_truth = _integral_deg(times)[-1] - _integral_deg(times)[0]
    assert 0.5 * turned_truth < heads[-1] - heads[0] < 1.5 * turned_truth, (heads[-1] - heads[0], turned_truth)


def _turned_rad_s(sim, n: int, omega_rad_s: float) -> float:
    """The bump's turning rate (rad/s): least-squares slope of the heading over 0.5 s of constant input."""
    times, heads = _turn_run(sim.step, n, lambda t: omega_rad_s, PI_START_S + 0.5)
    return float(np.radians(np.polyfit(times, heads, 1)[0]))


@pytest.mark.slow  # seconds of simulated turning (fast loop <= 4 min)
def test_the_calibrated_ring_turns_at_the_wanted_rate_up_to_5_rad_s():
    """Rates between the calibration's grid points (2.5, 4.5 rad/s) and both signs: the bump turns at the wanted
    rate within 10 %, with its own kick and settling (the calibration measures from 0 deg, this from 90 deg)."""
    params = RotationRingParams(n_cells=PI_CELLS)
    cal = calibrate_turning(params)
    assert cal.max_rad_s >= 5.0, cal
    sim = NIRGraphSimulator(rotation_ring_graph(params))
    for want in (2.5, -4.5):
        sim.reset()
        got = _turned_rad_s(sim, PI_CELLS, cal.command(want))
        assert abs(got / want - 1.0) <= 0.10, (want, got, cal)


def test_turning_calibration_inverts_its_table_by_hand():
    cal = TurningCalibration((0.0, 1.0, 2.0, 3.0), (0.0, 2.0, 3.0, 2.5))  # rises to 3 rad/s at 2, then falls
    assert cal.max_rad_s == 3.0
    assert cal.command(1.0) == pytest.approx(0.5)
    assert cal.command(2.5) == pytest.approx(1.5)
    assert cal.command(-2.0) == pytest.approx(-1.0)
    assert cal.command(0.0) == 0.0
    assert cal.command(10.0) == pytest.approx(2.0) and cal.command(-10.0) == pytest.approx(-2.0)  # saturated
    np.testing.assert_allclose(cal.command(np.array([1.0, -2.5])), [0.5, -1.5])
    with pytest.raises(InvalidInputError):
        cal.command(math.nan)


@settings(max_examples=30, **HSET)
@given(
    omegas=st.lists(st.one_of(st.floats(-5, 20), st.sampled_from([math.nan, math.inf])), min_size=0, max_size=4),
    speeds=st.lists(st.one_of(st.floats(-5, 20), st.sampled_from([math.nan, -math.inf])), min_size=0, max_size=4),
)
def test_bad_turning_tables_get_config_errors(omegas, speeds):
    om, sp = np.array([0.0, *omegas]), np.array([0.0, *speeds])
    good = (
        om.size == sp.size >= 2 and np.isfinite(om).all() and np.isfinite(sp).all()
        and np.all(np.diff(om) > 0) and sp[1] > 0
    )
    if good:
        assert TurningCalibration(tuple(om), tuple(sp)).max_rad_s > 0
        return
    with pytest.raises(ConfigError):
        TurningCalibration(tuple(om), tuple(sp))


@pytest.mark.parametrize("kwargs", [
    {"omegas_rad_s": ()}, {"omegas_rad_s": (1.0, 0.5)}, {"omegas_rad_s": (-1.0,)}, {"omegas_rad_s": (math.nan,)},
    {"omegas_rad_s": "ab"}, {"settle_s": 0.0}, {"measure_s": math.inf}, {"measure_s": True}, {"params": "ring"},
])
def test_calibrate_turning_rejects_bad_arguments(kwargs):
    kwargs = {"params": RotationRingParams(n_cells=24, shift_cells=3), **kwargs}
    with pytest.raises(ConfigError):
        calibrate_turning(**kwargs)


TURNING = [
    pytest.param("snntorch"),
    pytest.param("norse"),
    pytest.param("rockpool", marks=[pytest.mark.slow, pytest.mark.xfail(strict=True, reason=(
        "measured (calibrated sinusoid, 120 cells): Rockpool turns the bump 53.5 deg where cansim turns it 70.4 "
        "(24 % less; the integral is 66.8) and its RMS error is 13.6 deg against cansim's 2.9. Rockpool's LIFTorch "
        "resets by subtracting the threshold and ignores the graph's v_reset; cansim's own simulation of the graph "
        "with a subtractive reset fires the ring 2.9 x as much at rest and turns at 1.37 instead of 2.14 rad/s for "
        "a 2 rad/s command, the same direction as Rockpool (the attractor's gain amplifies the reset's surplus). "
        "No graph can carry the other reset rule to it"))]),
]


@pytest.mark.slow  # seconds of simulated turning (fast loop <= 4 min)
@pytest.mark.parametrize("consumer", TURNING)
def test_consumer_turns_the_bump_like_cansim(consumer):
    _need(consumer)
    g, command, (times, ref_heads) = _pi_reference()
    runner = ConsumerRunner(g, consumer, dt_s=DT)
    _, heads = _turn_run(runner.step, PI_CELLS, command, PI_SECONDS)
    truth = _integral_deg(times)
    err_ref = float(np.sqrt(np.mean((ref_heads - truth) ** 2)))
    err = float(np.sqrt(np.mean((heads - truth) ** 2)))
    turned, turned_ref = heads[-1] - heads[0], ref_heads[-1] - ref_heads[0]
    # the bump turns as far as in cansim's simulation, within 10 %
    assert abs(turned / turned_ref - 1.0) <= 0.10, (consumer, turned, turned_ref, truth[-1] - truth[0])
    # and the decoded heading follows the integral with the same error, within 10 % or one cell (3 deg on 120
    # cells, where the errors are a few degrees)
    assert abs(err - err_ref) <= max(0.10 * err_ref, 360.0 / PI_CELLS), (consumer, err, err_ref)


# ------------------------------------------------------------------ the example's graphs
@pytest.mark.slow
@pytest.mark.parametrize("consumer", ALL)
def test_the_examples_graphs_pass_the_kick_protocol_in_each_consumer(consumer, tmp_path):
    _need(consumer)
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "spiking_ring.py"
    spec = importlib.util.spec_from_file_location("spiking_ring_example", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--quick", "--duration-s", "1", "--no-progress", "--out", str(tmp_path)]) == 0
    for name, make_input in (
        ("spiking_ring.nir", lambda u: np.broadcast_to(u, (360,)) * 1.0),
        ("spiking_ring_pi.nir", lambda u: ring_input(u, 0.0, 360)),
    ):
        g = nir.read(tmp_path / name)
        got = _protocol_numbers(_kick_run(ConsumerRunner(g, consumer).step, 360, make_input, hold_s=0.5))
        assert _circ_diff_deg(got["pv_deg"], 90.0) <= 10.0 and got["within_30"] >= 0.70, (name, consumer, got)


# ------------------------------------------------------------------ typed errors
def _one_cell_graph(threshold: float):
    cell = nir.CubaLIF(tau_syn=np.array([5e-3]), tau_mem=np.array([2e-2]), r=np.array([2.0]), v_leak=np.array([0.1]),
                       v_threshold=np.array([threshold]), v_reset=np.array([0.0]), w_in=np.array([3.0]))
    return nir.NIRGraph(nodes={"input": nir.Input(input_type={"input": np.array([1])}), "cells": cell,
                               "output": nir.Output(output_type={"output": np.array([1])})},
                        edges=[("input", "cells"), ("cells", "output")])


@pytest.mark.parametrize("integration", ["exact", "euler"])
def test_the_simulators_two_integrations_by_hand(integration):
    """One cell, input 1 from step 0: the first spike falls where the documented update puts it."""
    dt = 1e-4
    a_s, a_m = (math.exp(-dt / 5e-3), math.exp(-dt / 2e-2)) if integration == "exact" else (1 - dt / 5e-3, 1 - dt / 2e-2)
    i, v, volts = 0.0, 0.1, []
    for _ in range(400):  # i <- a_s i + (1 - a_s) w_in x;  v <- a_m v + (1 - a_m)(v_leak + r i)
        i = a_s * i + (1 - a_s) * 3.0
        v = a_m * v + (1 - a_m) * (0.1 + 2.0 * i)
        volts.append(v)
    threshold = 0.5 * (volts[299] + volts[300])  # crossed between step 299 and step 300
    sim = NIRGraphSimulator(_one_cell_graph(threshold), dt_s=dt, integration=integration)
    out = sim.run(np.ones((400, 1)))[:, 0]
    assert np.flatnonzero(out)[0] == 300
    other = NIRGraphSimulator(_one_cell_graph(threshold), dt_s=dt,
                              integration="euler" if integration == "exact" else "exact").run(np.ones((400, 1)))[:, 0]
    assert np.flatnonzero(other)[0] != 300  # the two integrations differ enough to move the first spike
    with pytest.raises(ConfigError):
        NIRGraphSimulator(_one_cell_graph(1.0), integration="rk4")


@pytest.mark.slow  # ~1 min per toolchain
@pytest.mark.parametrize("consumer", ["snntorch", "norse"])
def test_cansims_euler_integration_is_the_consumers_arithmetic(consumer):
    """With the consumers' forward Euler, cansim's simulation turns the ring as snnTorch and Norse do (their
    float32 against cansim's float64 aside): the same heading at most readings of the 0.8 s protocol (measured: 85 %), the
    others a spike apart (measured: at most 0.12 deg, a 25th of a cell), the same end. With cansim's default
    (exponential) integration the runs part by degrees (70.4 against 67.3 deg turned)."""
    _need(consumer)
    g, command, _ = _pi_reference()
    _, ref = _turn_run(NIRGraphSimulator(g, integration="euler").step, PI_CELLS, command, PI_SECONDS)
    _, heads = _turn_run(ConsumerRunner(g, consumer, dt_s=DT).step, PI_CELLS, command, PI_SECONDS)
    gap = np.abs(heads - ref)
    assert np.mean(gap < 1e-6) >= 0.75 and gap.max() < 0.5, (consumer, gap.max(), np.mean(gap < 1e-6))
    assert abs(heads[-1] - ref[-1]) < 0.1, (consumer, heads[-1], ref[-1])


@pytest.mark.parametrize("consumer", ["snntorch", "norse"])
def test_a_float64_consumer_computes_in_float64(consumer):
    """``precision="float64"``: every parameter and buffer of the imported module is float64, and the first steps of the
    kicked ring run (snnTorch's float32 spikes cast at its linear layers) with the same spikes as in float32 over 0.15 s."""
    _need(consumer)
    import torch

    g = rotation_ring_graph(RotationRingParams(n_cells=24, shift_cells=3))
    wide, narrow = ConsumerRunner(g, consumer, precision="float64"), ConsumerRunner(g, consumer)
    assert wide.precision == "float64" and narrow.precision == "float32"
    tensors = [*wide._module.parameters(), *wide._module.buffers()]
    assert tensors and all(t.dtype == torch.float64 for t in tensors if t.is_floating_point())
    assert any(t.dtype == torch.float32 for t in narrow._module.parameters())
    kick = _gauss_current(24, 6.0)
    spikes = 0.0
    for k in range(1500):  # 0.1 s kick, 0.05 s after
        x = ring_input(kick if k < 1000 else 0.0, 0.0, 24)
        a, b = wide.step(x), narrow.step(x)
        assert a.dtype == np.float64 and np.array_equal(a, b), k
        spikes += a.sum()
    assert spikes > 0


def test_a_float64_snntorch_module_holds_the_graphs_numbers():
    """snnTorch's reader, run with ``precision="float64"``, keeps the graph's float64 values: every linear layer's
    weights and bias equal the graph's, and the neurons' decays are ``1 - dt/tau`` computed here in float64 (the
    reader's nirtorch call would round them all to float32: ``alpha`` 0.98000002, whose ``1 - alpha`` is 1e-6 off)."""
    _need("snntorch")
    import torch

    g = rotation_ring_graph(RotationRingParams(n_cells=24, shift_cells=3))
    mod = ConsumerRunner(g, "snntorch", precision="float64")._module
    layers = {k: m for k, m in mod.named_modules() if isinstance(m, torch.nn.Linear)}
    assert set(layers) == {"input_map", "excitation", "inhibition", "readout"}
    for name, layer in layers.items():
        assert np.array_equal(layer.weight.detach().numpy(), g.nodes[name].weight), name
        if layer.bias is not None:
            assert np.array_equal(layer.bias.detach().numpy(), g.nodes[name].bias), name
    cells = g.nodes["cells"]
    assert mod.cells.alpha.item() == 1.0 - 1e-4 / float(cells.tau_syn[0])  # 0.98 in float64
    assert mod.cells.beta.item() == 1.0 - 1e-4 / float(cells.tau_mem[0])  # 0.995
    assert torch.get_default_dtype() == torch.float32  # the reader's float64 setting did not leak out


def test_a_float64_norse_module_holds_the_graphs_numbers():
    """Norse's reader, run with ``precision="float64"``, keeps the graph's float64 weights (its ``_to_tensor`` calls
    ``.float()``: ``1e-4`` would become 9.99999975e-5) and its neurons' inverse time constants are ``1/tau`` in float64;
    the reader's own tensor function is back in place afterwards."""
    _need("norse")
    import torch
    from norse.torch.utils import import_nir

    reader = import_nir._to_tensor
    g = rotation_ring_graph(RotationRingParams(n_cells=24, shift_cells=3))
    mod = ConsumerRunner(g, "norse", precision="float64")._module
    layers = {k: m for k, m in mod.named_modules() if isinstance(m, torch.nn.Linear)}
    assert set(layers) == {"input_map", "excitation", "inhibition", "readout"}
    for name, layer in layers.items():
        assert np.array_equal(layer.weight.detach().numpy(), g.nodes[name].weight), name
        if layer.bias is not None:
            assert np.array_equal(layer.bias.detach().numpy(), g.nodes[name].bias), name
    assert any(not np.array_equal(g.nodes[n].weight, g.nodes[n].weight.astype(np.float32)) for n in layers)  # can fail
    cells = g.nodes["cells"]
    assert np.array_equal(mod.cells.synapse.p.tau_mem_inv.numpy(), 1.0 / np.asarray(cells.tau_syn, dtype=np.float64))
    assert np.array_equal(mod.cells.lif.p.tau_mem_inv.numpy(), 1.0 / np.asarray(cells.tau_mem, dtype=np.float64))
    assert import_nir._to_tensor is reader


@pytest.mark.slow  # ~1 min
def test_a_float64_snntorch_runs_cansims_euler_arithmetic():
    """On the 1.4 s turning protocol, snnTorch in float64 and cansim's Euler simulation of the same graph fire the
    same cells at every step, and their membrane potentials end within 1e-9 (with the float32 constants of snnTorch's
    reader as it calls nirtorch: the same spikes here, but potentials 2.4e-6 apart, and the spikes part 1.67 s into
    Sargolini's turning)."""
    _need("snntorch")
    g, command, _ = _pi_reference()
    sim = NIRGraphSimulator(g, integration="euler")
    runner = ConsumerRunner(g, "snntorch", precision="float64")
    parted = []

    def both(x):  # the ring cells' spikes of this step (cansim's Output reads them one step later)
        sim.step(x)
        a, b = sim.spikes("cells")[:PI_CELLS], runner.step(x)
        if not np.array_equal(a, b):
            parted.append(len(parted))
        return b

    _turn_run(both, PI_CELLS, command, PI_SECONDS)
    assert not parted, len(parted)
    gap = np.abs(runner._module.cells.mem.detach().numpy()[0] - sim._v["cells"])
    assert gap.max() < 1e-9, gap.max()


@settings(max_examples=40, **HSET)
@given(precision=st.one_of(st.text(max_size=8), st.integers(), st.floats(), st.none(), st.just(["float64"]))
       .filter(lambda p: p not in ("float32", "float64")))
def test_a_bad_precision_is_a_config_error_before_any_import(precision):
    with pytest.raises(ConfigError, match="precision must be one of"):
        ConsumerRunner(to_nir(_ring_population(12)), "norse", precision=precision)


def test_runner_and_simulator_reject_bad_input():
    g = to_nir(_ring_population(24))
    sim = NIRGraphSimulator(g)
    with pytest.raises(ShapeError):
        sim.step(np.zeros(5))
    with pytest.raises(InvalidInputError):
        sim.step(np.full(24, np.nan))
    with pytest.raises(ShapeError):
        sim.run(np.zeros((3, 7)))
    with pytest.raises(ConfigError):
        ConsumerRunner(g, "lava")
    for precision in ("float16", "double", None, 64):
        with pytest.raises(ConfigError, match="precision"):
            ConsumerRunner(g, "norse", precision=precision)
    with pytest.raises(ConfigError, match="float32 only"):
        ConsumerRunner(g, "rockpool", precision="float64")
    with pytest.raises(ConfigError):
        sim.spikes("nope")
    with pytest.raises(ShapeError):
        ring_input(np.zeros(3), 0.0, 24)
    with pytest.raises(InvalidInputError):
        ring_input(0.0, math.inf, 24)


@settings(max_examples=40, **HSET)
@given(
    edit=st.sampled_from(["node_type", "edge_to_nowhere", "linear_loop", "size", "nan_weight", "tau", "reset", "no_output",
                          "not_a_graph", "dt", "refractory"]),
    value=st.sampled_from([math.nan, math.inf, -1.0, 0.0, "x", None]),
)
def test_malformed_graphs_get_config_errors(edit, value):
    g = to_nir(_ring_population(12))
    kwargs = {}
    if edit == "node_type":
        g.nodes["excitation"] = nir.Scale(scale=np.ones(12))
    elif edit == "edge_to_nowhere":
        g.edges.append(("cells", "missing"))
    elif edit == "linear_loop":
        g.edges.append(("inhibition", "excitation"))
    elif edit == "size":
        g.nodes["excitation"] = nir.Linear(weight=np.ones((12, 5)))
    elif edit == "nan_weight":
        w = g.nodes["inhibition"].weight.copy()
        w[0, 0] = value if isinstance(value, float) and not math.isfinite(value) else math.nan
        g.nodes["inhibition"] = nir.Linear(weight=w)
    elif edit == "tau":
        g.nodes["cells"].tau_mem[:] = value if isinstance(value, float) and value <= 0 else -1.0
    elif edit == "reset":
        g.nodes["cells"].v_reset[:] = 5.0
    elif edit == "no_output":
        del g.nodes["output"]
        g.edges.remove(("cells", "output"))
    elif edit == "not_a_graph":
        g = {"nodes": {}}
    elif edit == "dt":
        kwargs["dt_s"] = -1.0 if value is None else value  # None would mean the graph's own step
    elif edit == "refractory":
        kwargs["refractory_steps"] = value  # a float, text or None: not a whole number of steps
    with pytest.raises(ConfigError):
        NIRGraphSimulator(g, **kwargs)


@settings(max_examples=25, **HSET)
@given(
    field=st.sampled_from(["n_cells", "recurrent_weight", "global_weight", "rotation_bias", "ring_to_rotation_weight",
                           "velocity_gain", "rotation_to_ring_weight", "shift_cells", "attractor", "neurons"]),
    value=st.sampled_from([math.nan, math.inf, -1.0, 0, 7, 10**6, "a", None, True]),
)
def test_bad_rotation_ring_parameters_get_config_errors(field, value):
    number = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    weights = {"recurrent_weight", "global_weight", "ring_to_rotation_weight", "velocity_gain", "rotation_to_ring_weight"}
    valid = (
        (field in weights and number and value >= 0)
        or (field == "rotation_bias" and number)
        or (field == "shift_cells" and value == 7)  # an integer in [1, 180) on the 360-cell ring
    )
    if valid:
        assert getattr(RotationRingParams(**{field: value}), field) == value
        return
    with pytest.raises(ConfigError):
        RotationRingParams(**{field: value})


def test_a_graph_rockpool_writes_back_is_refused_with_the_lost_edge_named():
    """Rockpool's to_nir of the module its from_nir built drops the inhibition -> cells edge: not the same network."""
    _need("rockpool")
    import torch
    from rockpool.nn.modules.torch.nir import from_nir as rockpool_from_nir
    from rockpool.nn.modules.torch.nir import to_nir as rockpool_to_nir

    g = to_nir(_ring_population(24))
    back = rockpool_to_nir(rockpool_from_nir(g), torch.zeros(1, 1, 24))
    with pytest.raises(ConfigError, match="metadata"):
        from_nir(back)
    with pytest.raises(ConfigError, match="inhibition -> cells"):
        from_nir(back, metadata=g.metadata["cansim"])
    # the same graph with cansim's edges is accepted when the metadata is handed over
    same = nir.NIRGraph(nodes=dict(g.nodes), edges=list(g.edges), metadata={})
    assert from_nir(same, metadata=g.metadata["cansim"]).params == _ring_population(24).params


@pytest.mark.slow  # seconds of simulated turning (fast loop <= 4 min)
def test_the_rat_heading_example_runs_on_a_short_piece(tmp_path):
    pytest.importorskip("ratinabox", reason="the recorded trajectory ships with ratinabox")
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "nir_ring_rat_heading.py"
    spec = importlib.util.spec_from_file_location("nir_ring_rat_heading", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--seconds", "0.3", "--cells", "60", "--out", str(tmp_path / "h.json")]) == 0
    res = json.loads((tmp_path / "h.json").read_text())
    assert res["seconds"] == 0.3 and 0.0 <= res["rms_heading_error_deg"] <= 180.0
    t, head = mod.rat_heading(1.0)
    assert t[0] == 0.0 and t[-1] <= 1.0 + 1e-9 and np.all(np.isfinite(head))
