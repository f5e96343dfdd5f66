"""The 2-D sheet that path-integrates inside its NIR graph (issue 23, item 2: the 2-D version).

Layout and arithmetic are checked by hand on a small sheet; the slow tests simulate the
graph (cansim's own simulator, then snnTorch and Norse importing it unmodified) and read
the bump's position from the spike counts with a population vector computed here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

nir = pytest.importorskip("nir")

from cansim.errors import ConfigError, InvalidInputError, ShapeError  # noqa: E402
from cansim.spiking import (  # noqa: E402
    NIRGraphSimulator,
    SheetCalibration,
    VelocitySheetParams,
    calibrate_sheet_speed,
    sheet_input,
    sheet_kick,
    sheet_position_cells,
    velocity_sheet_graph,
)
from cansim.spiking.nir_consumers import ConsumerRunner  # noqa: E402
from consumers import need as _need  # noqa: E402
from cansim.spiking.nir_io import current_gain, input_gain  # noqa: E402

HSET = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])
DT = 1e-4


# ------------------------------------------------------------------ by hand
def _pv_cells(counts: np.ndarray, n: int) -> np.ndarray:
    """Population vector per axis of an (n, n) count array, in cells (written out here, not the library's)."""
    c = counts.reshape(n, n)
    out = []
    for m in (c.sum(axis=1), c.sum(axis=0)):
        x = sum(m[i] * math.cos(2 * math.pi * i / n) for i in range(n))
        y = sum(m[i] * math.sin(2 * math.pi * i / n) for i in range(n))
        out.append((math.atan2(y, x) * n / (2 * math.pi)) % n)
    return np.array(out)


def test_the_graph_is_laid_out_as_documented():
    n, s = 12, 2
    p = VelocitySheetParams(n_cells=n, shift_cells=s, pool_cells=3, velocity_gain=0.7, direction_bias=0.25,
                            sheet_to_direction_weight=0.4, direction_to_sheet_weight=5.0, pool_bias=-0.5,
                            sheet_to_pool_weight=0.03, pool_to_sheet_weight=2.0)
    g = velocity_sheet_graph(p)
    S, total = n * n, 5 * n * n + 3
    assert set(g.nodes) == {"input", "input_map", "cells", "excitation", "inhibition", "readout", "output"}
    assert isinstance(g.nodes["cells"], nir.CubaLIF) and np.asarray(g.nodes["cells"].tau_mem).size == total
    assert g.nodes["input_map"].weight.shape == (total, S + 2)
    assert g.nodes["readout"].weight.shape == (S, total)
    assert g.metadata["cansim"]["format"] == "cansim.spiking.velocity_sheet/1"
    gi, cg = input_gain(p.neurons, DT), current_gain(p.neurons, DT)
    w_in, b_in = g.nodes["input_map"].weight / gi, g.nodes["input_map"].bias / gi
    # velocity: +x, -x, +y, -y populations, each S cells, in that order
    for d, (ux, uy) in enumerate([(1, 0), (-1, 0), (0, 1), (0, -1)]):
        rows = slice((1 + d) * S, (2 + d) * S)
        assert np.allclose(w_in[rows, S], 0.7 * ux) and np.allclose(w_in[rows, S + 1], 0.7 * uy)
        assert np.allclose(b_in[rows], 0.25)
    assert np.allclose(b_in[:S], p.neurons.bias_current) and np.allclose(b_in[5 * S:], -0.5)
    assert np.allclose(w_in[:S, :S], np.eye(S)) and not w_in[S:, :S].any()
    # the pushes: excitation passes z through, inhibition holds the pushes (cansim units after / current gain)
    w_inh = g.nodes["inhibition"].weight / cg
    g1 = np.exp(-((np.arange(11) - 5) ** 2) / 8.0)
    taps = np.outer(g1, g1) / np.outer(g1, g1).sum()
    j = (3, 7)
    for d, (ux, uy) in enumerate([(1, 0), (-1, 0), (0, 1), (0, -1)]):
        col = S + (1 + d) * S + j[0] * n + j[1]  # z_all offset S, then the population's block
        push = w_inh[:S, col].reshape(n, n)
        target = ((j[0] + s * ux) % n, (j[1] + s * uy) % n)
        assert np.unravel_index(np.argmax(push), push.shape) == target
        assert push[target] == pytest.approx(5.0 * taps[5, 5])
        assert push[(target[0] + 1) % n, target[1]] == pytest.approx(5.0 * taps[6, 5])
        # the direction cell hears its own sheet cell only
        row = w_inh[(1 + d) * S + j[0] * n + j[1], S : 2 * S]
        assert row[j[0] * n + j[1]] == pytest.approx(0.4) and np.count_nonzero(row) == 1
    # the pool: every pool cell hears every sheet spike; every sheet cell is inhibited by every pool spike
    assert np.allclose(w_inh[5 * S:, S : 2 * S], 0.03)
    assert np.allclose(w_inh[:S, S + 5 * S:], -2.0)


def test_the_sheets_graph_survives_a_nir_file(tmp_path):
    g = velocity_sheet_graph(VelocitySheetParams(n_cells=12))
    path = tmp_path / "sheet.nir"
    nir.write(path, g)
    back = nir.read(path)
    for name in ("input_map", "excitation", "inhibition", "readout"):
        assert np.array_equal(np.asarray(back.nodes[name].weight), np.asarray(g.nodes[name].weight))


def test_position_kick_and_input_by_hand():
    n = 16
    one = np.zeros((n, n))
    one[3, 7] = 5.0
    assert np.allclose(sheet_position_cells(one, n), (3.0, 7.0))
    two = np.zeros((n, n))
    two[0, 4] = two[n - 1, 4] = 1.0  # across the wrap: half-way between cell 15 and cell 0
    assert np.allclose(sheet_position_cells(two.ravel(), n), (n - 0.5, 4.0))
    kick = sheet_kick(n, (5.0, 2.0), peak=2.0, sigma_cells=2.0)
    assert kick.shape == (n, n) and kick[5, 2] == pytest.approx(2.0)
    assert kick[6, 2] == pytest.approx(2.0 * math.exp(-1.0 / 8.0)) and kick[5, 1] == kick[5, 3]
    assert np.allclose(sheet_position_cells(kick, n), _pv_cells(kick, n))
    assert np.allclose(sheet_position_cells(kick, n), (5.0, 2.0), atol=1e-9)
    x = sheet_input(kick, (0.3, -0.2), n)
    assert x.shape == (n * n + 2,) and np.array_equal(x[: n * n], kick.ravel()) and tuple(x[-2:]) == (0.3, -0.2)
    assert np.array_equal(sheet_input(0.5, (0, 0), n)[: n * n], np.full(n * n, 0.5))


def test_sheet_calibration_inverts_its_table_by_hand():
    cal = SheetCalibration((0.0, 0.5, 1.0, 1.5), (0.0, 0.2, 0.6, 0.5))  # rises to 0.6 m/s, then falls
    assert cal.max_m_s == pytest.approx(0.6)
    assert np.allclose(cal.command((0.4, 0.0)), (0.75, 0.0))  # 0.4 is half-way from 0.2 to 0.6
    assert np.allclose(cal.command((0.0, -0.3)), (0.0, -0.625))
    assert np.allclose(cal.command((0.3, 0.4)), (0.6 * 0.875, 0.8 * 0.875))  # |v| = 0.5 -> 0.875, same direction
    assert np.allclose(cal.command((2.0, 0.0)), (1.0, 0.0))  # saturates at the top of the rising part
    assert np.allclose(cal.command((0.0, 0.0)), (0.0, 0.0))
    both = cal.command([[0.1, 0.0], [0.0, 0.0]])
    assert both.shape == (2, 2) and np.allclose(both, [[0.25, 0.0], [0.0, 0.0]])


# ------------------------------------------------------------------ bad input
_BAD = st.one_of(st.just(float("nan")), st.just(float("inf")), st.just(-1.0), st.just("x"), st.just(True), st.none())


@settings(max_examples=40, **HSET)
@given(field=st.sampled_from(["n_cells", "cell_size_m", "recurrent_weight", "global_weight", "sheet_to_direction_weight",
                              "velocity_gain", "direction_to_sheet_weight", "shift_cells", "pool_cells",
                              "sheet_to_pool_weight", "pool_to_sheet_weight", "direction_bias", "pool_bias"]),
       value=_BAD)
def test_bad_sheet_parameters_get_config_errors(field, value):
    if field in ("direction_bias", "pool_bias") and value == -1.0:
        return  # a negative bias is a valid bias
    with pytest.raises(ConfigError):
        VelocitySheetParams(**{field: value})


@pytest.mark.parametrize("kwargs", [dict(n_cells=11), dict(n_cells=33), dict(n_cells=12, shift_cells=6),
                                    dict(attractor=3), dict(neurons="lif")])
def test_out_of_range_sheet_parameters_get_config_errors(kwargs):
    with pytest.raises(ConfigError):
        VelocitySheetParams(**kwargs)


@settings(max_examples=40, **HSET)
@given(current=st.sampled_from([(0.5, True), (np.zeros(16), True), (np.zeros((4, 4)), True), (np.zeros(5), False),
                                (float("nan"), False), (np.zeros((4, 3)), False), ("x", False)]),
       velocity=st.sampled_from([((0.0, 0.0), True), ((1.0, -2.0), True), ((float("inf"), 0.0), False), ((1.0,), False),
                                 ("ab", False), ((0.0, 0.0, 0.0), False)]),
       n=st.sampled_from([(4, True), (0, False), (True, False), (2.5, False), (-3, False)]))
def test_bad_sheet_inputs_get_typed_errors(current, velocity, n):
    (c, c_ok), (v, v_ok), (k, k_ok) = current, velocity, n
    if c_ok and v_ok and k_ok:
        out = sheet_input(c, v, k)
        assert out.shape == (18,) and np.array_equal(out[-2:], v)
    else:
        with pytest.raises((ShapeError, InvalidInputError)):
            sheet_input(c, v, k)


@pytest.mark.parametrize("call", [
    lambda: sheet_position_cells(np.zeros((4, 4)), 4),
    lambda: sheet_position_cells(-np.ones((4, 4)), 4),
    lambda: sheet_position_cells(np.ones(15), 4),
    lambda: sheet_position_cells(np.full((4, 4), np.nan), 4),
    lambda: sheet_kick(4, (1.0,)),
    lambda: sheet_kick(4, (1.0, 2.0), sigma_cells=0.0),
    lambda: sheet_kick(0, (1.0, 2.0)),
    lambda: SheetCalibration((0.0, 1.0), (0.0, 1.0)).command((1.0, 2.0, 3.0)),
    lambda: SheetCalibration((0.0, 1.0), (0.0, 1.0)).command((np.nan, 0.0)),
])
def test_bad_position_kick_and_command_arguments_get_typed_errors(call):
    with pytest.raises((ShapeError, InvalidInputError)):
        call()


@settings(max_examples=30, **HSET)
@given(inputs=st.lists(st.one_of(st.floats(-1, 2), st.just(float("nan"))), min_size=0, max_size=4),
       speeds=st.lists(st.one_of(st.floats(-1, 2), st.just(float("nan"))), min_size=0, max_size=4))
def test_bad_sheet_calibration_tables_get_config_errors(inputs, speeds):
    good = (len(inputs) == len(speeds) >= 2 and all(map(math.isfinite, inputs + speeds)) and inputs[0] == 0.0
            and speeds[0] == 0.0 and all(b > a for a, b in zip(inputs, inputs[1:])) and speeds[1] > 0)
    if good:
        SheetCalibration(tuple(inputs), tuple(speeds))
    else:
        with pytest.raises(ConfigError):
            SheetCalibration(tuple(inputs), tuple(speeds))


@pytest.mark.parametrize("kwargs", [dict(speeds_m_s=()), dict(speeds_m_s=(0.2, 0.1)), dict(speeds_m_s=(0.0, 0.1)),
                                    dict(speeds_m_s="ab"), dict(settle_s=0.0), dict(measure_s=float("nan")),
                                    dict(params="sheet")])
def test_calibrate_sheet_speed_rejects_bad_arguments(kwargs):
    with pytest.raises(ConfigError):
        calibrate_sheet_speed(**kwargs)


# ------------------------------------------------------------------ simulated (slow)
def _drive(step, n: int, velocity_of_t, seconds: float, read_every_s: float = 0.05) -> np.ndarray:
    """Kick at the centre for 100 ms, then the velocity input; the bump's position every ``read_every_s`` (cells)."""
    kick = sheet_input(sheet_kick(n, (n / 2.0, n / 2.0)), (0.0, 0.0), n)
    decay, trace, out = math.exp(-DT / 0.05), np.zeros(n * n), []
    every = int(round(read_every_s / DT))
    for k in range(int(round((0.1 + seconds) / DT))):
        t = k * DT - 0.1
        trace = trace * decay + step(kick if t < 0 else sheet_input(0.0, velocity_of_t(t), n))
        if t >= 0 and (k + 1) % every == 0:
            out.append(_pv_cells(trace, n))
    return np.unwrap(np.array(out) * 2 * np.pi / n, axis=0) * n / (2 * np.pi)


@pytest.mark.slow  # ~1 min of simulated sheet
def test_the_sheet_holds_its_bump_at_rest_and_moves_it_along_the_velocity():
    p = VelocitySheetParams()
    n = p.n_cells
    sim = NIRGraphSimulator(velocity_sheet_graph(p))
    rest = _drive(sim.step, n, lambda t: (0.0, 0.0), 0.5)
    assert np.abs(rest - n / 2.0).max() < 0.5
    for v in [(0.6, 0.0), (0.0, -0.6), (0.45, 0.45)]:
        sim.reset()
        path = _drive(sim.step, n, lambda t, v=v: v, 0.5)
        moved = path[-1] - path[0]
        assert np.linalg.norm(moved) > 1.5, (v, moved)  # at least 1.5 cells in 0.45 s
        angle = math.degrees(math.atan2(moved[1], moved[0]) - math.atan2(v[1], v[0]))
        assert abs((angle + 180) % 360 - 180) < 10.0, (v, moved)


@pytest.mark.slow  # ~2 min: a calibration, then three commanded runs
def test_the_calibrated_sheet_moves_at_the_wanted_velocity():
    p = VelocitySheetParams()
    n = p.n_cells
    cal = calibrate_sheet_speed(p, (0.2, 0.4, 0.6, 0.8, 1.0))
    sim = NIRGraphSimulator(velocity_sheet_graph(p))
    for want in [(0.5, 0.0), (0.0, 0.5), (-0.3, 0.4)]:
        sim.reset()
        cmd = cal.command(want)
        path = _drive(sim.step, n, lambda t, c=cmd: c, 0.6) * p.cell_size_m
        k = int(round(0.2 / 0.05))  # from 0.2 s on, after the bump has settled
        t = 0.05 * np.arange(1, len(path) + 1)
        got = np.array([np.polyfit(t[k:], path[k:, a], 1)[0] for a in range(2)])
        assert np.linalg.norm(got - want) <= 0.15 * np.linalg.norm(want), (want, got)


@pytest.mark.slow  # ~1-2 min per toolchain
@pytest.mark.parametrize("consumer", ["snntorch", "norse"])
def test_consumer_moves_the_sheets_bump_like_cansim(consumer):
    _need(consumer)
    p = VelocitySheetParams()
    n = p.n_cells
    g = velocity_sheet_graph(p)
    v = lambda t: (0.6, 0.3)  # noqa: E731
    ref = _drive(NIRGraphSimulator(g).step, n, v, 0.6)
    got = _drive(ConsumerRunner(g, consumer, dt_s=DT).step, n, v, 0.6)
    assert np.abs(got - ref).max() <= 0.25, (consumer, got - ref)  # a quarter of a cell all along
    moved, moved_ref = got[-1] - got[0], ref[-1] - ref[0]
    assert np.linalg.norm(moved - moved_ref) <= 0.1 * np.linalg.norm(moved_ref), (consumer, moved, moved_ref)
