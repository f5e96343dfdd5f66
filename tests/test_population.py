"""Behaviour of the CAN engine: thesis worked examples, invariants, attractor, path integration."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim import AttractorParams, Axis, InvalidInputError, Population
from cansim.backends.numpy_backend import dense_periodic_convolve, separable_periodic_convolve
from cansim.decoding import circular_mean_index, population_vector_window
from cansim.kernels import SeparableKernel
from cansim.path_integration import euler_grid_rotations, split_weights


# ----------------------------------------------------------------- worked examples
def test_fig_5_12_population_vector():
    # 5 head-direction cells at 72, 144, 216, 288, 360 deg; index 0 is 360 = 0 deg.
    profile = np.zeros(5)
    profile[0], profile[4], profile[3] = 1.0, 3.1, 0.8
    assert circular_mean_index(profile) * 72.0 == pytest.approx(290.978, abs=1e-3)


def test_fig_5_12_through_the_population(backend):
    ring = Population.head_direction(5, backend=backend)
    act = np.zeros(5)
    act[[0, 4, 3]] = [1.0, 3.1, 0.8]
    ring.activity = act
    assert math.degrees(ring.decode_physical()[0]) == pytest.approx(290.978, abs=1e-3)


def test_fig_5_11_split_158_deg_at_72_deg_per_cell():
    lo, w_lo, w_hi = split_weights(158.0 / 72.0)
    assert lo == 2
    assert w_lo == pytest.approx(1 - (158.0 / 72.0 - 2))
    assert (round(w_lo, 1), round(w_hi, 1)) == (0.8, 0.2)


def test_fig_5_11_yaw_layer_shift(backend):
    """A fully active first yaw layer rotated by 158 deg/s for 1 s lands 0.8/0.2 on layers 2 and 3."""
    pop = Population.whisker6d(backend=backend, dtype=np.float64)
    a = np.zeros(pop.shape)
    a[..., 0] = 1.0 / a[..., 0].size
    pop.activity = a
    pop.integrate(omega=[0.0, 0.0, math.radians(158.0)], dt=1.0)
    per_layer = pop.activity.sum(axis=(0, 1, 2, 3, 4))
    frac = 158.0 / 72.0 - 2
    np.testing.assert_allclose(per_layer, [0, 0, 1 - frac, frac, 0], atol=1e-12)


# ------------------------------------------------------------------- invariants
@pytest.mark.parametrize("shape", [(9,), (7, 11, 13), (5, 6, 7, 8)])
def test_shift_conserves_activity_and_whole_periods_are_identity(backend, shape):
    rng = np.random.default_rng(1)
    axes = [Axis.linear(f"a{i}", n, 1.0) for i, n in enumerate(shape)]
    pop = Population(axes, backend=backend, dtype=np.float64)
    pop.activity = rng.random(shape)
    total = pop.total
    start = pop.activity
    pop.shift(rng.uniform(-3, 3, len(shape)))
    assert pop.total == pytest.approx(total, rel=1e-12)
    pop.activity = start
    pop.shift([2 * n for n in shape])
    np.testing.assert_allclose(pop.activity, start, atol=1e-15)
    pop.shift([-n for n in shape])
    np.testing.assert_allclose(pop.activity, start, atol=1e-15)


def test_conditional_shift_conserves_activity(backend):
    rng = np.random.default_rng(2)
    pop = Population.openratslam(xy_cells=11, heading_cells=8, backend=backend, dtype=np.float64)
    pop.activity = rng.random(pop.shape)
    total = pop.total
    pop.shift_conditional((0, 1), rng.uniform(-2.5, 2.5, (8, 2)))
    assert pop.total == pytest.approx(total, rel=1e-12)


@pytest.mark.parametrize("shape,widths", [((9, 8, 7), (3, 5, 7)), ((6, 5, 4, 5), (5, 3, 3, 5)), ((4, 5), (7, 9))])
def test_separable_kernel_equals_dense_convolution(shape, widths):
    rng = np.random.default_rng(3)
    a = rng.random(shape)
    k = SeparableKernel.gaussian(widths, [1.0 + 0.3 * i for i in range(len(shape))])
    np.testing.assert_allclose(separable_periodic_convolve(a, k.taps), dense_periodic_convolve(a, k.dense()), rtol=1e-12)


def test_shift_is_the_product_of_1d_splits():
    """Bilinear split in 2-D equals the four areas of Fig 5.7-5.10 (stay, N, W, NW products)."""
    pop = Population([Axis.linear("x", 6, 1.0), Axis.linear("y", 6, 1.0)], dtype=np.float64)
    a = np.zeros((6, 6))
    a[2, 2] = 1.0
    pop.activity = a
    pop.shift([-0.5 * 0.6, 1.0 * 0.6])  # v = 0.6 * [-0.5, 1] (quadrant 2)
    got = pop.activity
    fx, fy = 0.3, 0.6  # move 0.3 toward -x, 0.6 toward +y
    expect = np.zeros((6, 6))
    expect[2, 2] = (1 - fx) * (1 - fy)
    expect[1, 2] = fx * (1 - fy)
    expect[2, 3] = (1 - fx) * fy
    expect[1, 3] = fx * fy
    np.testing.assert_allclose(got, expect, atol=1e-15)


def test_window_is_clipped_so_no_cell_counts_twice():
    a = np.zeros((5, 5))
    a[1, 3] = 1.0
    a[2, 3] = 1.0
    # +-3 window on a 5-cell axis covers the axis once: mean of indices 1 and 2 is 1.5
    d = population_vector_window(a, 3)
    assert d[0] == pytest.approx(1.5, abs=1e-12)
    assert d[1] == pytest.approx(3.0, abs=1e-12)


# ------------------------------------------------------------------ attractor
@pytest.mark.slow  # 2,000 steps per backend and preset (fast loop <= 4 min)
@pytest.mark.parametrize("preset", ["openratslam", "whisker6d"])
def test_single_packet_is_stable_for_2000_steps(backend, preset):
    pop = getattr(Population, preset)(backend=backend)
    centre = np.array(pop.shape) // 2
    for _ in range(10):
        pop.step()
    d0 = pop.decode()
    for _ in range(2000):
        d = pop.step()
    a = pop.activity
    assert np.all(np.isfinite(a))
    assert pop.total == pytest.approx(1.0, abs=1e-5)
    np.testing.assert_allclose(d, d0, atol=0.05)
    np.testing.assert_allclose(d, centre, atol=0.05)
    # one packet: the non-zero cells form one connected blob around the centre
    from scipy import ndimage

    _, n_blobs = ndimage.label(a > 0)
    assert n_blobs == 1


def test_head_direction_ring_holds_a_packet(backend):
    ring = Population.head_direction(360, backend=backend)
    ring.reset_cell([90])
    for _ in range(500):
        d = ring.step()
    assert d[0] == pytest.approx(90.0, abs=0.05)


# ------------------------------------------------------------ path integration
def _tracked(pop, n_steps, axis, **kw):
    n = pop.shape[axis]
    xs = [pop.decode()[axis]]
    for _ in range(n_steps):
        pop.integrate(**kw)
        xs.append(pop.decode()[axis])
    return np.unwrap(np.array(xs) * 2 * np.pi / n) * n / (2 * np.pi)


@pytest.mark.parametrize("heading_deg", [0, 45, 90, 135])
def test_planar_translation_moves_30_cells_in_100_steps(backend, heading_deg):
    # 72 theta layers (5 deg each) so every tested heading is a layer of the grid
    def fresh():
        pop = Population.openratslam(heading_cells=72, cell_size_m=0.1, backend=backend, dtype=np.float64)
        pop.reset_cell([10, 10, heading_deg // 5])
        return pop

    xs = _tracked(fresh(), 100, 0, velocity=0.03, dt=1.0)  # 0.3 cells per step
    ys = _tracked(fresh(), 100, 1, velocity=0.03, dt=1.0)
    th = math.radians(heading_deg)
    assert xs[-1] - xs[0] == pytest.approx(30 * math.cos(th), abs=0.5)
    assert ys[-1] - ys[0] == pytest.approx(30 * math.sin(th), abs=0.5)


def test_planar_rotation_moves_20_cells_in_100_steps(backend):
    pop = Population.openratslam(backend=backend, dtype=np.float64)
    step = 2 * math.pi / 36
    ths = _tracked(pop, 100, 2, omega=0.2 * step, dt=1.0)
    assert ths[-1] - ths[0] == pytest.approx(20.0, abs=0.5)


def _linear_mean(a: np.ndarray, axis: int, ref: float) -> float:
    """Mass-weighted mean index along ``axis``, distances unwrapped around ``ref``."""
    n = a.shape[axis]
    prof = a.sum(axis=tuple(i for i in range(a.ndim) if i != axis))
    d = (np.arange(n) - ref + n / 2) % n - n / 2
    return ref + float(np.dot(prof, d) / prof.sum())


ORIENTATIONS = [(0, 0, 0), (0, 0, 1), (1, 2, 0), (3, 1, 4)]


@pytest.mark.parametrize("orientation", ORIENTATIONS)
def test_6d_translation_follows_the_voxel_orientation(orientation):
    """The check below on the numba backend (the default); every backend in the slow set."""
    _check_6d_translation("numba", orientation)


@pytest.mark.slow  # 100 steps of 1.2 M cells per orientation, ~2.5 s each on numpy and OpenCL (fast loop <= 4 min)
@pytest.mark.parametrize("orientation", ORIENTATIONS)
def test_6d_translation_follows_the_voxel_orientation_on_every_backend(backend, orientation):
    _check_6d_translation(backend, orientation)


def _check_6d_translation(backend, orientation):
    """0.3 cells/step along a sensor-frame diagonal (x, y and z at once) moves the activity by R(roll, pitch, yaw) v.

    A 21-cell translational grid (5 cells per angle as in the thesis) so the packet,
    smeared by 100 pure shifts, does not wrap onto itself. Transport is measured by the
    activity's first moment (exact for mass-conserving shifts); the decoded estimate,
    biased by the +-3 window on a smeared packet, must agree within 1 cell.
    """
    cell = 0.02
    pop = Population.whisker6d(grid_cells=21, angle_cells=5, cell_size_m=cell, backend=backend, dtype=np.float64)
    pop.reset_cell([10, 10, 10, *orientation])
    v = np.array([1.0, -1.0, 1.0]) / math.sqrt(3.0) * 0.3 * cell  # 0.3 cells/step in total
    means = np.array([10.0, 10.0, 10.0])
    decoded_moved = np.zeros(3)
    prev = pop.decode()[:3]
    for _ in range(100):
        pop.integrate(velocity=v, dt=1.0)
        a = pop.activity
        means = np.array([_linear_mean(a, ax, means[ax]) for ax in range(3)])
        d = pop.decode()[:3]
        decoded_moved += (d - prev + 10.5) % 21 - 10.5
        prev = d
    R = euler_grid_rotations(pop.axes[3:])[orientation]
    expect = R @ (v / cell) * 100
    np.testing.assert_allclose(means - 10.0, expect, atol=0.5)
    np.testing.assert_allclose(decoded_moved, expect, atol=1.0)


def test_dynamics_in_the_loop_move_the_packet_at_nearly_the_commanded_speed(backend):
    """With attractor dynamics each step the packet lags a little (lattice pinning, heading spread).

    Documented behaviour of RatSLAM's CAN: at 0.3 cells/step the 3-D preset moves at
    90-100 % of the commanded speed.
    """
    pop = Population.openratslam(backend=backend, dtype=np.float64)
    pop.reset_cell([10, 10, 0])
    for _ in range(30):
        pop.step()
    xs = [pop.decode()[0]]
    for _ in range(100):
        xs.append(pop.step(velocity=0.3, dt=1.0)[0])
    xs = np.unwrap(np.array(xs) * 2 * np.pi / 21) * 21 / (2 * np.pi)
    assert 0.90 * 30 <= xs[-1] - xs[0] <= 30.0


# ------------------------------------------------------------------ bad input
def _bad_calls(pop):
    return [
        lambda: pop.step(velocity=float("nan"), dt=1.0),
        lambda: pop.step(velocity=0.1, omega=float("inf"), dt=1.0),
        lambda: pop.step(velocity=0.1, dt=-0.1),
        lambda: pop.integrate(velocity=0.1, dt=float("nan")),
        lambda: pop.shift([0.1, float("nan"), 0.0]),
        lambda: pop.shift([0.1, 0.2]),
        lambda: setattr(pop, "activity", np.ones((3, 3))),
        lambda: setattr(pop, "activity", np.full(pop.shape, np.nan)),
        lambda: pop.reset_cell([1, 2]),
        lambda: pop.inject([1, 2, 3], -1.0),
        lambda: pop.step(injection=(np.array([10**9]), np.array([1.0]))),
        lambda: pop.shift_conditional((0, 1), np.zeros((5, 2))),
        # axes that are not whole numbers, shifts that are not numbers (were OverflowError/ValueError/TypeError)
        lambda: pop.shift_conditional((math.inf,), np.zeros(pop.shape[1:] + (1,))),
        lambda: pop.shift_conditional((0.5,), np.zeros(pop.shape[1:] + (1,))),
        lambda: pop.shift_conditional(("a",), np.zeros(pop.shape[1:] + (1,))),
        lambda: pop.shift_conditional(None, np.zeros(pop.shape[1:] + (1,))),
        lambda: pop.shift_conditional((0,), np.full(pop.shape[1:] + (1,), "a")),
        lambda: pop.shift_conditional((0,), [[1.0], [1.0, 2.0]]),
        # flat indices cast with dtype=int64: NaN/inf/1e30 raised ValueError/OverflowError, 2.7 was truncated to 2
        lambda: pop.inject_flat([math.nan], [0.1]),
        lambda: pop.inject_flat([math.inf], [0.1]),
        lambda: pop.inject_flat([1e30], [0.1]),
        lambda: pop.inject_flat([2.7], [0.1]),
        lambda: pop.inject_flat(["a"], [0.1]),
        lambda: pop.inject_flat([1], ["a"]),
        lambda: pop.step(injection=([2.5], [0.1])),
    ]


def test_bad_input_raises_typed_errors_and_leaves_state_unchanged(backend):
    from cansim import InvalidInputError

    pop = Population.openratslam(backend=backend)
    for _ in range(5):
        pop.step(velocity=0.2, dt=1.0)
    before = pop.activity
    for call in _bad_calls(pop):
        with pytest.raises(InvalidInputError):
            call()
        np.testing.assert_array_equal(pop.activity, before)


def test_zero_activity_is_reported_and_state_kept():
    from cansim import ZeroActivityError

    pop = Population.openratslam(params=AttractorParams(global_inhibition=1.0))
    before = pop.activity
    with pytest.raises(ZeroActivityError):
        pop.step()
    np.testing.assert_array_equal(pop.activity, before)


def test_unknown_and_missing_backends(monkeypatch):
    import importlib.util

    import cansim.backends as reg
    from cansim import BackendUnavailableError, UnknownBackendError

    with pytest.raises(UnknownBackendError, match="choose one of"):
        Population.openratslam(backend="cuda")
    real = importlib.util.find_spec
    monkeypatch.setattr(reg.importlib.util, "find_spec", lambda n, *a: None if n == "pyopencl" else real(n, *a))
    assert "opencl" not in reg.available_backends()
    with pytest.raises(BackendUnavailableError, match=r"cansim\[opencl\]"):
        reg.get_backend("opencl")


def test_empty_grid_and_bad_axes():
    from cansim import InvalidInputError, ShapeError

    with pytest.raises(ShapeError):
        Population([])
    with pytest.raises(InvalidInputError):
        Axis.linear("x", 0, 1.0)
    with pytest.raises(InvalidInputError):
        Axis.linear("x", 5, -1.0)
    with pytest.raises(InvalidInputError):
        Population([Axis.linear("x", 4, 1.0), Axis.linear("x", 4, 1.0)])


def test_import_does_no_work():
    code = "import sys, cansim; print(int(any(m in sys.modules for m in ('numba', 'pyopencl', 'scipy'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "0"


@pytest.mark.parametrize(
    "orientation,cells",
    [
        # yaw one cell (72 deg): R = Rz(72) sends body x to (cos 72, sin 72, 0)
        ((0, 0, 1), {(10, 10, 10): (1 - 0.30901699437) * (1 - 0.95105651630), (11, 10, 10): 0.30901699437 * (1 - 0.95105651630),
                     (10, 11, 10): (1 - 0.30901699437) * 0.95105651630, (11, 11, 10): 0.30901699437 * 0.95105651630}),
        # pitch one cell: R = Ry(72) sends body x to (cos 72, 0, -sin 72)
        ((0, 1, 0), {(10, 10, 10): (1 - 0.30901699437) * (1 - 0.95105651630), (11, 10, 10): 0.30901699437 * (1 - 0.95105651630),
                     (10, 10, 9): (1 - 0.30901699437) * 0.95105651630, (11, 10, 9): 0.30901699437 * 0.95105651630}),
        # roll only: body x stays x
        ((0, 0, 0), {(11, 10, 10): 1.0}),
    ],
)
def test_six_dof_conditional_translation_of_one_voxel_by_hand(backend, orientation, cells):
    """Independent expectation: hand-computed cos/sin of 72 deg and the trilinear split (Fig 5.7-5.11)."""
    cell = 0.02
    pop = Population.whisker6d(grid_cells=21, angle_cells=5, cell_size_m=cell, backend=backend, dtype=np.float64)
    pop.reset_cell([10, 10, 10, *orientation])
    pop.integrate(velocity=[cell, 0.0, 0.0], dt=1.0)  # one cell along body x
    a = pop.activity
    got = {idx[:3]: float(a[idx]) for idx in zip(*np.nonzero(a > 1e-12))}
    assert set(got) == set(cells)
    for k, w in cells.items():
        assert got[k] == pytest.approx(w, abs=1e-9)
    assert all(idx[3:] == orientation for idx in zip(*np.nonzero(a > 1e-12)))


def test_thesis_6d_kernels_are_the_printed_normal_densities():
    """Eq 5.10 as printed: variance 1 / 2 per axis, pdf-normalised -> window sums 0.9464 and 0.6430."""
    exc, inh = Population.whisker6d().params.kernels(6)
    assert float(np.prod([t.sum() for t in exc.taps])) == pytest.approx(0.9464, abs=5e-4)
    assert float(np.prod([t.sum() for t in inh.taps])) == pytest.approx(0.6430, abs=5e-4)
    assert exc.taps[0][2] == pytest.approx(1 / math.sqrt(2 * math.pi))


def test_thesis_6d_packet_is_stable_without_input(backend):
    """Fig 5.4: from one active cell the packet settles within a few steps and stays at the centre."""
    pop = Population.whisker6d(backend=backend, dtype=np.float64)
    decoded = [pop.step() for _ in range(12)]
    for d in decoded[3:]:
        np.testing.assert_allclose(d, [2.0] * 6, atol=1e-6)
    a1, a2 = pop.activity, (pop.step(), pop.activity)[1]
    assert np.abs(a1 - a2).max() < 1e-6


# ------------------------------------------------ validated odometry, trusted twin
def _motion_cases():
    from cansim.path_integration import PlanarMotion, SixDofMotion, UniformMotion

    return {
        "ring": (UniformMotion(), Population.head_direction(36).axes),
        "sheet": (UniformMotion(), (Axis.linear("x", 9, 0.5), Axis.linear("y", 7, 2.0))),
        "planar": (PlanarMotion("openratslam"), Population.openratslam(9, 12, 0.25).axes),
        "6d": (SixDofMotion(), Population.whisker6d(5, 0.02, angle_cells=6).axes),
    }


def _odometry(kind, rng, zero):
    """Valid odometry fields as maps.odometry builds them (floats, read-only float64 (3,) arrays)."""
    if kind in ("ring", "planar"):
        v, w = (0.0 if zero else float(rng.uniform(-2, 2)) for _ in range(2))
        return (v, None if kind == "ring" else w, float(rng.uniform(0, 2)))
    if kind == "sheet":
        return (np.zeros(2) if zero else rng.uniform(-3, 3, 2), None, float(rng.uniform(0, 2)))
    v, w = (np.zeros(3) if zero else rng.uniform(-0.1, 0.1, 3) for _ in range(2))
    v.flags.writeable = w.flags.writeable = False
    return (v, w, float(rng.uniform(0, 2)))


@settings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["ring", "sheet", "planar", "6d"]), zero=st.booleans(), seed=st.integers(0, 2**31 - 1))
def test_trusted_motion_twin_gives_the_checked_shifts_bit_for_bit(kind, zero, seed):
    """The built-in models' twin for validated odometry computes what the checking function
    computes (same axes, same bits, None where it gives None), and a population's trusted
    step equals its public step; the checking function still refuses bad values."""
    model, axes = _motion_cases()[kind]
    checked, trusted = model.bind_checked_and_trusted(axes)
    assert checked is not trusted
    args = _odometry(kind, np.random.default_rng(seed), zero)
    want, got = checked(*args), trusted(*args)
    assert got.shift_axes == want.shift_axes
    for g, w in ((got.cond_shifts, want.cond_shifts), (got.uniform, want.uniform)):
        assert (g is None) == (w is None)
        if w is not None:
            assert g.tobytes() == w.tobytes()
    a, b = (Population(axes, motion=model, backend="numpy") for _ in range(2))
    a.reset_gaussian([n / 3 for n in a.shape], 1.0)
    b.activity = a.activity
    assert a._step_validated(*args).tobytes() == b.step(*args).tobytes()
    assert a.activity.tobytes() == b.activity.tobytes()
    bad = list(args)
    bad[2] = -1.0
    with pytest.raises(InvalidInputError):
        checked(*bad)


def test_a_model_that_overrides_bind_keeps_its_checks_on_the_trusted_path():
    """A subclass's own ``bind`` (here doubling the velocity) is what both paths run."""
    from cansim.path_integration import UniformMotion

    class Doubled(UniformMotion):
        def bind(self, axes):
            inner = super().bind(axes)
            return lambda velocity, omega, dt: inner(None if velocity is None else 2.0 * np.asarray(velocity), omega, dt)

    axes = (Axis.linear("x", 9, 1.0),)
    checked, trusted = Doubled().bind_checked_and_trusted(axes)
    assert checked(np.array([0.5]), None, 1.0).uniform.tolist() == [1.0]
    assert trusted(np.array([0.5]), None, 1.0).uniform.tolist() == [1.0]
    with pytest.raises(InvalidInputError):
        trusted(np.array([np.nan]), None, 1.0)


