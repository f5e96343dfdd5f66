"""Population.run: T iterations in one backend call equal T calls of step, bit for bit.

The oracle of every test here is the population's own ``step`` called T times on a twin
population (the path every other test of the library checks against the numpy
reference), never ``run`` itself.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cansim import AttractorParams, Axis, Population
from cansim.errors import InvalidInputError, ShapeError, ZeroActivityError
from cansim.path_integration import UniformMotion

SETTINGS = dict(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _make(kind: str, backend, dtype=np.float32) -> Population:
    if kind == "ring":
        return Population.head_direction(120, backend=backend, dtype=dtype)
    if kind == "sheet":
        return Population([Axis.linear("x", 16, 1.0), Axis.linear("y", 12, 1.0)], backend=backend, dtype=dtype)
    if kind == "ratslam":
        return Population.openratslam(15, 12, backend=backend, dtype=dtype)
    if kind == "6d":  # 5^6: the numba backend's small-grid kernel
        return Population.whisker6d(5, backend=backend, dtype=dtype)
    if kind == "6d-noncubic":  # the generic N-D pipeline
        return Population.whisker6d(6, angle_cells=5, backend=backend, dtype=dtype)
    raise AssertionError(kind)


def _inputs(kind: str, pop: Population, T: int, seed: int):
    rng = np.random.default_rng(seed)
    omega = None
    if kind == "ring":
        velocity = rng.uniform(-0.2, 0.2, T)  # rad/s: up to ~4 cells per step
        velocity[1] = 0.0
    elif kind == "sheet":
        velocity = rng.uniform(-2.5, 2.5, (T, 2))  # cells per second, both axes
    elif kind == "ratslam":
        velocity = rng.uniform(0.0, 1.5, T)  # m/s at 1 m/cell
        velocity[2] = 0.0  # a step without translation: no conditional shift
        omega = rng.uniform(-0.4, 0.4, T)
        omega[3] = 0.0
    else:
        velocity = rng.uniform(-0.03, 0.03, (T, 3))  # m/s at 0.02 m/cell
        omega = rng.uniform(-1.0, 1.0, (T, 3))
        omega[4] = 0.0
    dt = rng.uniform(0.5, 1.5, T)
    injections = [None] * T
    injections[2] = (np.array([3, 3, pop.size - 1]), np.array([0.1, 0.05, 0.2]))  # a repeated index adds up
    injections[5] = (np.array([pop.size // 2]), np.array([0.3]))
    injections[6] = (np.array([], dtype=np.int64), np.array([]))  # empty: no injection
    return velocity, omega, dt, injections


def _stepped(pop: Population, velocity, omega, dt, injections):
    decoded, activity = [], []
    for t in range(len(dt)):
        decoded.append(pop.step(velocity[t], None if omega is None else omega[t], float(dt[t]),
                                injection=injections[t]))
        activity.append(pop.activity)
    return np.array(decoded), np.array(activity)


@pytest.mark.parametrize("kind", ["ring", "sheet", "ratslam", "6d", "6d-noncubic"])
def test_run_equals_repeated_steps_bit_for_bit(backend, kind):
    """1-D, 2-D, 3-D and 6-D with per-step dt, moving and still steps, and injections."""
    T = 12
    a, b = _make(kind, backend), _make(kind, backend)
    a.reset_gaussian([n / 2 - 0.3 for n in a.shape], 1.2)
    b.activity = a.activity
    velocity, omega, dt, injections = _inputs(kind, a, T, seed=len(kind))
    decoded, activity = a.run(velocity, omega, dt, injections, record_activity=True)
    want_decoded, want_activity = _stepped(b, velocity, omega, dt, injections)
    assert decoded.shape == (T, a.ndim) and activity.shape == (T,) + a.shape and activity.dtype == a.dtype
    np.testing.assert_array_equal(activity, want_activity)
    np.testing.assert_array_equal(decoded, want_decoded)
    np.testing.assert_array_equal(a.activity, b.activity)
    np.testing.assert_array_equal(a.decode(), b.decode())


@pytest.mark.parametrize("kind", ["ring", "ratslam"])
def test_float64_run_equals_repeated_steps(backend, kind):
    T = 8
    a, b = _make(kind, backend, np.float64), _make(kind, backend, np.float64)
    b.activity = a.activity
    velocity, omega, dt, injections = _inputs(kind, a, T, seed=3)
    decoded = a.run(velocity, omega, dt, injections)
    np.testing.assert_array_equal(decoded, _stepped(b, velocity, omega, dt, injections)[0])
    np.testing.assert_array_equal(a.activity, b.activity)


def test_pure_dynamics_needs_n_steps(backend):
    a, b = _make("sheet", backend), _make("sheet", backend)
    a.reset_cell([3, 4])
    b.reset_cell([3, 4])
    decoded = a.run(n_steps=5)
    for t in range(5):
        np.testing.assert_array_equal(decoded[t], b.step())
    np.testing.assert_array_equal(a.activity, b.activity)
    with pytest.raises(InvalidInputError, match="n_steps"):
        a.run()


def test_a_motion_model_without_batch_form_is_called_per_step(backend):
    """A user's motion model (here a subclass) goes through its own per-step function."""

    class Doubled(UniformMotion):
        def bind(self, axes):
            inner = super().bind(axes)

            def shifts(velocity, omega, dt):
                return inner(None if velocity is None else 2.0 * np.asarray(velocity), omega, dt)

            return shifts

    axes = [Axis.linear("x", 20, 1.0), Axis.linear("y", 9, 1.0)]
    a, b = (Population(axes, motion=Doubled(), backend=backend) for _ in range(2))
    velocity = np.column_stack([np.full(6, 0.5), np.random.default_rng(1).uniform(-0.3, 0.3, 6)])
    decoded = a.run(velocity)
    np.testing.assert_array_equal(decoded, [b.step(v) for v in velocity])
    assert abs(decoded[-1][0] - (10 + 2 * 0.5 * 6)) < 1.0  # the doubling took effect (undoubled: 13)


