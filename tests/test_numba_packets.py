"""Several packets as fast as one (issue 26, item 2): one box per packet, the same bits.

The numba backend's fused step and run compute each far-apart packet on its own box
(:mod:`cansim.backends._numba_packets`). Here two and three packets, far apart, wrapping
round the periodic boundary, or close enough that their boxes merge, are stepped

- through the per-packet step and compared bit for bit with the one-box step round all
  of them (the kernel the backend used before, ``_numba_kernels.pipeline``),
- through every available backend and compared with the dense full-grid numpy reference
  (an independent computation: ``np.roll`` on the whole grid, its own summation order),
- through ``run`` and compared bit for bit with the one-box step called once per step,

and the packets are checked to have been kept apart (or merged) as their distance says.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("numba")

from cansim import InvalidInputError, available_backends  # noqa: E402
from cansim.backends import get_backend  # noqa: E402
from cansim.backends import _numba_kernels as _k  # noqa: E402
from cansim.backends import _numba_packets as _p  # noqa: E402
from cansim.backends.base import RunInputs  # noqa: E402
from cansim.backends.numba_backend import NumbaBackend, _pack  # noqa: E402
from cansim.backends.numpy_backend import NumpyBackend  # noqa: E402
from cansim.kernels import gaussian_kernel_1d  # noqa: E402

REF = NumpyBackend()
PACKETS = NumbaBackend()

#: (shape, packet centres, number of boxes the first step keeps apart)
LAYOUTS = {
    "two far apart, 61x61x36": ((61, 61, 36), [(10, 10, 5), (40, 45, 23)], 2),
    "three far apart, 61x61x36": ((61, 61, 36), [(5, 5, 5), (35, 40, 20), (20, 48, 5)], 3),
    "two wrapping the boundary": ((61, 61, 36), [(0, 60, 35), (30, 30, 17)], 2),
    "three, one on every corner wrap": ((50, 50, 36), [(0, 0, 0), (25, 25, 18), (49, 24, 0)], 3),
    "two close: one merged box": ((61, 61, 36), [(20, 20, 10), (25, 24, 12)], 1),
    "two far on theta only, 21x21x36": ((21, 21, 36), [(10, 10, 2), (10, 10, 20)], 2),
    "two on 21x21x36, apart on theta": ((21, 21, 36), [(3, 3, 3), (13, 13, 20)], 2),
    "4-D, two apart": ((24, 24, 10, 30), [(0, 0, 0, 0), (12, 12, 5, 15)], 2),
    "2-D, three apart": ((40, 40), [(0, 0), (20, 20), (0, 20)], 3),
}


def _packets(shape, centres, dtype, half=1, seed=0):
    """Blocks of +-half cells (wrapping) of random activity around each centre; sum 1."""
    rng = np.random.default_rng(seed)
    a = np.zeros(shape)
    for c in centres:
        idx = np.ix_(*[(np.arange(-half, half + 1) + ci) % n for ci, n in zip(c, shape)])
        a[idx] += rng.uniform(0.5, 1.0, size=(2 * half + 1,) * len(shape))
    return (a / a.sum()).astype(dtype)


def _step_kwargs(shape, rng, *, inject=True, scale=1.0):
    """OpenRatSLAM-like kernels (7 taps sigma 1, 5 taps sigma 2), conditional shifts on the leading axes."""
    d = len(shape)
    k = max(d - 1, 1) if d <= 3 else d // 2
    kw = dict(exc=[gaussian_kernel_1d(7, 1.0)] * d, inh=[gaussian_kernel_1d(5, 2.0)] * d, phi=2e-5, window=3,
              flat_index=None, values=None, shift_axes=None, cond_shifts=None, uniform_shifts=None)
    if inject:
        kw["flat_index"] = rng.integers(0, int(np.prod(shape)), 2).astype(np.int64)
        kw["values"] = rng.uniform(0.0, 0.2, 2)
    if d >= 2:
        kw["shift_axes"] = tuple(range(k))
        kw["cond_shifts"] = rng.uniform(-1.3, 1.3, shape[k:] + (k,)) * scale
    u = rng.uniform(-1.5, 1.5, d) * scale
    if d >= 2:
        u[:k] = 0.0
    kw["uniform_shifts"] = u
    return kw


def _one_box_step(a, kw):
    """The step on one box round every packet (the engine before issue 26 item 2)."""
    flat = np.ascontiguousarray(a).reshape(-1)
    out = np.empty_like(flat)
    n = np.array(a.shape, dtype=np.int64)
    exc, exc_w = _pack(kw["exc"])
    inh, inh_w = _pack(kw["inh"])
    fi = np.empty(0, np.int64) if kw["flat_index"] is None else np.asarray(kw["flat_index"], np.int64)
    vals = np.empty(0) if kw["values"] is None else np.asarray(kw["values"], np.float64)
    if kw["cond_shifts"] is not None:
        cmask = np.zeros(a.ndim, np.int64)
        cmask[list(kw["shift_axes"])] = 1
        ctab = np.ascontiguousarray(kw["cond_shifts"]).reshape(-1, len(kw["shift_axes"]))
    else:
        cmask, ctab = n, np.zeros((1, 1))
    uni = np.zeros(0) if kw["uniform_shifts"] is None else np.asarray(kw["uniform_shifts"], np.float64)
    dec = np.empty(a.ndim)
    bits = flat.view(np.uint32 if a.dtype == np.float32 else np.uint64)
    status = _k.pipeline(flat, bits, out, np.empty(3 * flat.size), n, fi, vals, True, exc, exc_w, inh, inh_w,
                         float(kw["phi"]), kw["cond_shifts"] is not None, cmask, ctab, uni.shape[0] > 0, uni,
                         True, int(kw["window"]), dec, False, 10**15, 1)
    if status != _k.STATUS_OK:
        return None, None
    return out.reshape(a.shape), dec


def _n_boxes(a, kw):
    """How many boxes the per-packet step plans for ``a`` (before injecting)."""
    d = a.ndim
    n = np.array(a.shape, dtype=np.int64)
    ew = np.array([len(t) for t in kw["exc"]], np.int64)
    iw = np.array([len(t) for t in kw["inh"]], np.int64)
    gap, spread = np.empty(d, np.int64), np.empty(d, np.int64)
    cmask = np.zeros(d, np.int64)
    ctab = np.zeros((1, 1))
    if kw["cond_shifts"] is not None:
        cmask[list(kw["shift_axes"])] = 1
        ctab = np.ascontiguousarray(kw["cond_shifts"]).reshape(-1, len(kw["shift_axes"]))
    uni = np.asarray(kw["uniform_shifts"], np.float64)
    _p.separations(ew, iw, n, kw["cond_shifts"] is not None, cmask, ctab, True, uni, gap, spread)
    flat = a.reshape(-1).astype(np.float64)
    cl_s = np.empty((_p.MAX_ITEMS, d), np.int64)
    cl_m = np.empty((_p.MAX_ITEMS, d), np.int64)
    occ = np.zeros((d, n.max()), np.uint8)
    return _p.plan_packets(flat.view(np.uint64), np.array([0, flat.size]), np.zeros((1, d), np.int64),
                           n.reshape(1, d), 1, n, np.empty(0, np.int64), gap, cl_s, cl_m, occ)


def _close(got, ref, dtype):
    tol = 1e-5 if np.dtype(dtype) == np.float32 else 1e-12
    np.testing.assert_allclose(got, ref, rtol=tol, atol=tol * float(np.max(ref)))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_per_packet_step_equals_one_box_step_bit_for_bit(layout, dtype):
    shape, centres, boxes = LAYOUTS[layout]
    a = _packets(shape, centres, dtype)
    kw = _step_kwargs(shape, np.random.default_rng(len(layout)))
    assert _n_boxes(a, kw) == boxes
    want_a, want_d = _one_box_step(a, kw)
    before = a.copy()
    got_a, got_d = PACKETS.step(a, **kw)
    np.testing.assert_array_equal(a, before)
    np.testing.assert_array_equal(got_a, want_a)
    np.testing.assert_array_equal(got_d, want_d)


@pytest.mark.parametrize("backend", available_backends())
@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_every_backend_matches_the_dense_reference_on_several_packets(layout, backend):
    shape, centres, _ = LAYOUTS[layout]
    a = _packets(shape, centres, np.float32, seed=3)
    kw = _step_kwargs(shape, np.random.default_rng(7))
    ref_a, ref_d = REF.step(a.astype(np.float64), **kw)  # the whole grid, in float64
    got_a, got_d = get_backend(backend).step(a, **kw)
    _close(got_a, ref_a, np.float32)
    # the decoded position of a packet sits between cells: compare it on the circle of each axis
    diff = (np.asarray(got_d) - ref_d + np.array(shape) / 2) % np.array(shape) - np.array(shape) / 2
    assert np.all(np.abs(diff) < 1e-4)


@pytest.mark.parametrize("layout", ["three far apart, 61x61x36", "two wrapping the boundary",
                                    "two close: one merged box", "2-D, three apart"])
def test_run_equals_one_box_steps_bit_for_bit(layout):
    """A run keeps the packets in their boxes between steps (and re-plans them each step);
    every step equals the one-box step on the previous step's grid."""
    shape, centres, _ = LAYOUTS[layout]
    a = _packets(shape, centres, np.float32, seed=5)
    rng = np.random.default_rng(11)
    T = 25
    steps = []
    for t in range(T):
        kw = _step_kwargs(shape, rng, inject=(t % 4 == 0))
        if t % 5 == 3:  # a step without motion
            kw["cond_shifts"] = kw["shift_axes"] = None
            kw["uniform_shifts"] = None
        steps.append(kw)
    off = np.zeros(T + 1, np.int64)
    idx, val = [], []
    for t, kw in enumerate(steps):
        n_inj = 0 if kw["flat_index"] is None else len(kw["flat_index"])
        if n_inj:
            idx.append(kw["flat_index"])
            val.append(kw["values"])
        off[t + 1] = off[t] + n_inj
    d = len(shape)
    axes = next(kw["shift_axes"] for kw in steps if kw["shift_axes"] is not None)
    has_cond = np.array([kw["cond_shifts"] is not None for kw in steps])
    proto = next(kw["cond_shifts"] for kw in steps if kw["cond_shifts"] is not None)
    cond = np.stack([kw["cond_shifts"] if kw["cond_shifts"] is not None else np.zeros_like(proto) for kw in steps])
    has_uni = np.array([kw["uniform_shifts"] is not None for kw in steps])
    uni = np.stack([kw["uniform_shifts"] if kw["uniform_shifts"] is not None else np.zeros(d) for kw in steps])
    inputs = RunInputs(T, off, np.concatenate(idx), np.concatenate(val), axes, cond, has_cond, uni, has_uni)
    res = PACKETS.run(a, inputs, exc=steps[0]["exc"], inh=steps[0]["inh"], phi=2e-5, window=3, record_activity=True)
    assert res.collapsed_at is None
    cur = a
    for t, kw in enumerate(steps):
        cur, dec = _one_box_step(cur, kw)
        np.testing.assert_array_equal(res.history[t], cur, err_msg=f"step {t}")
        np.testing.assert_array_equal(res.decoded[t], dec, err_msg=f"step {t}")
    np.testing.assert_array_equal(res.activity, cur)


