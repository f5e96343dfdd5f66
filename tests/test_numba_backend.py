"""What is particular to the numba backend: the locality (packet box) path, the dense
path, serial vs threaded passes, per-thread workspaces and the circular-arc search.

The shared conformance suite (tests/test_backend_conformance.py) proves the numba
kernels equal the numpy reference; here the *same* steps run through the locality path,
the forced dense path and the numpy reference on activity layouts chosen to stress the
box logic (one packet, two far-apart packets, packets straddling the wrap, a full grid).
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("numba")

from cansim.backends.numba_backend import NumbaBackend  # noqa: E402
from cansim.backends.numpy_backend import NumpyBackend  # noqa: E402
from cansim.kernels import gaussian_kernel_1d  # noqa: E402

REF = NumpyBackend()
LOCAL = NumbaBackend()
DENSE = NumbaBackend(locality=False)


def _kernels(ndim, exc_width=7, inh_width=5):
    exc = [gaussian_kernel_1d(exc_width, 1.0) for _ in range(ndim)]
    inh = [gaussian_kernel_1d(inh_width, 2.0) for _ in range(ndim)]
    return exc, inh


def _packets(shape, centres, dtype=np.float32, half=1, seed=0):
    """Blocks of +-half cells (wrapping) of random activity around each centre; sum 1."""
    rng = np.random.default_rng(seed)
    a = np.zeros(shape)
    for c in centres:
        idx = np.ix_(*[(np.arange(-half, half + 1) + ci) % n for ci, n in zip(c, shape)])
        a[idx] += rng.uniform(0.5, 1.0, size=(2 * half + 1,) * len(shape))
    return (a / a.sum()).astype(dtype)


def _n_translated(ndim):
    """Translated (conditioned) axes: (x, y) of 3-D, (x, y, z) of 6-D."""
    return ndim - 1 if ndim <= 3 else ndim // 2


def _step_kwargs(shape, rng, *, cond=True, uniform=True, inject=True, phi=2e-5):
    ndim = len(shape)
    exc, inh = _kernels(ndim)
    kw = dict(flat_index=None, values=None, exc=exc, inh=inh, phi=phi, shift_axes=None,
              cond_shifts=None, uniform_shifts=None, window=3)
    if inject:
        kw["flat_index"] = rng.integers(0, int(np.prod(shape)), 2).astype(np.int64)
        kw["values"] = rng.uniform(0.0, 0.2, 2)
    if cond and ndim >= 2:
        k = _n_translated(ndim)
        kw["shift_axes"] = tuple(range(k))
        kw["cond_shifts"] = rng.uniform(-2.5, 2.5, shape[k:] + (k,))
    if uniform:
        u = rng.uniform(-2.5, 2.5, ndim)
        if cond and ndim >= 2:
            u[: _n_translated(ndim)] = 0.0  # rotations act on the condition axes
        kw["uniform_shifts"] = u
    return kw


def _assert_same_step(a, kw, backends=(LOCAL, DENSE)):
    ref_a, ref_d = REF.step(a.copy(), **kw)
    for b in backends:
        if ref_a is None:  # e.g. a single-cell axis: inhibition cancels excitation
            assert b.step(a, **kw) == (None, None)
            continue
        before = a.copy()
        out = np.full_like(a, 7.0)  # stale content must not leak into the result
        got_a, got_d = b.step(a, out=out, **kw)
        np.testing.assert_array_equal(a, before)
        assert got_a is out and got_a.dtype == a.dtype
        tol = 1e-5 if a.dtype == np.float32 else 1e-12
        np.testing.assert_allclose(got_a, ref_a, rtol=tol, atol=tol * float(ref_a.max()))
        np.testing.assert_allclose(got_d, ref_d, rtol=1e-6, atol=1e-6)


LAYOUTS = {
    "one packet": [(3, 4, 5)],
    "two far-apart packets": [(1, 1, 1), (14, 8, 7)],
    "straddles every wrap": [(0, 0, 0)],
    "two packets straddling": [(19, 0, 8), (0, 10, 0)],
}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_locality_and_dense_paths_equal_reference_3d(layout, dtype):
    shape = (20, 13, 9)  # non-cubic; kernels of 7 taps span most of the last axis
    a = _packets(shape, LAYOUTS[layout], dtype)
    kw = _step_kwargs(shape, np.random.default_rng(1))
    _assert_same_step(a, kw)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_full_random_grid_equals_reference(dtype):
    shape = (7, 11, 13)
    a = np.random.default_rng(2).random(shape).astype(dtype)
    _assert_same_step(a, _step_kwargs(shape, np.random.default_rng(3)))


@pytest.mark.parametrize("shape", [(5, 6, 7, 8), (3, 4, 5, 6, 7, 5), (10, 9, 8, 7, 6, 5)])
def test_higher_dimensional_packets(shape):
    centres = [tuple(n // 2 for n in shape), tuple(0 for _ in shape)]
    a = _packets(shape, centres, np.float32, half=1)
    _assert_same_step(a, _step_kwargs(shape, np.random.default_rng(len(shape))))


def test_ring_packet_across_zero_moves_more_than_one_cell():
    shape = (360,)
    a = _packets(shape, [(359,)], np.float32, half=2)
    kw = _step_kwargs(shape, np.random.default_rng(4), cond=False)
    kw["uniform_shifts"] = np.array([-3.7])
    _assert_same_step(a, kw)


def test_kernel_wider_than_axis_wraps_like_reference():
    shape = (3, 16, 2)  # 7- and 9-tap kernels on axes of 3 and 2 cells wrap several times
    exc = [gaussian_kernel_1d(w, 1.5) for w in (7, 5, 9)]
    inh = [gaussian_kernel_1d(w, 2.0) for w in (5, 3, 7)]
    a = _packets(shape, [(1, 15, 0)], np.float64, half=0)
    for b in (LOCAL, DENSE):
        np.testing.assert_allclose(b.dynamics(a, exc, inh, 0.0), REF.dynamics(a, exc, inh, 0.0), rtol=1e-12, atol=1e-15)


def test_uniform_shift_on_a_conditioned_axis_keeps_reference_order():
    """A uniform shift on a translated axis runs after the whole conditional shift."""
    shape = (9, 10, 6)
    a = _packets(shape, [(4, 9, 2)], np.float32)
    rng = np.random.default_rng(5)
    kw = _step_kwargs(shape, rng, inject=False)
    kw["uniform_shifts"] = np.array([1.3, -0.6, 2.2])
    _assert_same_step(a, kw)


@settings(max_examples=15, deadline=None)
@given(
    shape=st.lists(st.integers(1, 14), min_size=1, max_size=4).map(tuple),
    seed=st.integers(0, 2**31 - 1),
    n_packets=st.integers(1, 3),
    scale=st.sampled_from([0.3, 1.0, 4.5]),
)
def test_random_packets_locality_equals_dense_equals_reference(shape, seed, n_packets, scale):
    rng = np.random.default_rng(seed)
    centres = [tuple(int(rng.integers(n)) for n in shape) for _ in range(n_packets)]
    a = _packets(shape, centres, np.float32, half=int(rng.integers(0, 2)), seed=seed)
    kw = _step_kwargs(shape, rng, phi=float(rng.choice([0.0, 2e-5])))
    if kw["cond_shifts"] is not None:
        kw["cond_shifts"] = kw["cond_shifts"] * scale
    if kw["uniform_shifts"] is not None:
        kw["uniform_shifts"] = kw["uniform_shifts"] * scale
    _assert_same_step(a, kw)


def test_serial_and_threaded_passes_are_bitwise_identical():
    shape = (12, 11, 10, 9)
    a = np.random.default_rng(6).random(shape).astype(np.float32)
    kw = _step_kwargs(shape, np.random.default_rng(7))
    serial = NumbaBackend(parallel_work=10**15, threads=1)
    threaded = NumbaBackend(parallel_work=0, threads=2)
    sa, sd = serial.step(a, **kw)
    ta, td = threaded.step(a, **kw)
    np.testing.assert_array_equal(sa, ta)
    np.testing.assert_array_equal(sd, td)


def test_one_backend_shared_by_threads_gives_each_its_own_result():
    """Workspaces are per thread: concurrent steps on one backend instance do not mix."""
    backend = NumbaBackend()
    shape = (21, 21, 36)
    jobs = []
    for i in range(4):
        a = _packets(shape, [(3 * i, 5 * i, 7 * i)], np.float32, seed=i)
        jobs.append((a, _step_kwargs(shape, np.random.default_rng(10 + i))))
    expected = [backend.step(a, **kw) for a, kw in jobs]
    results: list = [None] * len(jobs)

    def run(i):
        a, kw = jobs[i]
        for _ in range(30):
            results[i] = backend.step(a, **kw)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(jobs))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for (ea, ed), (ga, gd) in zip(expected, results):
        np.testing.assert_array_equal(ga, ea)
        np.testing.assert_array_equal(gd, ed)


def test_collapse_returns_none_and_leaves_out_untouched():
    shape = (8, 9, 10)
    a = np.full(shape, 1e-9, dtype=np.float32)  # every cell ends below phi
    out = np.full(shape, 3.0, dtype=np.float32)
    kw = _step_kwargs(shape, np.random.default_rng(8), inject=False)
    for b in (LOCAL, DENSE):
        assert b.step(a, out=out, **kw) == (None, None)
        assert b.dynamics(a, *_kernels(3), 2e-5, out=out) is None
        assert np.all(out == 3.0)
    assert LOCAL.dynamics(np.zeros(shape, np.float32), *_kernels(3), 2e-5) is None


def test_shift_of_silent_grid_is_silent():
    z = np.zeros((6, 7), np.float64)
    np.testing.assert_array_equal(LOCAL.shift(z, np.array([1.5, -2.25])), z)


@pytest.mark.parametrize(
    "occupied, n, arc",
    [
        ([], 7, (0, 0)),
        ([3], 7, (3, 1)),
        ([0, 4, 5], 7, (4, 4)),  # largest gap 1..3 -> cells 4, 5, 6, 0
        ([1, 2], 7, (1, 2)),
        ([0, 6], 7, (6, 2)),  # straddles the wrap
        (list(range(7)), 7, (0, 7)),
        ([0, 2, 4, 6], 8, (2, 7)),  # equal gaps: the first largest one (cell 1) is left out
    ],
)
def test_arc_from_occupancy_is_the_complement_of_the_largest_gap(occupied, n, arc):
    from cansim.backends._numba_kernels import arc_from_occupancy

    occ = np.zeros(n, np.uint8)
    occ[occupied] = 1
    assert tuple(arc_from_occupancy(occ, n)) == arc


def test_non_contiguous_out_receives_the_result():
    shape = (9, 8, 7)
    a = _packets(shape, [(2, 3, 4)], np.float32)
    kw = _step_kwargs(shape, np.random.default_rng(9))
    ref_a, _ = LOCAL.step(a, **kw)
    big = np.zeros((9, 8, 14), np.float32)
    out = big[:, :, ::2]
    got_a, _ = LOCAL.step(a, out=out, **kw)
    assert got_a is out
    np.testing.assert_array_equal(out, ref_a)


@pytest.mark.parametrize("shape", [(61, 61, 36), (5, 5, 5, 5, 5, 5), (360,), (9, 1, 7)])
@pytest.mark.parametrize("kind", ["packet", "two packets", "dense"])
def test_occupancy_marks_exactly_the_non_zero_projections(shape, kind):
    """The box search sees every non-zero cell and nothing else (a wider box would still
    be correct, only slower; this keeps the locality path local)."""
    from cansim.backends._numba_kernels import mark_occupancy

    rng = np.random.default_rng(len(shape))
    if kind == "dense":
        a = rng.random(shape).astype(np.float32)
    else:
        centres = [tuple(n // 3 for n in shape)] + ([tuple(n - 1 for n in shape)] if kind == "two packets" else [])
        a = _packets(shape, centres, np.float32, half=1)
    occ = np.zeros((len(shape), max(shape)), np.uint8)
    marks = mark_occupancy(a.reshape(-1).view(np.uint32), np.array(shape, np.int64), occ)
    expected = [np.flatnonzero(a.any(axis=tuple(j for j in range(a.ndim) if j != k))) for k in range(a.ndim)]
    for k, n in enumerate(shape):
        np.testing.assert_array_equal(np.flatnonzero(occ[k, :n]), expected[k])
    assert marks == sum(len(e) for e in expected)


def test_inject_into_non_contiguous_out():
    a = np.zeros((4, 5), np.float32)
    out = np.ones((4, 10), np.float32)[:, ::2]
    got = LOCAL.inject(a, np.array([3, 3, 7]), np.array([0.25, 0.5, 1.0]), out=out)
    assert got is out
    expected = np.zeros((4, 5), np.float32)
    expected.flat[3] = 0.75
    expected.flat[7] = 1.0
    np.testing.assert_array_equal(out, expected)


def test_ring_fast_path_matches_reference_and_keeps_out_on_collapse():
    """1-D rings take a dedicated kernel; it must equal numpy and honour the collapse contract."""
    from cansim.backends import get_backend
    from cansim.kernels import gaussian_kernel_1d

    nb, ref = get_backend("numba"), get_backend("numpy")
    rng = np.random.default_rng(5)
    exc, inh = [gaussian_kernel_1d(7, 1.0)], [gaussian_kernel_1d(5, 2.0)]
    for dtype in (np.float32, np.float64):
        for n in (5, 36, 360):
            a = rng.random(n).astype(dtype)
            a /= a.sum()
            kw = dict(flat_index=np.array([1, 1], dtype=np.int64), values=np.array([0.1, 0.2]), exc=exc, inh=inh,
                      phi=2e-5, shift_axes=None, cond_shifts=None, uniform_shifts=np.array([rng.uniform(-4, 4)]),
                      window=3)
            got, gd = nb.step(a, **kw)
            want, wd = ref.step(a, **kw)
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-7)
            np.testing.assert_allclose(gd, wd, atol=1e-6)
    out = np.full(36, 7.0, dtype=np.float32)
    res, dec = nb.step(np.full(36, 1 / 36, dtype=np.float32), flat_index=np.array([3], dtype=np.int64),
                       values=np.array([0.5]), exc=exc, inh=inh, phi=1.0, shift_axes=None, cond_shifts=None,
                       uniform_shifts=None, window=3, out=out)
    assert res is None and dec is None
    assert np.all(out == 7.0)


# ----------------------------------------------------------- small full-grid path
GENERIC = NumbaBackend(small_grids=False)  # the same backend without the generated small-grid kernel


def _small_kwargs(shape, rng, *, shift_axes, scale, window=3, exc_width=5):
    """A step with repeated injections, conditional shifts of ``scale`` cells and uniform shifts on the rest."""
    ndim = len(shape)
    cond_shape = tuple(n for ax, n in enumerate(shape) if ax not in shift_axes)
    uni = rng.uniform(-scale, scale, ndim)
    uni[list(shift_axes)] = 0.0
    flat = rng.integers(0, int(np.prod(shape)), 3)
    return dict(flat_index=np.array([flat[0], flat[1], flat[0]], dtype=np.int64), values=rng.uniform(0.0, 0.2, 3),
                exc=[gaussian_kernel_1d(exc_width, 1.0) for _ in shape],
                inh=[gaussian_kernel_1d(5, np.sqrt(2.0)) for _ in shape], phi=2e-5,
                shift_axes=tuple(shift_axes), cond_shifts=rng.uniform(-scale, scale, cond_shape + (len(shift_axes),)),
                uniform_shifts=uni, window=window)


def _assert_small_path_exact(a, kw):
    """The generated kernel equals the generic numba pipeline bitwise and the numpy reference to rounding."""
    from cansim.backends._numba_small import applies

    assert applies(a.shape, kw["exc"], kw["inh"])
    ref_a, ref_d = REF.step(a.copy(), **kw)
    gen_a, gen_d = GENERIC.step(a, **kw)
    before = a.copy()
    out = np.full_like(a, 7.0)
    got_a, got_d = LOCAL.step(a, out=out, **kw)
    np.testing.assert_array_equal(a, before)
    assert got_a is out and got_a.dtype == a.dtype
    np.testing.assert_array_equal(got_a, gen_a)
    tol = 1e-6 if a.dtype == np.float32 else 1e-13
    np.testing.assert_allclose(got_a, ref_a, rtol=tol, atol=tol * float(ref_a.max()))
    np.testing.assert_allclose(got_d, ref_d, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got_d, gen_d, rtol=0, atol=1e-12)
    assert abs(float(got_a.sum(dtype=np.float64)) - 1.0) < 1e-5  # shifts conserve the normalised activity


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("scale", [0.01, 0.9, 7.3])
def test_small_6d_grid_path_equals_reference(dtype, scale):
    """5^6 (whisker6d): excitation covers every axis, so the step runs the generated kernel."""
    shape = (5,) * 6
    rng = np.random.default_rng(int(scale * 100))
    a = _packets(shape, [(2, 2, 2, 2, 2, 2)], dtype, half=1, seed=3)
    _assert_small_path_exact(a, _small_kwargs(shape, rng, shift_axes=(0, 1, 2), scale=scale))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shift_axes", [(0, 1), (0, 2), (1,)])
def test_small_3d_grid_with_wrapping_kernel_and_any_condition_axes(dtype, shift_axes):
    """4^3 with 7-tap excitation (wraps the axis), any conditioned axes, a spread-out random grid."""
    shape = (4, 4, 4)
    rng = np.random.default_rng(len(shift_axes) * 10 + shift_axes[-1])
    a = rng.random(shape).astype(dtype)
    a /= a.sum()
    _assert_small_path_exact(a, _small_kwargs(shape, rng, shift_axes=shift_axes, scale=3.4, exc_width=7))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_small_grid_uniform_shift_on_a_conditioned_axis_runs_after_the_conditional_shift(dtype):
    shape = (4, 4, 4)
    rng = np.random.default_rng(11)
    a = _packets(shape, [(1, 2, 3)], dtype, half=1)
    kw = _small_kwargs(shape, rng, shift_axes=(1, 2), scale=2.2, exc_width=7)
    kw["uniform_shifts"] = np.array([0.7, -1.6, 2.45])  # touches the conditioned axes 1 and 2
    _assert_small_path_exact(a, kw)
    kw["cond_shifts"] = np.zeros_like(kw["cond_shifts"])  # no conditional motion: uniform shift only
    _assert_small_path_exact(a, kw)
    kw["uniform_shifts"] = None
    kw["cond_shifts"] = None  # dynamics and decoding only
    _assert_small_path_exact(a, kw)


def test_small_grid_window_narrower_than_an_axis_centres_on_the_first_maximum():
    shape = (5,) * 6
    rng = np.random.default_rng(12)
    a = _packets(shape, [(4, 0, 1, 3, 2, 0)], np.float32, half=1, seed=5)
    _assert_small_path_exact(a, _small_kwargs(shape, rng, shift_axes=(0, 1, 2), scale=1.5, window=1))


def test_small_grid_collapse_returns_none_and_leaves_out_untouched():
    shape = (5,) * 6
    kw = _small_kwargs(shape, np.random.default_rng(13), shift_axes=(0, 1, 2), scale=1.0)
    kw.update(flat_index=None, values=None)
    a = np.full(shape, 1.0 / 5**6, dtype=np.float32)  # uniform grid: inhibition leaves every cell below phi
    out = np.full(shape, 3.0, dtype=np.float32)
    assert REF.step(a, **kw) == (None, None)
    assert LOCAL.step(a, out=out, **kw) == (None, None)
    assert np.all(out == 3.0)


def test_small_grid_non_contiguous_out_receives_the_result():
    shape = (4, 4, 4)
    a = _packets(shape, [(0, 3, 1)], np.float64)
    kw = _small_kwargs(shape, np.random.default_rng(14), shift_axes=(0, 1), scale=1.2, exc_width=7)
    want, _ = GENERIC.step(a, **kw)
    out = np.zeros((4, 4, 8))[:, :, ::2]
    got, _ = LOCAL.step(a, out=out, **kw)
    assert got is out
    np.testing.assert_array_equal(out, want)


def test_small_grid_path_applies_only_to_fully_covered_hypercubes():
    from cansim.backends._numba_small import applies

    k5, k7 = gaussian_kernel_1d(5, 1.0), gaussian_kernel_1d(7, 1.0)
    assert applies((5,) * 6, [k5] * 6, [k5] * 6)
    assert not applies((10,) * 6, [k5] * 6, [k5] * 6)  # the packet box is smaller than the grid
    assert not applies((21, 21, 36), [k7] * 3, [k5] * 3)
    assert not applies((5, 5, 4), [k5] * 3, [k5] * 3)  # mixed lengths: generic pipeline
    assert not applies((5,), [k5], [k5])


@pytest.mark.parametrize("shape, shift_axes", [((5,) * 6, (0, 1, 2)), ((5,) * 6, (1, 4)), ((4,) * 4, (0, 2)),
                                               ((3,) * 5, (2,)), ((4,) * 3, (0, 1, 2))])
def test_condition_runs_describe_the_condition_lines(shape, shift_axes):
    """Pass k's condition index of line r repeats with period ``runs[k, 0]`` and is constant over
    aligned runs of ``runs[k, 1]`` lines (the small-grid step builds its per-line weights from that)."""
    from cansim.backends._numba_small import condition_lines, condition_runs

    lines, runs = condition_lines(shape, shift_axes), condition_runs(shape, shift_axes)
    rest = int(np.prod(shape)) // shape[0]
    for k in shift_axes:
        period, run = (int(v) for v in runs[k])
        g = lines[k, :rest]
        assert rest % period == 0 and period % run == 0
        np.testing.assert_array_equal(g, np.tile(g[:period], rest // period))
        np.testing.assert_array_equal(g[:period], np.repeat(g[:period:run], run))
        assert len(np.unique(g[:period])) == int(np.prod([n for ax, n in enumerate(shape) if ax not in shift_axes]))


def test_small_grid_with_different_kernel_widths_per_axis():
    shape = (4, 4, 4)
    rng = np.random.default_rng(15)
    a = _packets(shape, [(3, 0, 2)], np.float64, half=1)
    kw = _small_kwargs(shape, rng, shift_axes=(0, 1), scale=0.8)
    kw["exc"] = [gaussian_kernel_1d(w, 1.0) for w in (5, 7, 9)]
    kw["inh"] = [gaussian_kernel_1d(w, 1.5) for w in (3, 5, 7)]
    _assert_small_path_exact(a, kw)


@settings(max_examples=60, deadline=None)
@given(mo=st.integers(1, 40), rest=st.integers(1, 120), nw=st.integers(1, 7), m_in=st.integers(1, 40),
       seed=st.integers(0, 2**31 - 1))
def test_short_line_pass_sums_every_tap_in_order(mo, rest, nw, m_in, seed):
    """The pass over short lines (blocks of rows, tap after tap) gives the bits of summing
    ``w[j] * src[tab[p, j]]`` for j = 0, 1, ... in float64 and writes the rotated layout;
    -1 entries (outside the box) and zero taps add nothing. Sizes above ``_BLOCK`` cells
    take several blocks."""
    from cansim.backends._numba_kernels import rot_short_lines

    rng = np.random.default_rng(seed)
    src = rng.random(m_in * rest) * (rng.random(m_in * rest) < 0.7)
    start = rng.integers(-3, m_in + 3, nw)  # consecutive sources (runs) that leave the box at the ends
    tab = (np.arange(mo)[:, None] + start[None, :]) % (m_in + 4) - 2
    tab[(tab < 0) | (tab >= m_in) | (rng.random((mo, nw)) < 0.1)] = -1
    w = rng.random(nw) * (rng.random(nw) < 0.8)
    want = np.zeros((mo, rest))
    rows = src.reshape(m_in, rest)
    for j in range(nw):
        ok = tab[:, j] >= 0
        want[ok] += w[j] * rows[tab[ok, j]]
    dst = np.full(rest * mo, np.nan)
    rot_short_lines(src, dst, np.int64(mo), np.int64(rest), tab.astype(np.int64), w)
    np.testing.assert_array_equal(dst.reshape(rest, mo), want.T)


@pytest.mark.parametrize("shape", [(32, 32), (13, 3), (11, 7, 12), (61, 61, 36)])
@pytest.mark.parametrize("window", [1, 3, 40])
def test_a_box_of_the_grid_decodes_and_bounds_like_the_grid(shape, window):
    """What lets a numba run keep the activity in its box between steps: any box holding
    every non-zero cell (across the wrap, or wider than the packet) decodes to the bits of
    the whole grid, with or without the tabulated sines, close to the numpy reference; and
    the box found from it equals the one found from the grid."""
    from cansim.backends import _numba_kernels as k

    n = np.array(shape, np.int64)
    a = _packets(shape, [tuple(x - 1 for x in shape), tuple(x // 3 for x in shape)], np.float32, half=1)
    grid = a.reshape(-1)
    s, m = np.zeros(len(shape), np.int64), n.copy()
    assert k.occupied_box(grid.view(np.uint32), np.zeros_like(n), n, n, np.empty(0, np.int64), s, m)
    want = np.empty(len(shape))
    k.decode_box(grid, np.zeros(len(shape), np.int64), n, n, k.unravel(int(np.argmax(grid)), n), window, want,
                 np.empty((0, 2, 1)))
    np.testing.assert_allclose(want, REF.decode(a, window), rtol=0, atol=1e-4)
    for grow in (0, 1, 5):
        bs = (s - grow) % n
        bm = np.minimum(m + 2 * grow, n)
        bs[bm == n] = 0
        buf = np.empty(int(np.prod(bm)))
        k.crop(grid.astype(np.float64), np.zeros(len(shape), np.int64), n, buf, bs, bm, n)
        centre = k.unravel(k.box_argmax(buf, bs, bm, n), n)
        for trig in (np.empty((0, 2, 1)), k.trig_table(n)):
            got = np.empty(len(shape))
            k.decode_box(buf, bs, bm, n, centre, window, got, trig)
            np.testing.assert_array_equal(got, want)
        ts, tm = np.empty_like(s), np.empty_like(m)
        assert k.occupied_box(buf.view(np.uint64), bs, bm, n, np.empty(0, np.int64), ts, tm)
        np.testing.assert_array_equal(ts, s)
        np.testing.assert_array_equal(tm, m)
