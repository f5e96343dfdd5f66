"""The backend conformance suite, as a pytest plugin any backend can run against itself.

As Nengo does for its simulators: one set of tests compares a candidate backend's
kernels (dynamics, shifts, conditional shifts, injection, decoding, the fused step) with
the numpy reference on random grids, shapes, dtypes and seeds (hypothesis), and a whole
:class:`~cansim.population.Population` run step by step. The reference is never
compared with itself. A candidate's multi-step ``Backend.run`` must equal its own
``step`` called once per step, bit for bit.

Use it from a test module of your own::

    # test_my_backend.py
    from cansim.testing.conformance import *  # noqa: F401,F403  (collects the tests)

and run ``pytest test_my_backend.py --cansim-backend mybackend`` (a name
:func:`cansim.backends.get_backend` knows - a backend of your own once
:func:`cansim.backends.register_backend` has named it, e.g. in that ``conftest.py`` -
or several, comma-separated). Without the option the suite runs every available backend
except the reference (given as ``numpy``, the reference is compared with itself: a check
of the suite, not of a backend). The plugin's
options and fixtures come from :mod:`cansim.testing.plugin` (``-p cansim.testing.plugin``,
or ``pytest_plugins = ["cansim.testing.plugin"]`` in a ``conftest.py``).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cansim.kernels import gaussian_kernel_1d

__all__ = [name for name in (
    "test_dynamics_matches_reference", "test_uniform_shift_matches_reference", "test_conditional_shift_matches_reference",
    "test_inject_matches_reference", "test_decode_matches_reference", "test_fused_step_matches_reference",
    "test_backend_population_runs_identically", "test_run_equals_repeated_steps",
    "test_spiking_population_spikes_identically",
)]

SETTINGS = dict(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
NONCUBIC = [(7, 11, 13), (5, 6, 7, 8), (3, 4, 5, 6, 7, 5)]


def _close(got, ref, dtype):
    ref = np.asarray(ref, dtype=np.float64)
    got = np.asarray(got, dtype=np.float64)
    assert got.shape == ref.shape
    tol = 1e-5 if np.dtype(dtype) == np.float32 else 1e-10
    scale = max(float(np.abs(ref).max()), 1e-30)
    np.testing.assert_allclose(got, ref, rtol=tol, atol=tol * scale)


@st.composite
def grids(draw, max_cells=6000, min_ndim=1):
    shape = draw(
        st.one_of(
            st.sampled_from(NONCUBIC),
            st.lists(st.integers(1, 12), min_size=min_ndim, max_size=6).filter(lambda s: int(np.prod(s)) <= max_cells).map(tuple),
        )
    )
    dtype = draw(st.sampled_from([np.float32, np.float64]))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["dense", "packet", "two_packets"]))
    a = rng.random(shape)
    if kind != "dense":
        mask = np.zeros(shape, dtype=bool)
        for _ in range(1 if kind == "packet" else 2):
            centre = [rng.integers(n) for n in shape]
            idx = np.ix_(*[(np.arange(-1, 2) + c) % n for c, n in zip(centre, shape)])
            mask[idx] = True
        a = np.where(mask, a, 0.0)
    a = a / a.sum()
    return a.astype(dtype), rng


def _kernels(rng, ndim):
    exc = [gaussian_kernel_1d(int(rng.choice([1, 3, 5, 7, 9])), float(rng.uniform(0.5, 2.5))) for _ in range(ndim)]
    inh = [gaussian_kernel_1d(int(rng.choice([1, 3, 5, 7])), float(rng.uniform(0.8, 3.0))) for _ in range(ndim)]
    return exc, inh


@settings(**SETTINGS)
@given(data=grids())
def test_dynamics_matches_reference(candidate, reference, data):
    a, rng = data
    exc, inh = _kernels(rng, a.ndim)
    phi = float(rng.choice([0.0, 2e-5, 1e-3]))
    before = a.copy()
    ref = reference.dynamics(a, exc, inh, phi)
    got = candidate.dynamics(a, exc, inh, phi)
    np.testing.assert_array_equal(a, before)  # input untouched
    if ref is None:
        assert got is None
    else:
        assert got is not None and got.dtype == a.dtype
        _close(got, ref, a.dtype)


@settings(**SETTINGS)
@given(data=grids(), scale=st.sampled_from([0.3, 1.0, 3.7]))
def test_uniform_shift_matches_reference(candidate, reference, data, scale):
    a, rng = data
    shifts = rng.uniform(-1, 1, a.ndim) * scale
    _close(candidate.shift(a, shifts), reference.shift(a, shifts), a.dtype)


@settings(**SETTINGS)
@given(data=grids(min_ndim=2), scale=st.sampled_from([0.4, 1.0, 2.6]))
def test_conditional_shift_matches_reference(candidate, reference, data, scale):
    a, rng = data
    k = int(rng.integers(1, a.ndim))
    shift_axes = tuple(sorted(rng.choice(a.ndim, size=k, replace=False).tolist()))
    cond_shape = tuple(n for i, n in enumerate(a.shape) if i not in shift_axes)
    shifts = rng.uniform(-1, 1, cond_shape + (k,)) * scale
    _close(
        candidate.shift_conditional(a, shift_axes, shifts),
        reference.shift_conditional(a, shift_axes, shifts),
        a.dtype,
    )


@settings(**SETTINGS)
@given(data=grids())
def test_inject_matches_reference(candidate, reference, data):
    a, rng = data
    n = int(rng.integers(1, 6))
    flat = rng.integers(0, a.size, n).astype(np.int64)
    flat[-1] = flat[0]  # repeated indices add up
    vals = rng.uniform(0, 0.5, n)
    _close(candidate.inject(a, flat, vals), reference.inject(a, flat, vals), a.dtype)


@settings(**SETTINGS)
@given(data=grids(), window=st.integers(0, 4))
def test_decode_matches_reference(candidate, reference, data, window):
    a, _ = data
    np.testing.assert_allclose(candidate.decode(a, window), reference.decode(a, window), rtol=1e-6, atol=1e-6 * max(a.shape))


@settings(**SETTINGS)
@given(data=grids())
@example(data=(np.eye(1, 21 * 21 * 36, 10 * 21 * 36 + 10 * 36 + 18).reshape(21, 21, 36), np.random.default_rng(0)))
def test_fused_step_matches_reference(candidate, reference, data):
    a, rng = data
    exc, inh = _kernels(rng, a.ndim)
    flat = rng.integers(0, a.size, 2).astype(np.int64)
    vals = rng.uniform(0, 0.2, 2)
    uniform = rng.uniform(-2, 2, a.ndim)
    shift_axes = cond = None
    if a.ndim >= 2:
        shift_axes = tuple(range(a.ndim - 1))
        cond = rng.uniform(-1.5, 1.5, (a.shape[-1], a.ndim - 1))
    kw = dict(flat_index=flat, values=vals, exc=exc, inh=inh, phi=2e-5, shift_axes=shift_axes,
              cond_shifts=cond, uniform_shifts=uniform, window=3)
    ref_a, ref_d = reference.step(a, **kw)
    got_a, got_d = candidate.step(a, **kw)
    assert (got_a is None) == (ref_a is None)  # both report a collapse, or neither
    if ref_a is not None:
        _close(got_a, ref_a, a.dtype)
        np.testing.assert_allclose(got_d, ref_d, rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("shape", NONCUBIC)
def test_backend_population_runs_identically(candidate, reference, shape):
    """A full Population run with motion agrees with the reference run step by step."""
    from cansim import Axis, AttractorParams, Population

    axes = [Axis.linear(f"a{i}", n, 0.1) for i, n in enumerate(shape)]
    params = AttractorParams(exc_width=5, exc_sigma=1.0, inh_width=3, inh_sigma=1.5)
    ref = Population(axes, params, backend=reference)
    got = Population(axes, params, backend=candidate)
    rng = np.random.default_rng(len(shape))
    for _ in range(15):
        vel = rng.uniform(-0.3, 0.3, len(shape))  # m/s at 0.1 m/cell: up to 3 cells/step
        got.activity = ref.activity  # compare one step at a time (float32 rounding differs)
        dr = ref.step(vel, dt=1.0)
        dg = got.step(vel, dt=1.0)
        _close(got.activity, ref.activity, np.float32)
        np.testing.assert_allclose(dg, dr, atol=1e-3)


@pytest.mark.parametrize("shape", [(47,), (9, 7, 12), (3, 4, 5, 6, 7, 5)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_run_equals_repeated_steps(candidate, shape, dtype):
    """``Population.run`` (the candidate's ``Backend.run``) equals T calls of its ``step`` bit for bit,
    with per-step shifts of up to 2.5 cells, per-step dt and injections (a repeated index among them)."""
    from cansim import Axis, AttractorParams, Population

    axes = [Axis.linear(f"a{i}", n, 0.1) for i, n in enumerate(shape)]
    params = AttractorParams(exc_width=5, exc_sigma=1.0, inh_width=3, inh_sigma=1.5)
    pops = [Population(axes, params, backend=candidate, dtype=dtype) for _ in range(2)]
    pops[0].reset_gaussian([n / 3 for n in shape], 1.0)
    pops[1].activity = pops[0].activity
    rng = np.random.default_rng(sum(shape))
    T = 10
    velocity = rng.uniform(-0.25, 0.25, (T, len(shape)))
    velocity[3] = 0.0
    dt = rng.uniform(0.5, 1.0, T)
    size = int(np.prod(shape))
    injections = [None] * T
    injections[1] = (np.array([0, 0, size - 1]), np.array([0.05, 0.1, 0.2]))
    injections[7] = (np.array([size // 2]), np.array([0.4]))
    decoded, activity = pops[0].run(velocity, dt=dt, injections=injections, record_activity=True)
    for t in range(T):
        d = pops[1].step(velocity[t], dt=float(dt[t]), injection=injections[t])
        np.testing.assert_array_equal(activity[t], pops[1].activity)
        np.testing.assert_array_equal(decoded[t], d)
    np.testing.assert_array_equal(pops[0].activity, pops[1].activity)


@pytest.mark.parametrize("shape", [(36,), (7, 6), (5, 4, 3)])
def test_spiking_population_spikes_identically(candidate, reference, shape):
    """A spiking population (LIF, seeded noise, path integration) emits the reference's spikes, step for step."""
    from cansim.axes import Axis
    from cansim.spiking import SPIKING_BACKENDS, NeuronParams, SpikingParams, SpikingPopulation

    if candidate.name not in SPIKING_BACKENDS:  # the backends with a spiking implementation (one list, cansim.spiking)
        pytest.skip(f"backend {candidate.name!r} has no spiking implementation")
    axes = tuple(Axis.angle(f"a{i}", n) for i, n in enumerate(shape))
    params = SpikingParams(neurons=NeuronParams(noise_sigma=0.3, bias_current=1.05), recurrent_weight=60.0, global_weight=0.5)
    ref = SpikingPopulation(axes, params, seed=7, backend=reference.name)
    got = SpikingPopulation(axes, params, seed=7, backend=candidate.name)
    drive = np.random.default_rng(len(shape))
    for k in range(120):
        vel = drive.normal(0.0, 20.0, len(shape)) if k % 3 else None
        cur = drive.normal(0.2, 0.4, shape) if k % 5 == 0 else None
        np.testing.assert_array_equal(got.step(vel, cur), ref.step(vel, cur))
    np.testing.assert_array_equal(got.v, ref.v)