def test_a_lone_injection_far_from_the_packet_is_a_packet_of_its_own():
    shape = (61, 61, 36)
    a = _packets(shape, [(10, 10, 10)], np.float32)
    kw = _step_kwargs(shape, np.random.default_rng(2), inject=False)
    kw["flat_index"] = np.array([np.ravel_multi_index((45, 40, 30), shape)], np.int64)
    kw["values"] = np.array([0.3])
    want_a, want_d = _one_box_step(a, kw)
    got_a, got_d = PACKETS.step(a, **kw)
    np.testing.assert_array_equal(got_a, want_a)
    np.testing.assert_array_equal(got_d, want_d)
    assert want_a[45, 40, 30] == 0.0 or np.count_nonzero(want_a[35:56, 30:51, 20:]) > 0  # the injection survived


def test_far_packets_cost_about_one_box_each():
    """Two packets far apart: the planned boxes are packet-sized, not the grid (the point of item 2)."""
    shape = (61, 61, 36)
    a = _packets(shape, [(5, 5, 5), (35, 40, 23)], np.float32)
    kw = _step_kwargs(shape, np.random.default_rng(0), inject=False)
    assert _n_boxes(a, kw) == 2
    one = _packets(shape, [(5, 5, 5)], np.float32)
    assert _n_boxes(one, kw) == 1