@pytest.mark.parametrize("kind,args", [
    ("planar", (np.array([0.3, 0.0, 0.0]), 0.1, 1.0)),  # a spatial field on a planar grid
    ("planar", ("fast", 0.0, 1.0)),
    ("6d", (0.3, 0.1, 1.0)),  # planar fields on the 6-D grid
    ("6d", (np.array([0.1, np.nan, 0.0], np.float32), np.zeros(3), 1.0)),  # not float64: checked
    ("6d", ([0.1, 0.0], np.zeros(3), 1.0)),
    ("sheet", ([np.inf, 0.0], None, 1.0)),
    ("sheet", (np.zeros(3), None, 1.0)),
    ("ring", (0.1, 0.2, 1.0)),  # omega on a ring
])
def test_trusted_twin_checks_inputs_not_of_the_validated_form(kind, args):
    """Trust covers values of the validated form only: anything else gets the checked
    function's typed error, never a crash or a silent result."""
    from cansim import ShapeError

    model, axes = _motion_cases()[kind]
    checked, trusted = model.bind_checked_and_trusted(axes)
    with pytest.raises((InvalidInputError, ShapeError)) as want:
        checked(*args)
    with pytest.raises(type(want.value)):
        trusted(*args)


@pytest.mark.parametrize("make", [lambda: Population.head_direction(2**40), lambda: Population.head_direction(2**26 + 1),
                                  lambda: Population.whisker6d(30), lambda: Population.openratslam(xy_cells=10**4)])
