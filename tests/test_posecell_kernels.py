"""The exact engine's excite/inhibit kernels against a plain-Python scatter in OpenRatSLAM's order.

``cansim.models._posecell_kernels._spread`` compiles each kernel width separately (the
width is a tuple length, a compile-time constant), skips empty (y, x) columns and splits
straight from wrapped rows; every path must give, bit for bit, what the C++ ``excite`` /
``inhibit`` loops give: sources visited x outermost, theta innermost, each non-zero
source added to its dim^3 targets in (theta, y, x) kernel order through the wrap tables.
The reference below is that loop written out in Python floats (IEEE doubles, the same
operations), independent of the compiled kernel.
"""

from __future__ import annotations

import numpy as np
import pytest

from cansim.models import _posecell_kernels as K
from cansim.models.posecell_network import _gather_table, _wrap_table


def _reference_spread(p: np.ndarray, w: np.ndarray, dim: int) -> np.ndarray:
    nth, nxy = p.shape[0], p.shape[1]
    half = dim // 2
    wxy, wth = _wrap_table(nxy, half).tolist(), _wrap_table(nth, half).tolist()
    out = [[[0.0] * nxy for _ in range(nxy)] for _ in range(nth)]
    wl = w.tolist()
    for i in range(nxy):
        for j in range(nxy):
            for k in range(nth):
                v = float(p[k, j, i])
                if v != 0.0:
                    n = 0
                    for zl in range(k, k + dim):
                        for yl in range(j, j + dim):
                            for xl in range(i, i + dim):
                                row = out[wth[zl]][wxy[yl]]
                                row[wxy[xl]] = row[wxy[xl]] + v * wl[n]
                                n += 1
    return np.array(out)


def _field(rng: np.random.Generator, nth: int, nxy: int, density: float) -> np.ndarray:
    p = rng.random((nth, nxy, nxy))
    p[rng.random(p.shape) > density] = 0.0
    p[:, :, 0] += (rng.random((nth, nxy)) < density) * rng.random((nth, nxy))  # mass on the wrap edges
    p[:, -1, :] += (rng.random((nth, nxy)) < density) * rng.random((nth, nxy))
    return p


@pytest.mark.parametrize("dim", [1, 3, 5, 7, 9, 11])
@pytest.mark.parametrize("seed,density", [(0, 0.05), (1, 0.4), (2, 1.0)])
def test_every_width_spreads_in_the_cpp_order_bit_for_bit(dim, seed, density):
    rng = np.random.default_rng(seed)
    nth, nxy = 10, 9  # 11 > 9: the kernel wraps onto itself (cells receive a source twice)
    p = _field(rng, nth, nxy, density)
    w = rng.random(dim ** 3)
    w /= w.sum()
    half = dim // 2
    out = np.full_like(p, np.nan)  # the kernel must overwrite every cell
    K._spread(p, w, dim, _wrap_table(nxy, half), _wrap_table(nth, half), out, np.ones(nth, dtype=bool))
    ref = _reference_spread(p, w, dim)
    assert np.array_equal(out.view(np.uint64), ref.view(np.uint64))


def test_an_empty_field_spreads_to_zeros():
    p = np.zeros((6, 7, 7))
    out = np.full_like(p, np.nan)
    K._spread(p, np.ones(125) / 125, 5, _wrap_table(7, 2), _wrap_table(6, 2), out, np.ones(6, dtype=bool))
    assert np.array_equal(out, np.zeros_like(p))


@pytest.mark.parametrize("seed", [0, 1])
def test_dynamics_is_excite_inhibit_global_inhibition_and_normalisation(seed):
    """One dynamics step against the reference spreads and the C++ per-cell rule, bit for bit."""
    rng = np.random.default_rng(seed)
    nth, nxy, gi = 12, 11, 2e-3
    p = _field(rng, nth, nxy, 0.2)
    w_e = rng.random(7 ** 3); w_e /= w_e.sum()
    w_i = rng.random(5 ** 3); w_i /= w_i.sum()
    total, expected = _reference_dynamics(p, w_e, 7, w_i, 5, gi)
    got = p.copy()
    t = K.dynamics(got, np.empty_like(got), w_e, 7, _wrap_table(nxy, 3), _wrap_table(nth, 3),
                   w_i, 5, _wrap_table(nxy, 2), _wrap_table(nth, 2), gi)
    assert t == total
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))