@settings(max_examples=30, deadline=None)
@given(
    shape=st.lists(st.integers(8, 60), min_size=2, max_size=4).filter(lambda s: int(np.prod(s)) <= 80_000).map(tuple),
    seed=st.integers(0, 2**31 - 1),
    n_packets=st.integers(1, 4),
    scale=st.sampled_from([0.3, 1.0, 3.0]),
    dtype=st.sampled_from([np.float32, np.float64]),
)
def test_random_packets_per_packet_step_equals_one_box_step(shape, seed, n_packets, scale, dtype):
    rng = np.random.default_rng(seed)
    centres = [tuple(int(rng.integers(n)) for n in shape) for _ in range(n_packets)]
    a = _packets(shape, centres, dtype, half=int(rng.integers(0, 3)), seed=seed)
    kw = _step_kwargs(shape, rng, scale=scale)
    want_a, want_d = _one_box_step(a, kw)
    got_a, got_d = PACKETS.step(a, **kw)
    if want_a is None:
        assert got_a is None
        return
    np.testing.assert_array_equal(got_a, want_a)
    np.testing.assert_array_equal(got_d, want_d)


# ------------------------------------------------------------ regions (where a grid can be non-zero)
def _region_mask(shape, starts, lengths):
    """Boolean grid: the cells of one box (per axis the arc ``start .. start + length - 1``, wrapping)."""
    mask = np.ones(shape, dtype=bool)
    for k, (n, s0, m0) in enumerate(zip(shape, starts, lengths)):
        on = np.zeros(n, dtype=bool)
        on[(s0 + np.arange(m0)) % n] = True
        mask &= on.reshape((1,) * k + (n,) + (1,) * (len(shape) - k - 1))
    return mask