def test_collapse_mid_run_leaves_the_state_as_before(backend):
    """phi 0.16 on a 60-cell ring: a single cell survives step 0 and collapses later."""
    pop, twin = (Population.head_direction(60, params=AttractorParams(global_inhibition=0.16), backend=backend)
                 for _ in range(2))
    failed = None
    for t in range(6):  # where T calls of step collapse
        try:
            twin.step(0.3)
        except ZeroActivityError:
            failed = t
            break
    assert failed is not None and failed >= 1
    before, pos = pop.activity, pop.decode()
    with pytest.raises(ZeroActivityError, match=f"step {failed} of the run"):
        pop.run(np.full(6, 0.3))
    np.testing.assert_array_equal(pop.activity, before)
    np.testing.assert_array_equal(pop.decode(), pos)


def test_opencl_windowed_step_equals_whole_grid_step_bit_for_bit():
    """What lets the opencl run compute whole grids: a step on the window the packet can
    reach gives the same bits as the whole-grid step (the total is summed per grid row)."""
    ob = pytest.importorskip("cansim.backends.opencl_backend")
    from cansim.errors import BackendUnavailableError
    from cansim.kernels import gaussian_kernel_1d

    try:
        local, whole = ob.OpenCLBackend(), ob.OpenCLBackend(locality=False)
        local.prepare(np.float64)
    except BackendUnavailableError as exc:
        pytest.skip(str(exc))
    shape = (41, 37, 36)
    rng = np.random.default_rng(5)
    for dtype in (np.float32, np.float64):
        a = np.zeros(shape)
        a[np.ix_([39, 40, 0, 1], [35, 36, 0], [34, 35, 0])] = rng.uniform(0.1, 1.0, (4, 3, 3))  # across every wrap
        a = (a / a.sum()).astype(dtype)
        kw = dict(flat_index=np.array([np.ravel_multi_index((2, 1, 1), shape)] * 2), values=np.array([0.05, 0.01]),
                  exc=[gaussian_kernel_1d(7, 1.0)] * 3, inh=[gaussian_kernel_1d(5, 2.0)] * 3, phi=2e-5,
                  shift_axes=(0, 1), cond_shifts=rng.uniform(-2.5, 2.5, (36, 2)),
                  uniform_shifts=np.array([0.0, 0.0, -1.3]), window=3)
        assert ob._locality_window(a, kw["flat_index"], kw["exc"], kw["inh"], (0, 1), kw["cond_shifts"],
                                   kw["uniform_shifts"]) is not None  # the windowed path is taken
        got, pos = local.step(a, **kw)
        want, want_pos = whole.step(a, **kw)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(pos, want_pos)


@settings(**SETTINGS)
@given(
    shape=st.sampled_from([(32, 32), (9, 40), (13, 3), (11, 7, 12), (6, 9, 5, 4)]),
    start=st.sampled_from(["packet", "two packets", "broad"]),
    locality=st.booleans(),
    dtype=st.sampled_from([np.float32, np.float64]),
    seed=st.integers(0, 2**31 - 1),
)
def test_numba_run_keeps_the_box_between_steps_and_still_equals_steps(shape, start, locality, dtype, seed):
    """The numba run keeps the activity in its box from step to step (it never writes the
    grid in between); its result equals T calls of ``step`` bit for bit when the packet
    crosses the wrap of every axis, when two packets make the box span an axis, when a
    broad start narrows, and when injections land far from the packet (the box grows to
    hold them); on the locality and the dense path."""
    pytest.importorskip("numba")
    from cansim.backends.numba_backend import NumbaBackend

    rng = np.random.default_rng(seed)
    axes = [Axis.linear(f"a{i}", n, 1.0) for i, n in enumerate(shape)]
    a, b = (Population(axes, backend=NumbaBackend(locality=locality), dtype=dtype) for _ in range(2))
    if start == "broad":
        a.activity = rng.random(shape)
    else:
        for k in range(1 if start == "packet" else 2):
            a.inject_flat(np.array([rng.integers(a.size)]), np.array([1.0]))
        a.activity = a.activity + (rng.random(shape) < 0.02) * rng.random(shape) * 0.1
    b.activity = a.activity
    T = 25
    velocity = rng.uniform(-3.0, 3.0, (T, len(shape)))  # crosses every wrap within a few steps
    velocity[rng.integers(T)] = 0.0
    injections = [None] * T
    for t in rng.choice(T, 5, replace=False):
        cells = rng.integers(0, a.size, rng.integers(1, 4))
        injections[t] = (cells, np.full(len(cells), 0.3))
    decoded, activity = a.run(velocity, injections=injections, record_activity=True)
    want_decoded, want_activity = _stepped(b, velocity, None, np.ones(T), injections)
    np.testing.assert_array_equal(activity, want_activity)
    np.testing.assert_array_equal(decoded, want_decoded)
    np.testing.assert_array_equal(a.activity, b.activity)