def _reference_dynamics(p: np.ndarray, w_e: np.ndarray, e_dim: int, w_i: np.ndarray, i_dim: int, gi: float):
    """C++ ``excite``, ``inhibit``, global inhibition and normalisation in plain Python floats."""
    exc = _reference_spread(p, w_e, e_dim)
    inh = _reference_spread(exc, w_i, i_dim)
    cells = []
    for e, h in zip(exc.ravel().tolist(), inh.ravel().tolist()):
        a = e - h
        cells.append(a - gi if a >= gi else 0.0)
    total = 0.0
    for a in cells:
        total += a
    if not total > 0.0:
        return total, np.array(cells).reshape(p.shape)
    return total, np.array([a / total for a in cells]).reshape(p.shape)


def test_gather_tables_list_each_targets_sources_ascending_with_their_offsets():
    # n = 6, dim = 5 (half 2): the scatter sends source s to (s + d - 2) mod 6, so target 0 is
    # reached from 2 (d=0), 1 (d=1), 0 (d=2), 5 (d=3), 4 (d=4); ascending: 0, 1, 2, 4, 5
    src, off = _gather_table(6, 5, 1, 1)
    assert src[0].tolist() == [0, 1, 2, 4, 5] and off[0].tolist() == [2, 1, 0, 4, 3]
    assert src[3].tolist() == [1, 2, 3, 4, 5] and off[3].tolist() == [4, 3, 2, 1, 0]  # interior: no wrap
    src, off = _gather_table(6, 5, 10, 7)  # strides scale both columns
    assert src[0].tolist() == [0, 10, 20, 40, 50] and off[0].tolist() == [14, 7, 0, 28, 21]


def _gather_args(nxy: int, nth: int, dim: int) -> tuple:
    return (*_gather_table(nxy, dim, 1, 1), *_gather_table(nxy, dim, nxy, dim), *_gather_table(nth, dim, nxy * nxy, dim * dim))


@pytest.mark.parametrize("e_dim,i_dim", [(7, 5), (5, 3), (3, 7), (5, 9), (3, 1)])
@pytest.mark.parametrize("seed,density,quantile", [(0, 0.02, 0.5), (1, 0.2, 0.9), (2, 0.05, 0.0), (3, 0.02, 1.0)])
def test_gathered_inhibition_is_the_cpp_scatter_bit_for_bit(e_dim, i_dim, seed, density, quantile):
    """``dynamics_gather`` gathers the inhibition only for cells excited to >= global inhibition,
    four cells at a time: every cell must still equal the C++ scatter's. ``quantile`` puts the
    global inhibition at that share of the excited cells (0: none skipped; 1: all but the peak)."""
    rng = np.random.default_rng(seed)
    nth, nxy = 13, 11
    p = _field(rng, nth, nxy, density)
    w_e = rng.random(e_dim ** 3); w_e /= w_e.sum()
    w_i = rng.random(i_dim ** 3); w_i /= w_i.sum()
    exc = _reference_spread(p, w_e, e_dim)
    gi = float(np.quantile(exc[exc > 0], quantile)) * 0.5 if quantile else 0.0
    total, expected = _reference_dynamics(p, w_e, e_dim, w_i, i_dim, gi)
    got = np.full_like(p, np.nan)  # every cell must be written
    src = p.copy()
    t = K.dynamics_gather(src, got, np.empty_like(got), w_e, e_dim, _wrap_table(nxy, e_dim // 2), _wrap_table(nth, e_dim // 2),
                          w_i, i_dim, _wrap_table(nxy, i_dim // 2), _wrap_table(nth, i_dim // 2),
                          *_gather_args(nxy, nth, i_dim), gi, np.ones(nth, dtype=bool))
    assert np.array_equal(src.view(np.uint64), p.view(np.uint64))  # the source is only read
    assert t == total
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))