def _list_mask(shape, boxes):
    """Boolean grid: the cells of a region list (shape (R, 2, d); boxes of no cells unused)."""
    mask = np.zeros(shape, dtype=bool)
    for b in boxes:
        if np.prod(b[1]) > 0:
            mask |= _region_mask(shape, b[0], b[1])
    return mask


def _random_list(shape, rng):
    """A region list of 1-3 random boxes (per axis a random arc, sometimes the whole axis)."""
    r = NumbaBackend.new_regions(shape)[0]
    r[0, 1] = 0
    for j in range(int(rng.integers(1, 4))):
        r[j, 0] = [int(rng.integers(n)) for n in shape]
        r[j, 1] = [n if rng.random() < 0.2 else int(rng.integers(1, n + 1)) for n in shape]
    return r


@settings(max_examples=40, deadline=None)
@given(
    shape=st.lists(st.integers(8, 50), min_size=2, max_size=4).filter(lambda s: int(np.prod(s)) <= 60_000).map(tuple),
    seed=st.integers(0, 2**31 - 1),
    n_packets=st.integers(1, 4),
    dtype=st.sampled_from([np.float32, np.float64]),
)
def test_a_step_told_where_the_grids_are_non_zero_gives_the_same_bits(shape, seed, n_packets, dtype):
    """``regions`` (boxes holding the input's and the output buffer's non-zero cells) spare
    the whole-grid passes; the result equals the one-box step's bit for bit, and the boxes
    reported hold every non-zero cell of it."""
    rng = np.random.default_rng(seed)
    centres = [tuple(int(rng.integers(n)) for n in shape) for _ in range(n_packets)]
    regions = NumbaBackend.new_regions(shape)
    regions[0] = _random_list(shape, rng)
    regions[1] = _random_list(shape, rng)
    a = _packets(shape, centres, dtype, half=int(rng.integers(0, 3)), seed=seed)
    a[~_list_mask(shape, regions[0])] = 0  # a is zero outside its boxes
    if not a.any():
        a[tuple(regions[0, 0, 0])] = 1
    kw = _step_kwargs(shape, rng, scale=float(rng.choice([0.3, 1.0])))
    out = np.zeros(shape, dtype=dtype)
    o_mask = _list_mask(shape, regions[1])
    out[o_mask] = rng.uniform(0.0, 1.0, int(o_mask.sum()))  # a previous grid's leftovers, inside its boxes
    want_a, want_d = _one_box_step(a, kw)
    got_a, got_d = NumbaBackend().step(a, out=out, regions=regions, **kw)
    if want_a is None:
        assert got_a is None
        return
    assert got_a is out
    np.testing.assert_array_equal(got_a, want_a)
    np.testing.assert_array_equal(got_d, want_d)
    assert not got_a[~_list_mask(shape, regions[2])].any()


