"""The finite-value validators (whisker_io.validation): typed errors on bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from whisker_io.errors import CansimError, InvalidInputError, ShapeError
from whisker_io.validation import finite_array, finite_scalar, finite_vector


def test_finite_scalar_hand_cases():
    assert finite_scalar(3, "x") == 3.0 and isinstance(finite_scalar(np.float32(2.5), "x"), float)
    assert finite_scalar(np.array(1.5), "x") == 1.5
    for bad in (math.nan, math.inf, "1.0", None, True, 1 + 2j, [1.0], [1.0, 2.0]):
        with pytest.raises(InvalidInputError, match="x"):
            finite_scalar(bad, "x")


def test_finite_vector_hand_cases():
    out = finite_vector((1, 2, 3), 3, "v")
    assert out.dtype == np.float64 and out.tolist() == [1.0, 2.0, 3.0]
    src = np.zeros(3)
    assert finite_vector(src, 3, "v") is not src  # a copy
    assert finite_vector(4.0, 1, "v").tolist() == [4.0]
    assert finite_vector([1.0] * 7, None, "v").shape == (7,)
    with pytest.raises(ShapeError, match=r"v must have shape \(3,\)"):
        finite_vector([1, 2], 3, "v")
    with pytest.raises(ShapeError):
        finite_vector([[1, 2, 3]], 3, "v")
    with pytest.raises(InvalidInputError, match="index 1"):
        finite_vector([0.0, math.nan, 0.0], 3, "v")
    with pytest.raises(InvalidInputError):
        finite_vector(["a", "b", "c"], 3, "v")
    with pytest.raises(InvalidInputError):
        finite_vector([1j, 0, 0], 3, "v")


def test_finite_array_shape_wildcards():
    assert finite_array(np.ones((5, 3)), (None, 3), "p").shape == (5, 3)
    with pytest.raises(ShapeError, match=r"\(n, 3\)"):
        finite_array(np.ones((5, 2)), (None, 3), "p")
    with pytest.raises(InvalidInputError, match=r"index \(1, 0\)"):
        finite_array([[0.0, 0.0], [math.inf, 0.0]], None, "p")


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(0, 6), elements=st.floats(allow_nan=True, allow_infinity=True)),
       st.one_of(st.none(), st.integers(0, 6)))
def test_vector_accepts_exactly_the_finite_vectors_of_length_n(v, n):
    try:
        out = finite_vector(v, n, "v")
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        assert (n is not None and v.shape != (n,)) or not np.all(np.isfinite(v))
        return
    assert np.all(np.isfinite(v)) and (n is None or v.shape == (n,))
    assert np.array_equal(out, v)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.floats(), st.integers(-10**400, 10**400), st.text(max_size=3), st.none(), st.booleans()))
def test_scalar_is_finite_float_or_typed_error(x):
    try:
        out = finite_scalar(x, "x")
    except CansimError as exc:
        assert isinstance(exc, InvalidInputError)
        return
    assert isinstance(out, float) and math.isfinite(out)
    assert not isinstance(x, (str, bool)) and x is not None


def test_whole_number():
    from whisker_io.validation import whole_number
    assert whole_number(3, "n") == 3 and whole_number(np.int64(4), "n") == 4 and whole_number(5.0, "n") == 5
    for bad in (2.5, "3", True, None, math.nan, math.inf):
        with pytest.raises(InvalidInputError, match="n"):
            whole_number(bad, "n")
    with pytest.raises(InvalidInputError, match=">= 2"):
        whole_number(1, "n", minimum=2)


def test_text_or_bools_nested_in_lists_are_not_numbers():
    """np.array(["0"], float) parses text; the validator must not (found by the explorer's fuzz test)."""
    for bad in ([0, 0, "0"], [[1.0, "2"]], [True, 0.0], (0.0, b"1")):
        with pytest.raises(InvalidInputError):
            finite_vector(bad, None, "v") if np.ndim(bad) == 1 else finite_array(bad, None, "v")
    np.testing.assert_array_equal(finite_vector([0, 1.5, 2], 3, "v"), [0.0, 1.5, 2.0])
