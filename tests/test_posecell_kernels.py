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
from cansim.models.posecell_network import _wrap_table


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
    K._spread(p, w, dim, _wrap_table(nxy, half), _wrap_table(nth, half), out)
    ref = _reference_spread(p, w, dim)
    assert np.array_equal(out.view(np.uint64), ref.view(np.uint64))


def test_an_empty_field_spreads_to_zeros():
    p = np.zeros((6, 7, 7))
    out = np.full_like(p, np.nan)
    K._spread(p, np.ones(125) / 125, 5, _wrap_table(7, 2), _wrap_table(6, 2), out)
    assert np.array_equal(out, np.zeros_like(p))


@pytest.mark.parametrize("seed", [0, 1])
def test_dynamics_is_excite_inhibit_global_inhibition_and_normalisation(seed):
    """One dynamics step against the reference spreads and the C++ per-cell rule, bit for bit."""
    rng = np.random.default_rng(seed)
    nth, nxy, gi = 12, 11, 2e-3
    p = _field(rng, nth, nxy, 0.2)
    w_e = rng.random(7 ** 3); w_e /= w_e.sum()
    w_i = rng.random(5 ** 3); w_i /= w_i.sum()
    exc = _reference_spread(p, w_e, 7)
    inh = _reference_spread(exc, w_i, 5)
    cells = []
    for e, h in zip(exc.ravel().tolist(), inh.ravel().tolist()):
        a = e - h
        cells.append(a - gi if a >= gi else 0.0)
    total = 0.0
    for a in cells:
        total += a
    expected = np.array([a / total for a in cells]).reshape(p.shape)
    got = p.copy()
    t = K.dynamics(got, np.empty_like(got), w_e, 7, _wrap_table(nxy, 3), _wrap_table(nth, 3),
                   w_i, 5, _wrap_table(nxy, 2), _wrap_table(nth, 2), gi)
    assert t == total
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))
