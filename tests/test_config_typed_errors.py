"""Configurations that checked their fields by hand and let bad values through untyped (issues 21 and 25).

Before the fix, about 1,000 bad values (text, NaN, bools, arrays, huge ints, fractions where
counts go) given to these eight classes escaped as ``TypeError``, ``IndexError``,
``ValueError`` or ``OverflowError`` - or were accepted (NaN, True, 2.5). Every field now
declares its check or is read by :func:`whisker_io.validation.number_tuple`: a bad value is
an :class:`~whisker_io.errors.InvalidInputError` (or a ShapeError, one of them) naming the field.
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.testing.worlds import Ch3OdometryNoise, LoopRoute
from whisker_io.errors import InvalidInputError
from whisker_io.features.tactile_image import TactileImageParams
from whisker_io.hw.usb_array import FrameLayout
from whisker_io.radial.datasets import EvansSetParams, TrainingSetParams, ValidationSetParams
from whisker_io.radial.models import SearchParams
from whisker_io.validation import number_tuple

CLASSES = [Ch3OdometryNoise, LoopRoute, TactileImageParams, FrameLayout, TrainingSetParams, EvansSetParams,
           ValidationSetParams, SearchParams]
BAD = [math.nan, math.inf, -math.inf, "x", True, None, [1, 2], np.array([1.0, 2.0]), 10**400, 1 + 2j, object(),
       (), (math.nan, 1.0), ("a", "b"), -1, 0, 2.5, Fraction(1, 3)]
FIELDS = [(c, f.name) for c in CLASSES for f in dataclasses.fields(c)]


@settings(max_examples=300, deadline=None)
@given(where=st.sampled_from(FIELDS), value=st.sampled_from(BAD))
def test_a_bad_field_is_refused_with_a_typed_error_or_accepted(where, value):
    cls, name = where
    try:
        cls(**{name: value})
    except InvalidInputError as exc:  # ShapeError is one too
        assert any(f.name in str(exc) for f in dataclasses.fields(cls)), str(exc)  # says which field to mend
        return
    # accepted: never a non-finite number, never True for a number (only a bool field takes it)
    kind = {f.name: f.type for f in dataclasses.fields(cls)}[name]
    assert not (isinstance(value, float) and not math.isfinite(value)), (cls.__name__, name, value)
    assert value is not True or kind == "bool", (cls.__name__, name, value)


@pytest.mark.parametrize("cls,kwargs", [
    (TrainingSetParams, dict(contact_angle_deg=math.nan)),  # was a TypeError (unpacking a float)
    (TrainingSetParams, dict(n_distances=2.5)),  # was accepted
    (EvansSetParams, dict(distances_m="x")),  # was an IndexError
    (EvansSetParams, dict(distances_m=(0.08, 0.18, 2.5))),  # a fractional grid size was accepted
    (ValidationSetParams, dict(frequency_range_hz=math.nan)),  # was a TypeError
    (ValidationSetParams, dict(n_waypoints=True)),  # was accepted as 1
    (SearchParams, dict(cv_folds="x")),  # was a TypeError
    (SearchParams, dict(svr_C=(1.0, math.nan))),  # was accepted
    (TactileImageParams, dict(height_range_m="x")),  # was a ValueError
    (FrameLayout, dict(angle_lsb_rad=10**400)),  # was an OverflowError
    (FrameLayout, dict(modules=("C1", 3))),  # was accepted
    (Ch3OdometryNoise, dict(angular_std_deg="x")),  # was a TypeError
    (LoopRoute, dict(corner_radius_m=np.array([1.0, 2.0]))),  # was a ValueError
    (LoopRoute, dict(step_m=1e-12)),  # 10^13 places: would not end
])
def test_regressions_of_the_untyped_errors(cls, kwargs):
    with pytest.raises(InvalidInputError):
        cls(**kwargs)


def test_defaults_and_the_reduced_sets_still_build():
    for cls in CLASSES:
        cls()
    TrainingSetParams().reduced(), EvansSetParams().reduced(), ValidationSetParams().reduced(), SearchParams().quick()


def test_number_tuple_by_hand():
    assert number_tuple([0.2, 2.5], "f", length=2, above=0) == (0.2, 2.5)
    assert number_tuple(np.array([2.0, 3.0]), "d", whole=True) == (2, 3)
    for bad, kw in [("ab", {}), (3.0, {}), ([], {}), ([True], {}), ([1.5], dict(whole=True)), ([0.0], dict(above=0)),
                    ([-1.0], dict(minimum=0)), ([1.0, 2.0, 3.0], dict(length=2)), ([[1.0]], {})]:
        with pytest.raises(InvalidInputError):
            number_tuple(bad, "f", **kw)


# ------------------------------------------- the readers that now use the one field check (issue 21)
@pytest.mark.parametrize("key", ["low", "high"])
@pytest.mark.parametrize("value", [10**400, -(10**400)])
def test_a_sweep_specs_integer_too_large_for_a_float_is_a_config_error(key, value):
    """TOML integers have no size limit: a huge one raised a bare OverflowError before."""
    from cansim.errors import ConfigError
    from cansim.tools.sweep import parse_spec

    spec = {"experiment": "bump", "metrics": ["x"],
            "random": {"n_samples": 2, "b": {"distribution": "uniform", "low": 0.0, "high": 1.0, key: value}}}
    with pytest.raises(ConfigError) as info:
        parse_spec(spec)
    assert str(info.value) == f"random.b.{key}: expected a finite number, got {value!r}"


@pytest.mark.parametrize(("key", "value", "message"), [
    ("n_seeds", 0, "n_seeds: expected an integer >= 1, got 0"),
    ("n_seeds", 2.0, "n_seeds: expected an integer >= 1, got 2.0"),
    ("base_seed", True, "base_seed: expected an integer >= 0, got True"),
    ("base_seed", -1, "base_seed: expected an integer >= 0, got -1"),
])
def test_a_sweep_specs_counts_keep_their_messages(key, value, message):
    from cansim.errors import ConfigError
    from cansim.tools.sweep import parse_spec

    with pytest.raises(ConfigError) as info:
        parse_spec({"experiment": "bump", "metrics": ["x"], key: value})
    assert str(info.value) == message


@settings(max_examples=100, deadline=None)
@given(value=st.one_of(st.sampled_from([math.nan, math.inf, -math.inf, 10**400, "x", True, None, [1.0]]),
                       st.text(max_size=3)))
def test_an_experiment_parameter_of_a_wrong_kind_is_refused_naming_it(value):
    from cansim.experiments.params import resolve

    defaults = {"count": 3, "rate_hz": 1.0, "on": True, "mode": "a"}
    wants = {"count": "an integer", "rate_hz": "a finite number", "on": "true or false"}
    for key, want in wants.items():
        if (key == "on" and isinstance(value, bool)) or (key == "count" and isinstance(value, int)
                                                          and not isinstance(value, bool)):
            continue  # what the parameter takes (an integer of any size is a count)
        with pytest.raises(InvalidInputError) as info:
            resolve({key: value}, defaults, name="exp")
        assert str(info.value) == f"exp: {key} must be {want}, got {value!r}"


def test_an_experiment_parameter_is_kept_as_its_defaults_type():
    from cansim.experiments.params import checked_seed, resolve

    out = resolve({"count": 4.0, "rate_hz": 2, "on": np.bool_(False)}, {"count": 3, "rate_hz": 1.0, "on": True},
                  name="exp")
    assert (out, [type(v) for v in out.values()]) == ({"count": 4, "rate_hz": 2.0, "on": False}, [int, float, bool])
    assert checked_seed(np.int64(7)) == 7 and type(checked_seed(np.int64(7))) is int


def test_a_slip_angle_too_large_for_a_float_is_refused_typed():
    from whisker_io.sim.signals import WhiskContact

    with pytest.raises(InvalidInputError, match="^slip_rad must be a float .*too large for a float$"):
        WhiskContact(0.1, 0.05, 0.1, slip_rad=10**400)
    assert WhiskContact(0.1, 0.05, 0.1, slip_rad=3).slip_rad == 3.0
