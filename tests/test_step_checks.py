"""The per-step checks' fast paths refuse and accept exactly what the full checks do (issue 26 item 1).

The valid path of ``Population.step`` and ``SlamLoop.step`` skips the ABC / numpy machinery
(plain-float fast path of ``finite_scalar``, ``PlanarMotion`` checking its shift range on
scalars instead of ``check_shift`` on the arrays); these tests hold the fast paths to the
slow ones' decisions, computed here independently.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim import Axis, Population
from cansim.errors import InvalidInputError
from cansim.grid_inputs import MAX_SHIFT_CELLS
from cansim.grid_inputs import check_shift
from cansim.path_integration import MotionShifts, PlanarMotion, UniformMotion, shifts_range_checked
from whisker_io.validation import finite_scalar, finite_vector

_ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True)
_HUGE_OR_SMALL = st.one_of(
    st.floats(-10.0, 10.0), st.floats(-1e300, 1e300), st.sampled_from([0.0, -0.0, 2.0**30, -(2.0**30), 1e-300])
)


def _planar_axes(nx: int, nth: int, cell_m: float) -> tuple[Axis, Axis, Axis]:
    return (Axis.linear("x", nx, cell_m), Axis.linear("y", nx, cell_m), Axis.angle("theta", nth))


def _reference_shifts(v: float, w: float, dt: float, nth: int, cell_m: float, frame: str):
    """The shifts as arrays, built here from the definition (PlanarMotion's docstring), or None when
    the largest of them is not below MAX_SHIFT_CELLS (what check_shift refuses)."""
    th = np.arange(nth) * (2.0 * np.pi / nth)
    d = np.stack([np.cos(th), np.sin(th)] if frame == "standard" else [np.sin(th), np.cos(th)], axis=1)
    d = d / np.array([cell_m, cell_m])
    with np.errstate(over="ignore", invalid="ignore"):
        cond = (v * dt) * d if v != 0.0 else None
        rot = w * dt * (1.0 / (2.0 * np.pi / nth))
    for arr in (cond, np.array([rot])):
        if arr is not None and not float(np.abs(arr).max()) < MAX_SHIFT_CELLS:  # NaN refused too
            return None
    return cond, rot


@settings(max_examples=300, deadline=None)
@given(_HUGE_OR_SMALL, _HUGE_OR_SMALL, st.one_of(st.floats(0.0, 10.0), st.floats(0.0, 1e300)),
       st.sampled_from([1e-6, 0.015, 1.0, 1e6]), st.sampled_from([4, 36, 90]), st.sampled_from(["standard", "openratslam"]))
def test_planar_shift_range_is_refused_exactly_where_the_array_check_refuses(v, w, dt, cell_m, nth, frame):
    axes = _planar_axes(5, nth, cell_m)
    checked, trusted = PlanarMotion(frame).bind_checked_and_trusted(axes)
    want = _reference_shifts(v, w, dt, nth, cell_m, frame)
    for f in (checked, trusted):
        if want is None:
            with pytest.raises(InvalidInputError, match="too large to represent"):
                f(v, w, dt)
            continue
        ms = f(v, w, dt)
        cond, rot = want
        if cond is None:
            assert ms.cond_shifts is None
        else:
            assert ms.shift_axes == (0, 1)
            np.testing.assert_allclose(ms.cond_shifts, cond, rtol=1e-12, atol=0)
        assert (ms.uniform is None) == (rot == 0.0)
        if ms.uniform is not None:
            assert ms.uniform[:2].tolist() == [0.0, 0.0]
            assert math.isclose(ms.uniform[2], rot, rel_tol=1e-12)


@settings(max_examples=300, deadline=None)
@given(st.lists(_HUGE_OR_SMALL, min_size=1, max_size=4), st.one_of(st.floats(0.0, 10.0), st.floats(0.0, 1e300)),
       st.sampled_from([1e-9, 0.5, 1e3]))
def test_uniform_shift_range_is_refused_exactly_where_the_array_check_refuses(velocity, dt, step):
    n = len(velocity)
    axes = tuple(Axis.linear(f"a{i}", 5, step) for i in range(n))
    checked, trusted = UniformMotion().bind_checked_and_trusted(axes)
    arg = velocity[0] if n == 1 else np.array(velocity)
    with np.errstate(over="ignore", invalid="ignore"):  # the definition, in the engine's rounding order
        inv = 1.0 / step
        want = np.array([velocity[0] * dt * inv]) if n == 1 else np.array(velocity) * (dt * np.full(n, inv))
        try:
            check_shift(want, "uniform")
            refused = False
        except InvalidInputError:
            refused = True
        for f in (checked, trusted):
            if refused:
                with pytest.raises(InvalidInputError, match="too large to represent"):
                    f(arg, None, dt)
                continue
            assert f(arg, None, dt).uniform.tolist() == want.tolist()


def test_an_oversized_step_leaves_the_population_unchanged():
    pop = Population.openratslam(5, 8, 1e-6, backend="numpy")
    before = pop.activity
    with pytest.raises(InvalidInputError, match="translation shift"):
        pop.step(2e3, 0.0, 1.0)  # 2e9 cells along heading 0 (> 2**30)
    with pytest.raises(InvalidInputError, match="uniform shift"):
        pop.step(0.0, 1e300, 1e10)  # vrot * dt overflows to inf
    assert np.array_equal(pop.activity, before)


def test_a_users_motion_model_is_still_range_checked_by_the_population():
    """The scalar range check is trusted only for the built-in models' own functions."""

    class Wild(UniformMotion):
        def bind(self, axes):  # shifts nobody checked
            return lambda velocity, omega, dt: MotionShifts(None, None, np.array([velocity * dt]))

    axes = (Axis.linear("x", 9, 1.0),)
    assert not any(shifts_range_checked(f) for f in Wild().bind_checked_and_trusted(axes))
    assert all(shifts_range_checked(f) for f in PlanarMotion().bind_checked_and_trusted(_planar_axes(5, 8, 1.0)))
    pop = Population(axes, motion=Wild(), backend="numpy")
    with pytest.raises(InvalidInputError, match="too large to represent"):
        pop.step(3.0 * 2.0**30, None, 1.0)


@settings(max_examples=300, deadline=None)
@given(_ANY_FLOAT)
def test_finite_scalar_plain_float_fast_path_matches_the_general_path(x):
    """A float and the same value as a numpy float64 (the general path) get the same answer."""
    results = []
    for value in (x, np.float64(x)):
        try:
            results.append(("ok", finite_scalar(value, "x")))
        except InvalidInputError as exc:
            results.append(("error", str(exc)))
    assert results[0] == results[1]
    assert (results[0][0] == "ok") == math.isfinite(x)
    if math.isfinite(x):
        assert type(results[0][1]) is float and results[0][1] == x


@settings(max_examples=200, deadline=None)
@given(st.lists(_ANY_FLOAT, min_size=0, max_size=40))
def test_finite_vector_returns_a_fresh_copy_and_finds_the_first_bad_index(values):
    arr = np.array(values, dtype=np.float64)
    bad = [i for i, v in enumerate(values) if not math.isfinite(v)]
    if bad:
        with pytest.raises(InvalidInputError, match=rf"at index {bad[0]} \({len(bad)} non-finite"):
            finite_vector(arr, None, "v")
        return
    out = finite_vector(arr, len(values), "v")
    assert out is not arr and np.array_equal(out, arr)
    out[...] = -1.0  # the caller's array is not the result
    assert np.array_equal(arr, np.array(values, dtype=np.float64))