def test_collapse_mid_run_on_a_sheet_names_the_step_of_repeated_steps(backend):
    """The generic N-D run stops at the collapse where repeated steps do, and keeps nothing of the run."""
    params = AttractorParams(global_inhibition=0.09)  # a single cell survives step 0, its shifted packet does not
    axes = [Axis.linear("x", 14, 1.0), Axis.linear("y", 10, 1.0)]
    pop, twin = (Population(axes, params, backend=backend) for _ in range(2))
    velocity = np.tile([0.4, -0.3], (8, 1))
    failed = None
    for t in range(8):
        try:
            twin.step(velocity[t])
        except ZeroActivityError:
            failed = t
            break
    assert failed is not None and failed >= 1
    before = pop.activity
    with pytest.raises(ZeroActivityError, match=f"step {failed} of the run"):
        pop.run(velocity)
    np.testing.assert_array_equal(pop.activity, before)


# ------------------------------------------------------------------ bad input
BAD_VELOCITY = st.sampled_from(["nan", "inf", "short", "3d", "text", "huge"])


@settings(**SETTINGS)
@given(bad=BAD_VELOCITY, at=st.integers(0, 7))
def test_bad_velocity_raises_typed_error_and_changes_nothing(backend, bad, at):
    pop = _make("ratslam", backend)
    pop.reset_gaussian([7.2, 7.0, 5.5], 1.0)
    before, pos = pop.activity, pop.decode()
    v = np.full(8, 0.3)
    w = np.full(8, 0.1)
    if bad == "nan":
        v[at] = np.nan
    elif bad == "inf":
        w[at] = -np.inf
    elif bad == "huge":
        v[at] = 1e300
    elif bad == "short":
        w = w[: at % 7]
    elif bad == "3d":
        v = np.ones((8, 2, 2))
    with pytest.raises((InvalidInputError, ShapeError)) as err:
        pop.run("fast" if bad == "text" else v, w)
    assert err.value.args[0]  # a message that says what is wrong
    np.testing.assert_array_equal(pop.activity, before)
    np.testing.assert_array_equal(pop.decode(), pos)


@settings(**SETTINGS)
@given(
    bad=st.sampled_from(["negative dt", "nan dt", "2d dt", "dt length", "index", "negative energy", "nan energy",
                         "pair", "length", "n_steps", "zero steps", "omega on a ring", "vector for a grid"]),
    at=st.integers(0, 4),
)
def test_bad_dt_injection_and_lengths_raise_typed_errors(backend, bad, at):
    ring = bad in ("omega on a ring",)
    pop = Population.head_direction(36, backend=backend) if ring else _make("sheet", backend)
    before = pop.activity
    T = 5
    v = np.zeros(T) if ring else np.zeros((T, 2))
    kw: dict = dict(velocity=v)
    inj = [None] * T
    if bad == "negative dt":
        dt = np.ones(T)
        dt[at] = -0.1
        kw["dt"] = dt
    elif bad == "nan dt":
        kw["dt"] = np.where(np.arange(T) == at, np.nan, 1.0)
    elif bad == "2d dt":
        kw["dt"] = np.ones((T, 1))
    elif bad == "dt length":
        kw["dt"] = np.ones(T + 1 + at)
    elif bad == "index":
        inj[at] = (np.array([pop.size + at]), np.array([0.1]))
    elif bad == "negative energy":
        inj[at] = (np.array([0, 1]), np.array([0.1, -1e-3]))
    elif bad == "nan energy":
        inj[at] = (np.array([0]), np.array([np.nan]))
    elif bad == "pair":
        inj[at] = (np.array([0]),)
    elif bad == "length":
        inj = inj[:at]
    elif bad == "n_steps":
        kw["n_steps"] = T + 1 + at
    elif bad == "zero steps":
        kw = dict(n_steps=0)
    elif bad == "omega on a ring":
        kw["omega"] = np.ones(T)
    elif bad == "vector for a grid":
        kw["velocity"] = np.zeros(T)  # the sheet needs (T, 2)
    if bad not in ("zero steps",):
        kw["injections"] = inj
    with pytest.raises((InvalidInputError, ShapeError)):
        pop.run(**kw)
    np.testing.assert_array_equal(pop.activity, before)