def test_a_grid_over_the_cell_limit_is_refused_before_allocating(make):
    """Population.head_direction(2**40) was accepted and then ran out of memory (issue 25)."""
    from cansim.population import MAX_CELLS

    with pytest.raises(InvalidInputError, match=str(MAX_CELLS)):
        make()


_OPS = st.lists(
    st.tuples(st.sampled_from(["step", "step", "step", "inject", "set", "gauss", "dynamics", "shift", "warm_up",
                               "run", "numpy step"]),
              st.integers(0, 2**31 - 1)),
    min_size=1, max_size=12,
)


@settings(max_examples=25, deadline=None)
@given(ops=_OPS, dtype=st.sampled_from([np.float32, np.float64]))
def test_the_regions_a_population_keeps_give_the_same_bits_through_any_sequence(ops, dtype):
    """The numba step is told where the two grids of the population can be non-zero
    (``Population._regions``); whatever wrote them last (a step, an injection, a reset,
    a run, another backend), every result equals the same population's without them."""
    pytest.importorskip("numba")
    tracked = Population.openratslam(21, 36, 0.25, backend="numba", dtype=dtype)
    plain = Population.openratslam(21, 36, 0.25, backend="numba", dtype=dtype)
    plain._regions = None
    assert tracked._regions is not None
    narrowed = False
    for op, seed in [("step", 0), *ops, ("step", 1), ("step", 2)]:
        rng = np.random.default_rng(seed)
        v, w = float(rng.uniform(-2.0, 2.0)), float(rng.uniform(-1.0, 1.0))  # up to 8 cells, 10 deg a step
        idx = rng.integers(0, tracked.size, int(rng.integers(1, 4)))
        vals = rng.uniform(0.0, 0.3, len(idx))
        cell = [int(rng.integers(n)) for n in tracked.shape]
        inj = (idx, vals) if rng.random() < 0.5 else None
        for pop in (tracked, plain):
            if op == "step":
                pop.step(v, w, 1.0, injection=inj)
            elif op == "inject":
                pop.inject(cell, 0.4)
            elif op == "set":
                g = np.zeros(pop.shape)
                g[tuple(cell)] = 1.0
                pop.activity = g
            elif op == "gauss":
                pop.reset_gaussian(cell, 1.5)
            elif op == "dynamics":
                pop.dynamics()
            elif op == "shift":
                pop.shift([v * 3, w * 3, 2.5])
            elif op == "warm_up":
                pop.warm_up(v, w)
            elif op == "run":
                pop.run([v] * 3, [w] * 3, [1.0] * 3, [(idx, vals), None, None])
            else:  # a step on another backend, then back
                pop.set_backend("numpy")
                pop.step(v, w, 1.0)
                pop.set_backend("numba")
        np.testing.assert_array_equal(tracked.activity, plain.activity)
        np.testing.assert_array_equal(tracked.decode(), plain.decode())
        narrowed |= bool(np.any(tracked._regions[0, 1] < tracked.shape))
    assert narrowed  # the steps did run on the regions


