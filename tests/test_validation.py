"""The finite-value validators (whisker_io.validation): typed errors on bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
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


# ------------------------------------------------------------- config_field
def test_config_field_hand_cases():
    from whisker_io.errors import ConfigError
    from whisker_io.validation import config_field

    assert config_field(7, "exc_width", int, minimum=1, odd=True) == 7
    assert config_field(np.int64(3), "n", int, minimum=3) == 3
    assert config_field(2, "sigma", float, above=0) == 2 and config_field(1.0, "correction", float, above=0, maximum=1) == 1.0
    assert config_field(None, "budget", int, minimum=1, optional=True) is None
    assert config_field("learnt", "lv_mode", str, choices=("stored", "learnt")) == "learnt"
    assert config_field(np.bool_(True), "flag", bool)
    cases = [
        ((4, "exc_width", int), dict(minimum=1, odd=True), "exc_width must be an odd integer >= 1, got 4"),
        ((2.0, "n", int), {}, "n must be an integer, got 2.0"),
        ((True, "n", int), {}, "n must be an integer, got True"),
        ((0, "cell_size_m", float), dict(above=0), "cell_size_m must be a finite number > 0, got 0"),
        ((1.5, "correction", float), dict(above=0, maximum=1), "correction must be a finite number > 0 and <= 1, got 1.5"),
        ((math.nan, "x", float), {}, "x must be a finite number, got nan"),
        ((10**400, "x", float), {}, "x must be a finite number"),
        (("1", "x", float), {}, "x must be a finite number, got '1'"),
        ((1, "flag", bool), {}, "flag must be a boolean"),
        (("x", "lv_mode", str), dict(choices=("stored", "learnt")), "lv_mode must be one of 'stored', 'learnt', got 'x'"),
        ((None, "n", int), dict(minimum=1), "n must be an integer >= 1, got None"),
        ((0, "n", int), dict(minimum=1, optional=True, hint="None means all"), "n must be an integer >= 1 or None, got 0; None means all"),
    ]
    for args, kw, message in cases:
        with pytest.raises(ConfigError) as info:
            config_field(*args, **kw)
        assert str(info.value).startswith(message), str(info.value)


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.integers(-10, 10), st.floats(), st.booleans(), st.none(), st.text(max_size=2)), st.booleans())
def test_config_field_int_accepts_exactly_the_odd_or_any_ints_in_range(value, odd):
    from whisker_io.errors import ConfigError
    from whisker_io.validation import config_field

    good = isinstance(value, int) and not isinstance(value, bool) and value >= 1 and (not odd or value % 2 == 1)
    try:
        assert config_field(value, "w", int, minimum=1, odd=odd) is value
    except ConfigError as exc:
        assert not good and str(exc).startswith("w must be")
        return
    assert good


@settings(max_examples=50, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5), st.booleans(), st.none(), st.text(max_size=2)))
@example(1e10)  # overflows b
@example(0.25)
def test_scaled_fields_multiplies_the_named_fields_or_raises_a_typed_error(scale):
    import dataclasses

    from whisker_io.validation import scaled_fields

    @dataclasses.dataclass(frozen=True)
    class Noise:
        a: float = 2.0
        b: float = 1e300
        kept: float = 7.0

    ok = (isinstance(scale, (int, float)) and not isinstance(scale, bool) and math.isfinite(scale) and scale >= 0
          and math.isfinite(2.0 * scale))
    if ok:
        got = scaled_fields(Noise(), scale, ("a",))
        assert (got.a, got.b, got.kept) == (2.0 * scale, 1e300, 7.0)
    else:
        with pytest.raises(InvalidInputError, match="scale"):
            scaled_fields(Noise(), scale, ("a",))
    if ok and scale > 1e9:
        with pytest.raises(InvalidInputError, match="overflow"):
            scaled_fields(Noise(), scale, ("a", "b"))


@settings(max_examples=100, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10), st.booleans(), st.none(),
                 st.text(max_size=2)))
def test_scale_factor_is_a_finite_float_at_least_zero_or_a_typed_error(value):
    from whisker_io.validation import scale_factor

    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value >= 0
    if ok:
        assert scale_factor(value, "odometry_scale") == float(value)
    else:
        with pytest.raises(InvalidInputError, match="odometry_scale"):
            scale_factor(value, "odometry_scale")
