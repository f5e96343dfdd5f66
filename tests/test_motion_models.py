"""A motion model of one's own: what its step function returns is checked the same on every backend (a user's
pass, session 47: a wrong shape raised inside numpy and shifted 3 or 6 cells silently on numba)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim import Axis, InvalidInputError, Population
from cansim.errors import ShapeError
from cansim.path_integration import MotionModel, MotionShifts, UniformMotion, check_motion_shifts


class Returns(MotionModel):
    """Returns whatever it is given, every step."""

    def __init__(self, result):
        self.result = result

    def bind(self, axes):
        return lambda velocity, omega, dt: self.result


GRID = (Axis.linear("x", 6, 0.1), Axis.angle("th", 8))


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("result,says", [
    (MotionShifts(None, None, np.array([1.0])), r"uniform of shape \(1,\)"),  # a 1-D shift on a 2-D grid
    (MotionShifts((0,), None, None), "shift_axes \\(0,\\) with cond_shifts None"),
    (MotionShifts((0,), np.zeros((6, 1)), None), r"cond_shifts of shape \(6, 1\) for shift_axes \(0,\) \(expected \(8, 1\)\)"),
    (MotionShifts((1, 0), np.zeros(2), None), r"shift_axes \(1, 0\)"),
    (MotionShifts((2,), np.zeros((6, 8, 1)), None), r"shift_axes \(2,\)"),
    ((np.zeros(2),), "got tuple"),
    (None, "got NoneType"),
])
def test_a_wrong_result_is_the_same_shape_error_on_every_backend(backend, result, says):
    p = Population(GRID, motion=Returns(result), backend=backend, dtype=np.float64)
    before = p.activity
    with pytest.raises(ShapeError, match="Returns's step function must return MotionShifts") as exc:
        p.step(1.0)
    assert said(exc, says)
    np.testing.assert_array_equal(p.activity, before)  # nothing moved


def said(exc, pattern):
    import re

    return re.search(pattern, str(exc.value)) is not None


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_right_result_moves_the_packet_as_a_built_in_model_would(backend):
    own = Population(GRID, motion=Returns(MotionShifts(None, None, [1.0, 2.0])), backend=backend, dtype=np.float64)
    built = Population(GRID, motion=UniformMotion(), backend=backend, dtype=np.float64)
    # uniform motion by (0.1 m, 2 steps of th) in one second: one cell of x, two of th
    np.testing.assert_array_equal(own.step(0.0), built.step([0.1, 2 * GRID[1].step]))
    np.testing.assert_array_equal(own.activity, built.activity)


def test_a_motion_that_is_no_model_instance_or_binds_no_function_is_refused_at_construction():
    with pytest.raises(InvalidInputError, match="got the class UniformMotion"):
        Population(GRID, motion=UniformMotion)
    with pytest.raises(InvalidInputError, match="got function"):
        Population(GRID, motion=lambda v, w, dt: None)

    class Binds42(MotionModel):
        def bind(self, axes):
            return 42

    with pytest.raises(InvalidInputError, match="Binds42.bind\\(axes\\) must return a function"):
        Population(GRID, motion=Binds42())


@settings(max_examples=60, deadline=None)
@given(shape=st.lists(st.integers(1, 5), min_size=1, max_size=4), axes=st.lists(st.integers(-1, 4), max_size=3),
       cond_extra=st.integers(0, 1), uniform_len=st.integers(0, 5))
def test_check_motion_shifts_accepts_exactly_the_rule(shape, axes, cond_extra, uniform_len):
    shape = tuple(shape)
    ndim = len(shape)
    ax = tuple(axes) or None
    cond = None if ax is None else np.zeros(tuple(n for k, n in enumerate(shape) if k not in ax) + (len(ax) + cond_extra,))
    uniform = np.zeros(uniform_len) if uniform_len else None
    valid_axes = ax is None or (list(ax) == sorted(set(ax)) and all(0 <= k < ndim for k in ax))
    ok = valid_axes and (ax is None or cond_extra == 0) and (uniform is None or uniform_len == ndim)
    try:
        got = check_motion_shifts(MotionShifts(ax, cond, uniform), shape)
    except ShapeError:
        assert not ok
        return
    assert ok and (got.uniform is None or got.uniform.dtype == np.float64)


def test_shift_axes_may_be_any_sequence_of_axis_indices_but_not_booleans():
    shape = (6, 8)
    got = check_motion_shifts(MotionShifts([0], np.zeros((8, 1)), None), shape)  # a list, as one's own model may give
    assert got.shift_axes == (0,) and got.cond_shifts.dtype == np.float64
    with pytest.raises(ShapeError, match="shift_axes"):
        check_motion_shifts(MotionShifts((True,), np.zeros((8, 1)), None), shape)