@pytest.mark.parametrize("e_dim,i_dim", [(7, 5), (5, 3), (3, 7)])
@pytest.mark.parametrize("live_layers", [(0,), (5,), (12,), (3, 9)])
def test_only_the_layers_the_live_layers_excite_are_gathered_bit_for_bit(e_dim, i_dim, live_layers):
    """With few live layers the inhibition scans only the excited field's layers within the
    excitation's theta reach (e_dim // 2 either side, across the wrap); cells excited above
    the global inhibition in the outermost reached layers must still be gathered and kept."""
    rng = np.random.default_rng(e_dim * 100 + sum(live_layers))
    nth, nxy = 13, 11
    p = np.zeros((nth, nxy, nxy))
    for k in live_layers:
        p[k] = rng.random((nxy, nxy)) * (rng.random((nxy, nxy)) < 0.3)
    w_e = rng.random(e_dim ** 3) + 0.5; w_e /= w_e.sum()  # no small weight: the far layers are excited too
    w_i = rng.random(i_dim ** 3); w_i /= w_i.sum()
    exc = _reference_spread(p, w_e, e_dim)
    gi = float(np.quantile(exc[exc > 0], 0.3)) * 0.2
    reached = {(k + d) % nth for k in live_layers for d in range(-(e_dim // 2), e_dim // 2 + 1)}
    outer = {(k + d) % nth for k in live_layers for d in (-(e_dim // 2), e_dim // 2)} - {k % nth for k in live_layers}
    total, expected = _reference_dynamics(p, w_e, e_dim, w_i, i_dim, gi)
    assert {int(k) for k in np.flatnonzero(exc.reshape(nth, -1).max(axis=1) > 0)} == reached
    assert all(expected[k].max() > 0 for k in outer)  # the reach's end layers keep cells
    flags = np.zeros(nth, dtype=bool)
    flags[list(live_layers)] = True
    got = np.full_like(p, np.nan)  # every cell must be written
    t = K.dynamics_gather(p.copy(), got, np.empty_like(got), w_e, e_dim, _wrap_table(nxy, e_dim // 2),
                          _wrap_table(nth, e_dim // 2), w_i, i_dim, _wrap_table(nxy, i_dim // 2), _wrap_table(nth, i_dim // 2),
                          *_gather_args(nxy, nth, i_dim), gi, flags)
    assert t == total
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))
    assert flags.tolist() == [bool(expected[k].max() > 0) for k in range(nth)]


def test_a_negative_cell_takes_the_scatter_path_and_still_matches():
    """With a negative cell an inhibition can be negative, so no cell may be skipped."""
    rng = np.random.default_rng(5)
    nth, nxy, gi = 9, 9, 0.05
    p = _field(rng, nth, nxy, 0.1)
    p[4, 4, 4] = -30.0  # its neighbours' inhibition turns negative: excited below gi, they still survive
    w_e = rng.random(7 ** 3); w_e /= w_e.sum()
    w_i = rng.random(5 ** 3); w_i /= w_i.sum()
    total, expected = _reference_dynamics(p, w_e, 7, w_i, 5, gi)
    exc = _reference_spread(p, w_e, 7)
    assert np.any((exc < gi) & (expected > 0))  # the case a skip would get wrong
    got = np.full_like(p, np.nan)  # every cell must be written
    t = K.dynamics_gather(p.copy(), got, np.empty_like(got), w_e, 7, _wrap_table(nxy, 3), _wrap_table(nth, 3),
                          w_i, 5, _wrap_table(nxy, 2), _wrap_table(nth, 2), *_gather_args(nxy, nth, 5), gi, np.ones(nth, dtype=bool))
    assert t == total
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))


@pytest.mark.parametrize("nxy,nth,cell", [(21, 36, 1.0), (12, 10, 0.3), (5, 5, 0.5)])
def test_the_network_equals_its_all_scatter_run_cell_for_cell(nxy, nth, cell):
    """``PosecellNetwork``'s shortcuts (gathered inhibition, skipped empty layers) against the same
    network on the plain scatter path, 300 steps of random odometry and injections, every cell's bits."""
    from cansim.models.posecell_network import PosecellNetwork

    fast, plain = PosecellNetwork(nxy, nth, cell), PosecellNetwork(nxy, nth, cell)
    plain._gather = None
    assert fast._gather is not None
    rng = np.random.default_rng(nxy)
    for step in range(300):
        v, w = float(rng.uniform(-0.4, 1.0)), float(rng.uniform(-0.6, 0.6))
        inj = None
        if step % 7 == 0:
            idx = rng.integers(0, fast.size, size=int(rng.integers(1, 4)))
            inj = (idx.astype(np.int64), rng.random(idx.size) * 0.2)
        a = fast.step(v, w, 1.0, injection=inj)
        b = plain.step(v, w, 1.0, injection=inj)
        assert np.array_equal(a.view(np.uint64), b.view(np.uint64))
        assert np.array_equal(fast.activity.view(np.uint64), plain.activity.view(np.uint64)), step


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_skipping_empty_layers_changes_no_bit(seed):
    """``translate``, ``rotate_theta`` and ``best_sums`` given which layers hold only +0.0 (the rest
    skipped) against the same kernels told every layer may be live; the flags they return are exact."""
    from cansim.models.posecell_network import PosecellNetwork

    rng = np.random.default_rng(seed)
    pc = PosecellNetwork(15, 36)
    p = np.zeros((36, 15, 15))
    live = rng.random(36) < 0.3
    live[0] = live[35] = True  # the theta wrap
    for k in np.flatnonzero(live):
        p[k] = rng.random((15, 15)) * (rng.random((15, 15)) < 0.2)
    p[int(np.flatnonzero(live)[0]), 0, 0] = 0.0  # a live flag on zeros is allowed
    for add in (0.0, np.pi):
        rot, cs, sn = pc._layer_tables[add]
        a, b = p.copy(), p.copy()
        flags = live.copy()
        K.translate(a, rot, cs, sn, 0.8, flags)
        K.translate(b, rot, cs, sn, 0.8, np.ones(36, dtype=bool))
        assert np.array_equal(a.view(np.uint64), b.view(np.uint64)) and np.array_equal(flags, live)
    for s1, s2, weight in ((-1, -2, 0.3), (-35, -35, 1.0), (-3, -4, 0.999), (0, -1, 0.5)):
        a, b = p.copy(), p.copy()
        flags = live.copy()
        K.rotate_theta(a, np.full_like(a, np.nan), s1, s2, weight, flags)
        K.rotate_theta(b, np.empty_like(b), s1, s2, weight, np.ones(36, dtype=bool))
        assert np.array_equal(a.view(np.uint64), b.view(np.uint64))
        assert not np.any(b.any(axis=(1, 2)) & ~flags)  # every layer holding a non-zero cell is flagged
        args = (pc._half, pc._a_xy, pc._a_th, pc._sin_xy, pc._cos_xy, pc._sin_th, pc._cos_th)
        got = K.best_sums(a, *args, flags)
        ref = K.best_sums(b, *args, np.ones(36, dtype=bool))
        assert np.array_equal(np.array(got).view(np.uint64), np.array(ref).view(np.uint64))


def test_a_collapsing_step_with_an_injection_leaves_the_network_as_it_was():
    """The gathered step reads the state in place (the injection added, then undone): a step that
    global inhibition silences must leave every bit, and the next steps, as without it."""
    from cansim.errors import ZeroActivityError
    from cansim.models.posecell_network import PosecellNetwork
    from cansim.params import AttractorParams

    params = AttractorParams(global_inhibition=0.004)
    a, b = PosecellNetwork(params=params), PosecellNetwork(params=params)
    for pc in (a, b):
        pc.step(0.3, 0.1, 1.0, injection=(np.array([1234], dtype=np.int64), np.array([0.5])))
    before = a.activity
    flat = int(np.argmax(before))
    with pytest.raises(ZeroActivityError):  # global inhibition 1 silences every cell
        a._gi = 1.0
        a.step(0.3, 0.1, 1.0, injection=(np.array([flat, flat, 77], dtype=np.int64), np.array([0.25, 0.5, 0.125])))
    a._gi = b._gi
    assert np.array_equal(a.activity.view(np.uint64), before.view(np.uint64))
    for _ in range(5):
        x, y = a.step(0.4, -0.2, 1.0), b.step(0.4, -0.2, 1.0)
        assert np.array_equal(x.view(np.uint64), y.view(np.uint64))
        assert np.array_equal(a.activity.view(np.uint64), b.activity.view(np.uint64))