def test_a_warm_up_between_steps_leaves_the_regions_true():
    """warm_up steps a scratch copy; the population's own grids (and where they are
    non-zero) must not follow it."""
    pytest.importorskip("numba")
    tracked = Population.openratslam(21, 36, 0.25, backend="numba")
    plain = Population.openratslam(21, 36, 0.25, backend="numba")
    plain._regions = None
    for pop in (tracked, plain):
        for _ in range(5):
            pop.step(1.0, 0.2, 1.0)
        pop.warm_up(2.0, 0.5)  # the scratch step lands elsewhere than the next real one
        for _ in range(3):
            pop.step(1.0, 0.2, 1.0)
    assert np.any(tracked._regions[0, 1] < tracked.shape)
    np.testing.assert_array_equal(tracked.activity, plain.activity)


@settings(max_examples=60, deadline=None)
@given(size=st.integers(1, 720), factor=st.floats(0.01, 100.0))
def test_an_angular_axis_covers_a_whole_turn(size, factor):
    """``Axis("th", 36, 0.1, angular=True)`` was accepted, and 5 rad of rotation then decoded as 80 deg, not 286
    (a user's pass, session 47): an angular axis's step is 2 pi / size."""
    turn = Axis("th", size, 2 * math.pi / size, angular=True)
    assert turn == Axis.angle("th", size) and turn.period == pytest.approx(2 * math.pi)
    step = 2 * math.pi / size * factor
    if abs(factor - 1.0) > 1e-6:
        with pytest.raises(InvalidInputError, match=r"angular axis covers a whole turn.*Axis\.angle\('th', "):
            Axis("th", size, step, angular=True)
    assert Axis("th", size, step).period == pytest.approx(size * step)  # a linear axis takes any step


def test_an_angular_step_stored_as_float32_is_a_whole_turn():
    """NIR metadata or hand-built axes may hold 2 pi / n in single precision (a review, session 47)."""
    step = float(np.float32(2 * math.pi / 36))
    assert Axis("th", 36, step, angular=True).size == 36