@pytest.mark.parametrize("layout", ["three far apart, 61x61x36", "two on 21x21x36, apart on theta"])
def test_a_step_reads_only_the_region_it_is_told(layout):
    """The regions are used, not checked: a packet left outside the input's boxes is not
    stepped, and an output buffer's leftovers outside its boxes stay (so the equality above
    is a test of the region path, and a caller must give true regions); the result's
    boxes are one per packet."""
    shape, centres, n_boxes = LAYOUTS[layout]
    a = _packets(shape, centres, np.float64)
    kw = _step_kwargs(shape, np.random.default_rng(1), inject=False)
    regions = NumbaBackend.new_regions(shape)
    regions[0, 0] = [[(ci - 2) % n for ci, n in zip(centres[0], shape)], [5] * len(shape)]
    got, _ = NumbaBackend().step(a, regions=regions, **kw)
    regions = NumbaBackend.new_regions(shape)
    whole, _ = NumbaBackend().step(a, regions=regions, **kw)
    assert np.count_nonzero(np.prod(regions[2, :, 1], axis=1)) == n_boxes
    assert got.sum() == pytest.approx(1.0) and whole.sum() == pytest.approx(1.0)
    far = _region_mask(shape, [(ci - 8) % n for ci, n in zip(centres[1], shape)], [17] * 3)
    assert whole[far].sum() > 0.1 and not got[far].any()
    out = np.full(shape, 7.0)
    regions = NumbaBackend.new_regions(shape)
    regions[1, 0, 1] = 1
    got, _ = NumbaBackend().step(a, out=out, regions=regions, **kw)
    assert np.count_nonzero(got == 7.0) > 0.9 * got.size


@settings(max_examples=40, deadline=None)
@given(
    kind=st.sampled_from(["start", "length", "dtype", "shape", "list"]),
    value=st.integers(-5, 80),
    which=st.integers(0, 1),
    seed=st.integers(0, 2**31 - 1),
)
def test_bad_regions_raise_the_typed_error_and_touch_nothing(kind, value, which, seed):
    shape = (21, 21, 36)
    rng = np.random.default_rng(seed)
    a = _packets(shape, [(10, 10, 18)], np.float64)
    kw = _step_kwargs(shape, rng)
    regions = NumbaBackend.new_regions(shape)
    k = int(rng.integers(3))
    if kind == "start":
        if 0 <= value < shape[k]:
            value = -1 - value % 3
        regions[which, 0, 0, k] = value
    elif kind == "length":
        if 0 <= value <= shape[k]:
            value = shape[k] + 1 + value % 3
        regions[which, 0, 1, k] = value
    elif kind == "dtype":
        regions = regions.astype(np.float64)
    elif kind == "shape":
        regions = regions[:, : 1 + value % 7]
    else:
        regions = regions.tolist()
    out = np.full(shape, 3.0)
    before_a, before_out = a.copy(), out.copy()
    with pytest.raises(InvalidInputError, match="regions"):
        NumbaBackend().step(a, out=out, regions=regions, **kw)
    np.testing.assert_array_equal(a, before_a)
    np.testing.assert_array_equal(out, before_out)


@settings(max_examples=30, deadline=None)
@given(shape=st.lists(st.integers(1, 70), min_size=1, max_size=6).map(tuple), which=st.sampled_from([0, 1, 2]),
       seed=st.integers(0, 2**31 - 1))
def test_new_regions_are_the_whole_grid_and_forget_resets_only_its_list(shape, which, seed):
    r = NumbaBackend.new_regions(shape)
    assert r.shape == (3, _p.MAX_REGIONS, 2, len(shape)) and r.dtype == np.int64
    for i in range(3):  # box 0 the whole grid, every other box empty
        np.testing.assert_array_equal(r[i, 0, 0], 0)
        np.testing.assert_array_equal(r[i, 0, 1], shape)
        assert not np.prod(r[i, 1:, 1], axis=1).any()
    rng = np.random.default_rng(seed)
    r[:] = rng.integers(0, 5, r.shape)
    before = r.copy()
    NumbaBackend.forget_regions(r, which, shape)
    np.testing.assert_array_equal(r[which, 0, 0], 0)
    np.testing.assert_array_equal(r[which, 0, 1], shape)
    assert not r[which, 1:, 1].any()
    others = [i for i in range(3) if i != which]
    np.testing.assert_array_equal(r[others], before[others])
