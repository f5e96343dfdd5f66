"""Field checks declared next to each field (``checked``) and the one validator (``validate_fields``).

Three parts: the validator on small hand-made dataclasses (every option, with the
messages written out by hand); a property test over every configuration class of the
packages that declares its checks (found by reading the sources): the defaults build,
and a drawn wrong-kind or out-of-range value of any declared field raises the error its
declaration names (:class:`ConfigError` unless it says otherwise) with its message; and
a guard that no ``__post_init__`` goes back to checking a field by hand with
``config_field`` when the check could be declared, nor, in a class that declares its
checks, with ``finite_scalar`` / ``whole_number``.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import math
import types
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from whisker_io.errors import ConfigError, InvalidInputError, ShapeError, UnknownFieldError
from whisker_io.validation import (CHECK_KEY, ConfigDataclass, FieldCheck, checked, config_field, field_checks,
                                   finite_scalar, validate_fields, whole_number)

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cansim", "maps", "whisker_io")


# ------------------------------------------------------------------ the validator by hand
@dataclass(frozen=True)
class Probe:
    count: int = checked(3, int, minimum=1, maximum=10)
    width: int = checked(7, int, minimum=1, odd=True, hint="a kernel is centred on a cell")
    radius_m: float = checked(0.5, float, above=0, hint="give metres")
    fraction: float = checked(0.25, float, minimum=0, maximum=1)
    enabled: bool = checked(False, bool)
    mode: str = checked("fast", str, choices=("fast", "exact"))
    limit: int | None = checked(None, int, minimum=0, optional=True)
    sizes: tuple[int, ...] = checked(kind=int, default_factory=lambda: 4, minimum=2)
    note: str = "free"  # not checked

    def __post_init__(self) -> None:
        validate_fields(self)


@dataclass(frozen=True)
class Narrower(Probe):
    count: int = 5  # a new default only: the base's check still applies


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"count": 0}, "count must be an integer >= 1 and <= 10, got 0"),
        ({"count": 11}, "count must be an integer >= 1 and <= 10, got 11"),
        ({"count": 2.0}, "count must be an integer >= 1 and <= 10, got 2.0"),
        ({"count": True}, "count must be an integer >= 1 and <= 10, got True"),
        ({"count": "3"}, "count must be an integer >= 1 and <= 10, got '3'"),
        ({"width": 4}, "width must be an odd integer >= 1, got 4; a kernel is centred on a cell"),
        ({"width": -1}, "width must be an odd integer >= 1, got -1; a kernel is centred on a cell"),
        ({"radius_m": 0}, "radius_m must be a finite number > 0, got 0; give metres"),
        ({"radius_m": math.nan}, "radius_m must be a finite number > 0, got nan; give metres"),
        ({"radius_m": math.inf}, "radius_m must be a finite number > 0, got inf; give metres"),
        ({"fraction": -0.1}, "fraction must be a finite number >= 0 and <= 1, got -0.1"),
        ({"fraction": 1.5}, "fraction must be a finite number >= 0 and <= 1, got 1.5"),
        ({"enabled": 1}, "enabled must be a boolean (True or False), got 1"),
        ({"mode": "slow"}, "mode must be one of 'fast', 'exact', got 'slow'"),
        ({"mode": 1}, "mode must be one of 'fast', 'exact', got 1"),
        ({"limit": -1}, "limit must be an integer >= 0 or None, got -1"),
        ({"sizes": 1}, "sizes must be an integer >= 2, got 1"),
    ],
)
def test_each_option_refuses_with_config_fields_message(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as info:
        Probe(**kwargs)
    assert str(info.value) == message
    assert isinstance(info.value, InvalidInputError)  # the one error tree


def test_edges_and_none_are_accepted() -> None:
    p = Probe(count=10, width=1, radius_m=1e-12, fraction=1, enabled=True, mode="exact", limit=0, sizes=2)
    assert (p.count, p.width, p.fraction, p.limit, p.sizes) == (10, 1, 1, 0, 2)
    assert Probe(count=1, fraction=0).count == 1
    assert Probe().limit is None and Probe().note == "free"
    assert Probe(note=3).note == 3  # an undeclared field is not checked


def test_default_factory_is_called_and_checked() -> None:
    assert Probe().sizes == 4
    assert Probe(sizes=9).sizes == 9


def test_numpy_values_are_made_plain_first() -> None:
    p = Probe(count=np.int64(4), radius_m=np.float32(0.5), enabled=np.bool_(True))
    assert type(p.count) is int and type(p.radius_m) is float and p.enabled is True
    assert p == Probe(count=4, radius_m=0.5, enabled=True)


def test_a_redeclared_default_keeps_the_base_check() -> None:
    assert Narrower().count == 5
    assert [n for n, _ in field_checks(Narrower)] == [n for n, _ in field_checks(Probe)]
    with pytest.raises(ConfigError, match=r"^count must be an integer >= 1 and <= 10, got 0$"):
        Narrower(count=0)


def test_fields_are_checked_in_field_order() -> None:
    with pytest.raises(ConfigError, match="^count "):
        Probe(count=0, radius_m=-1)
    assert [n for n, _ in field_checks(Probe)] == ["count", "width", "radius_m", "fraction", "enabled", "mode", "limit",
                                                   "sizes"]


def test_the_check_sits_in_the_field_metadata() -> None:
    f = {f.name: f for f in dataclasses.fields(Probe)}
    assert f["radius_m"].metadata[CHECK_KEY] == FieldCheck(float, above=0, hint="give metres")
    assert CHECK_KEY not in f["note"].metadata
    g = checked(1, int, minimum=0, metadata={"unit": "cells"}, compare=False)
    assert g.metadata["unit"] == "cells" and g.metadata[CHECK_KEY].minimum == 0 and g.compare is False


# ------------------------------------------------- the error, label, reader and message options
@dataclass
class SensorProbe:
    """A sensor-stage class: InvalidInputError, its own labels and messages (as whisker_io's classes)."""

    rate_hz: float = checked(2.0, float, above=0, maximum=10, error=InvalidInputError, reader=finite_scalar,
                             message="{name} must be in (0, 10] Hz, got {value!r}")
    gain: float = checked(1.0, float, minimum=0, error=InvalidInputError, reader=finite_scalar,
                          label="SensorProbe.gain")
    span: int = checked(5, int, minimum=1, error=InvalidInputError, reader=whole_number)
    neighbours: int = checked(3, int, minimum=3, error=InvalidInputError, reader=whole_number,
                              message="{name} must be >= 3 (a plane needs 3 points), got {value!r}")
    frame: str = checked("a", str, choices=("a", "b"), error=InvalidInputError, label="probe frame",
                         message="{name} must be 'a' or 'b', got {value!r}", hint="see the manual")
    width: int = checked(3, int, minimum=1, error=InvalidInputError, message="{name}: want {want}, not {value}")

    def __post_init__(self) -> None:
        validate_fields(self)


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        # reader=finite_scalar: a value that is no number gets finite_scalar's error and message
        ({"rate_hz": math.nan}, InvalidInputError, "rate_hz must be finite, got nan"),
        ({"rate_hz": -math.inf}, InvalidInputError, "rate_hz must be finite, got -inf"),
        ({"rate_hz": "2"}, InvalidInputError, "rate_hz must be real numbers, got '2'"),
        ({"rate_hz": True}, InvalidInputError, "rate_hz must be real numbers, got True"),
        ({"rate_hz": [1.0, 2.0]}, ShapeError, "rate_hz must be a single number, got an array of shape (2,)"),
        # ... and a number out of range the declared message
        ({"rate_hz": 0}, InvalidInputError, "rate_hz must be in (0, 10] Hz, got 0"),
        ({"rate_hz": 10.5}, InvalidInputError, "rate_hz must be in (0, 10] Hz, got 10.5"),
        # label: the name shown, in the reader's message as in the range message (default wording)
        ({"gain": math.nan}, InvalidInputError, "SensorProbe.gain must be finite, got nan"),
        ({"gain": -0.5}, InvalidInputError, "SensorProbe.gain must be a finite number >= 0, got -0.5"),
        # reader=whole_number: whole_number's messages (its minimum message is the default wording)
        ({"span": 2.5}, InvalidInputError, "span must be a whole number, got 2.5"),
        ({"span": "5"}, InvalidInputError, "span must be real numbers, got '5'"),
        ({"span": 0}, InvalidInputError, "span must be an integer >= 1, got 0"),
        ({"span": -3.0}, InvalidInputError, "span must be an integer >= 1, got -3.0"),
        ({"neighbours": 2}, InvalidInputError, "neighbours must be >= 3 (a plane needs 3 points), got 2"),
        # a name with choices: a wrong kind and a wrong name share the message; the hint follows it
        ({"frame": "c"}, InvalidInputError, "probe frame must be 'a' or 'b', got 'c'; see the manual"),
        ({"frame": 1}, InvalidInputError, "probe frame must be 'a' or 'b', got 1; see the manual"),
        # no reader: the kind is config_field's (no 2.0 for an int), the template may use {want} and {value}
        ({"width": 2.0}, InvalidInputError, "width: want an integer >= 1, not 2.0"),
        ({"width": 0}, InvalidInputError, "width: want an integer >= 1, not 0"),
    ],
)
def test_a_declared_error_label_reader_and_message_are_used(kwargs: dict[str, Any], error: type,
                                                            message: str) -> None:
    with pytest.raises(InvalidInputError) as info:
        SensorProbe(**kwargs)
    assert type(info.value) is error, type(info.value)
    assert str(info.value) == message


def test_a_reader_accepts_what_the_shared_validator_accepts_and_keeps_the_value() -> None:
    p = SensorProbe(rate_hz=10, span=4.0, gain=np.float32(0.5))  # 10 is in (0, 10]; whole_number takes 4.0
    assert (p.rate_hz, p.span, p.gain) == (10, 4.0, 0.5)
    assert type(p.rate_hz) is int and type(p.span) is float  # the value given, not the number read


def test_config_field_takes_the_same_options() -> None:
    assert config_field(3, "n", int, minimum=1, reader=whole_number) == 3
    with pytest.raises(InvalidInputError) as info:
        config_field(-1.0, "x_m", float, above=0, error=InvalidInputError, reader=finite_scalar,
                     message="{name} must be positive, got {value!r}")
    assert type(info.value) is InvalidInputError and str(info.value) == "x_m must be positive, got -1.0"
    with pytest.raises(ConfigError, match=r"^x_m must be a finite number > 0, got -1.0$"):
        config_field(-1.0, "x_m", float, above=0)  # the defaults are unchanged


# ------------------------------------- the store, reader_message and {config.<field>} options
@dataclass(frozen=True)
class RecordProbe:
    """A record that keeps the number read and names another field in its messages (as Axis, SafetyEnvelope)."""

    name: str = "p"
    length_m: float = checked(1.0, float, above=0, store=True, label="probe {config.name!r}: length_m")
    count: int = checked(2, int, minimum=1, reader=whole_number, store=True, reader_message="RecordProbe: {error}")
    step: float = checked(0.5, float, above=0, error=InvalidInputError, reader=finite_scalar, store=True,
                          message="probe {config.name!r}: step must be positive, got {value!r}")

    def __post_init__(self) -> None:
        validate_fields(self)


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        # {config.name!r} in a label: the other field's value, in the default wording
        ({"length_m": 0}, ConfigError, "probe 'p': length_m must be a finite number > 0, got 0"),
        ({"name": "C2", "length_m": "1"}, ConfigError, "probe 'C2': length_m must be a finite number > 0, got '1'"),
        # ... and in a message template
        ({"name": "q", "step": -1}, InvalidInputError, "probe 'q': step must be positive, got -1"),
        ({"step": math.nan}, InvalidInputError, "step must be finite, got nan"),  # the reader's own message
        # reader_message: what the reader refuses is the declared error, its message wrapped
        ({"count": 2.5}, ConfigError, "RecordProbe: count must be a whole number, got 2.5"),
        ({"count": [1, 2]}, ConfigError, "RecordProbe: count must be a single number, got an array of shape (2,)"),
        ({"count": "2"}, ConfigError, "RecordProbe: count must be real numbers, got '2'"),
        ({"count": 0}, ConfigError, "count must be an integer >= 1, got 0"),  # a number out of range: not wrapped
    ],
)
def test_a_template_names_another_field_and_a_reader_refusal_is_rewrapped(kwargs: dict[str, Any], error: type,
                                                                           message: str) -> None:
    with pytest.raises(InvalidInputError) as info:
        RecordProbe(**kwargs)
    assert type(info.value) is error, type(info.value)
    assert str(info.value) == message


def test_store_keeps_the_number_read() -> None:
    p = RecordProbe(length_m=1, count=3.0, step=np.float32(0.25))
    assert (type(p.length_m), type(p.count), type(p.step)) == (float, int, float)
    assert (p.length_m, p.count, p.step) == (1.0, 3, 0.25)
    assert type(RecordProbe(step=2).step) is float


@settings(max_examples=200, deadline=None)
@given(name=st.text(max_size=6), length=st.one_of(st.integers(1, 10**6), st.floats(1e-9, 1e6)),
       count=st.integers(1, 10**9), as_float=st.booleans())
def test_stored_values_equal_the_given_numbers_and_templates_name_the_field(name: str, length: float, count: int,
                                                                           as_float: bool) -> None:
    p = RecordProbe(name=name, length_m=length, count=float(count) if as_float else count, step=length)
    assert type(p.length_m) is float and p.length_m == float(length) and p.step == float(length)
    assert type(p.count) is int and p.count == count
    with pytest.raises(ConfigError) as info:
        RecordProbe(name=name, length_m=-length)
    assert str(info.value) == f"probe {name!r}: length_m must be a finite number > 0, got {-length!r}"


@pytest.mark.parametrize(
    "declare",
    [
        lambda: checked(1),  # no kind
        lambda: checked(1, list),  # not int, float, bool or str
        lambda: checked("a", str, minimum=0),  # bounds on a name
        lambda: checked(1.0, float, odd=True),  # odd on a float
        lambda: checked(1, int, choices=("a",)),  # choices on a number
        lambda: checked(1.0, float, error=ValueError),  # outside the project's error tree
        lambda: checked(1.0, float, error="ConfigError"),  # not a class
        lambda: checked(1.0, float, reader=whole_number),  # whole_number reads ints
        lambda: checked(1, int, reader=finite_scalar),  # finite_scalar reads floats
        lambda: checked(1.0, float, reader=float),  # not a shared reader
        lambda: checked(1.0, float, message="{nme} must be > 0"),  # a field the template does not have
        lambda: checked(1.0, float, message="{0} must be > 0"),  # a positional field
        lambda: checked(1.0, float, label=3),  # a label is text
        lambda: checked(1.0, float, label="axis {config.name!r"),  # an unclosed field
        lambda: checked(1.0, float, label="axis {name}"),  # a label names the configuration's fields only
        lambda: checked(1.0, float, reader_message="wrapped: {error}"),  # no reader to wrap
        lambda: checked(1.0, float, reader=finite_scalar, reader_message="wrapped: {err}"),  # not the reader's error
        lambda: checked("a", str, store=True),  # only a number is read and stored
        lambda: checked(True, bool, store=True),
    ],
)
def test_a_malformed_declaration_fails_when_the_class_is_written(declare: Any) -> None:
    with pytest.raises(TypeError):
        declare()


# ------------------------------------------------------------ every declared config class
def _declaring_classes() -> list[tuple[str, str]]:
    """(module, class) of every class in the packages with a field declared by ``checked(...)``."""
    found = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef) and any(
                    isinstance(s, ast.AnnAssign) and isinstance(s.value, ast.Call)
                    and getattr(s.value.func, "id", None) == "checked"
                    for s in node.body
                ):
                    found.append((module, node.name))
    return found


def _load(module: str, name: str) -> type:
    return getattr(importlib.import_module(module), name)


CLASSES = [_load(m, n) for m, n in _declaring_classes()]
#: the constructor's required fields, for the classes that have some
REQUIRED: dict[str, dict[str, Any]] = {
    "cansim.studies.ch5_object_maps.StudyConfig": {
        "n_loops": 1, "noise_scale": 0.3, "thresholds": {"svr": (0.4, 0.5)}, "radial_model": None, "seed": 0},
    "cansim.axes.Axis": {"name": "x", "size": 4, "step": 0.1},
    "whisker_io.array.geometry.WhiskerModule": {"name": "C2", "column": "C", "row": 2,
                                                "base_position_m": (0.01, 0.02, 0.0), "length_m": 0.1},
}


def _qualname(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def _build(cls: type, **changes: Any) -> Any:
    return cls(**{**REQUIRED.get(_qualname(cls), {}), **changes})


def test_the_converted_classes_are_found() -> None:
    names = {c.__name__ for c in CLASSES}
    expected = {  # the classes converted in issue 21 (a guard against a discovery that finds nothing)
        "MapConfig", "WhiskGraphConfig", "SurfaceFieldConfig", "SurfaceMatchConfig", "LeakyIntegrator",
        "TactileTemplateConfig", "TactileSequenceConfig", "VisualTemplateConfig", "WhiskFrontEndConfig",
        "LocalViewParams", "SlamConfig", "RatSLAMConfig", "WhiskerRatSLAMConfig", "SpikingPoseCellParams",
        "ContactSeekingParams", "PlacementParams", "StudyConfig", "NeuronParams", "RotationRingParams",
        # the sensor stage and the engine, with their own error classes and messages
        "WhiskPattern", "RCP", "RetractAtMax", "ContactAngleParams", "DetectionParams", "PFHParams",
        "OdometryNoise", "WhiskSchedule", "SignalParams", "SweepParams", "ContactNoise", "LoopShape",
        "AttractorParams", "PlanarMotion", "SpikingParams",
        # messages naming another field ({config.name!r}), reader errors re-wrapped, numbers stored back
        "Axis", "WhiskerModule", "SafetyEnvelope", "MazeRoute",
    }
    assert expected <= names, expected - names
    for cls in CLASSES:
        assert dataclasses.is_dataclass(cls) and field_checks(cls), cls


@pytest.mark.parametrize("cls", CLASSES, ids=_qualname)
def test_a_misspelt_field_is_an_unknown_field_error_naming_the_field_meant(cls: type) -> None:
    assert issubclass(cls, ConfigDataclass), f"{cls.__name__} declares checked fields: derive it from ConfigDataclass"
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    meant = max(names, key=len)
    typo = meant[:-1] + ("x" if meant[-1] != "x" else "y")  # one letter changed
    with pytest.raises(UnknownFieldError, match=rf"{cls.__name__} has no field '{typo}' \(did you mean '{meant}'\?\)"):
        _build(cls, **{typo: 1})
    base = _build(cls)
    with pytest.raises(UnknownFieldError, match=f"has no field '{typo}'"):
        dataclasses.replace(base, **{typo: 1})
    with pytest.raises(UnknownFieldError, match=rf"takes at most {len(names)} positional arguments, got {len(names) + 1}"):
        cls(*[getattr(base, n) for n in names], 0)


@dataclass(frozen=True)
class _Window(ConfigDataclass):
    start_s: float = checked(0.0, float, minimum=0)
    stop_s: float = checked(1.0, float, minimum=0)

    def __post_init__(self) -> None:
        validate_fields(self)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["start_s", "stop_s"]) | st.text(min_size=1, max_size=8),
                       st.floats(0, 10), max_size=3),
       st.lists(st.floats(0, 10), max_size=3))
def test_only_the_fields_pass_the_name_check(kwargs: dict[str, float], args: list[float]) -> None:
    """Known names and at most two positional values build (or fail a field rule / Python's own duplicate
    check); any other name or a third positional value is an UnknownFieldError (a ConfigError)."""
    foreign = [k for k in kwargs if k not in ("start_s", "stop_s")]
    try:
        w = _Window(*args, **kwargs)
    except UnknownFieldError as exc:
        assert isinstance(exc, ConfigError) and isinstance(exc, TypeError)
        if foreign:
            assert f"has no field {foreign[0]!r}" in str(exc)
        elif len(args) > 2:
            assert "takes at most 2 positional arguments" in str(exc)
        else:  # every value drawn is >= 0: no field rule refuses it
            pytest.fail(f"a valid call was refused: {exc}")
        return
    except TypeError as exc:  # Python's own: a field given positionally and by name
        assert not isinstance(exc, ConfigError)
        assert not foreign and len(args) <= 2 and "multiple values" in str(exc), exc
        return
    assert not foreign and len(args) <= 2
    given_values = dict(zip(("start_s", "stop_s"), args)) | kwargs
    assert (w.start_s, w.stop_s) == (given_values.get("start_s", 0.0), given_values.get("stop_s", 1.0))


@pytest.mark.parametrize("cls", CLASSES, ids=_qualname)
def test_the_signature_shows_the_fields_not_new(cls: type) -> None:
    """``inspect.signature`` (and the API docs, which read it) show the constructor's fields, not ``(*args, **kwargs)``."""
    import inspect

    names = [f.name for f in dataclasses.fields(cls) if f.init]
    assert list(inspect.signature(cls).parameters) == names
    with pytest.raises(AttributeError):
        _build(cls).__signature__  # noqa: B018 - an instance is no callable: no signature of its own


def test_a_subclass_with_its_own_init_is_checked_against_it_and_a_derived_field_is_named() -> None:
    from whisker_io.array.control import RCP, WhiskPattern

    @dataclass(frozen=True)
    class Tagged(WhiskPattern):
        def __init__(self, tag: str = "", **kwargs: Any) -> None:  # any keyword: passed on, nothing to check here
            super().__init__(**kwargs)

    assert dataclasses.astuple(Tagged(tag="x")) == dataclasses.astuple(WhiskPattern())

    @dataclass(frozen=True)
    class Named(WhiskPattern):
        def __init__(self, tag: str) -> None:
            super().__init__()

    assert dataclasses.astuple(Named(tag="x")) == dataclasses.astuple(WhiskPattern())
    with pytest.raises(UnknownFieldError, match="Named has no field 'tags' \\(did you mean 'tag'\\?\\); its fields: tag$"):
        Named(tags="x")
    with pytest.raises(UnknownFieldError, match="RCP's field 'amplitudes_rad' is derived from the others, not given"):
        RCP(amplitudes_rad=1.0)


def test_the_check_follows_the_kinds_of_the_init_parameters() -> None:
    """Keyword-only fields are no positional slots, ``*args`` takes any number, positional-only names are no
    keywords; a name the subclass's own __init__ takes is never called derived."""

    @dataclass(frozen=True, kw_only=True)
    class K(ConfigDataclass):
        a: float = 1.0

    with pytest.raises(UnknownFieldError, match="K takes at most 0 positional arguments, got 1; give them by name: a"):
        K(1.0)
    assert K(a=2.0).a == 2.0

    class V(ConfigDataclass):
        def __init__(self, x: float, *rest: float) -> None:
            self.total = x + sum(rest)

    assert V(1.0, 2.0, 3.0).total == 6.0
    with pytest.raises(UnknownFieldError, match="V has no field 'y'"):
        V(1.0, y=2.0)

    class P(ConfigDataclass):
        def __init__(self, x: float, /) -> None:
            self.x = x

    assert P(1.0).x == 1.0
    with pytest.raises(UnknownFieldError, match="P has no field 'x'"):
        P(x=1.0)

    @dataclass(frozen=True)
    class D(ConfigDataclass):
        d: float = dataclasses.field(default=0.0, init=False)

        def __init__(self, d: float = 0.0) -> None:  # takes the derived field's name itself
            object.__setattr__(self, "d", 2 * d)

    with pytest.raises(UnknownFieldError, match="D has no field 'x'"):
        D(d=3.0, x=1.0)  # x is the culprit, not d
    assert D(d=3.0).d == 6.0


def test_a_misspelt_key_in_a_saved_description_keeps_its_advice() -> None:
    from cansim.models.ratslam_config import RatSLAMConfig

    d = RatSLAMConfig().to_dict()
    d["xy_cell"] = 23
    with pytest.raises(UnknownFieldError, match=r"^not a RatSLAMConfig description: RatSLAMConfig has no field 'xy_cell' "
                                                r"\(did you mean 'xy_cells'\?\)"):
        RatSLAMConfig.from_dict(d)
    nested = RatSLAMConfig().to_dict()
    nested["attractor"]["exc_widht"] = 7
    with pytest.raises(UnknownFieldError, match=r"^not a RatSLAMConfig description: AttractorParams has no field "
                                                r"'exc_widht' \(did you mean 'exc_width'\?\)"):
        RatSLAMConfig.from_dict(nested)


def test_a_subclass_field_is_known_and_pickling_still_works() -> None:
    import copy
    import pickle

    from cansim.models.ratslam_config import RatSLAMConfig

    cfg = RatSLAMConfig(xy_cells=23, cell_size_m=0.5)  # a SlamConfig field and one of the subclass
    for protocol in range(pickle.HIGHEST_PROTOCOL + 1):
        assert pickle.loads(pickle.dumps(cfg, protocol=protocol)) == cfg
    assert copy.deepcopy(cfg) == cfg and copy.copy(cfg) == cfg
    assert dataclasses.replace(cfg, heading_cells=12) == RatSLAMConfig(xy_cells=23, cell_size_m=0.5, heading_cells=12)
    with pytest.raises(UnknownFieldError, match="RatSLAMConfig has no field 'heading_cell'"):
        dataclasses.replace(cfg, heading_cell=12)
    with pytest.raises(ConfigError, match="pc_dim_xy is OpenRatSLAM's name: use xy_cells"):
        RatSLAMConfig(pc_dim_xy=23)


@pytest.mark.parametrize("cls", CLASSES, ids=_qualname)
def test_the_defaults_build_and_pass_their_declared_checks(cls: type) -> None:
    config = _build(cls)
    for name, rule in field_checks(cls):
        assert rule.check(getattr(config, name), name, config) is getattr(config, name)


def _bad_values(rule: FieldCheck) -> st.SearchStrategy[Any]:
    """Values that ``rule`` refuses: another kind, or out of its range (drawn independently of the code)."""
    wrong = [st.text(max_size=4).filter(lambda s: rule.choices is None or s not in rule.choices)
             if rule.kind is str and rule.choices is not None else st.nothing(),
             st.just([1]), st.just(1 + 2j)]
    if not rule.optional:
        wrong.append(st.none())
    if rule.kind in (int, float):
        wrong += [st.text(max_size=3), st.booleans(), st.sampled_from([math.nan, math.inf, -math.inf])]
    if rule.kind is int:
        wrong.append(st.floats(-1e6, 1e6).filter(lambda x: not x.is_integer()))
        if rule.odd:
            wrong.append(st.integers(-10**6, 10**6).map(lambda k: 2 * k).filter(
                lambda v: (rule.minimum is None or v >= rule.minimum) and (rule.maximum is None or v <= rule.maximum)))
    number = st.integers(1, 10**6) if rule.kind is int else st.floats(1e-9, 1e6)
    if rule.minimum is not None:
        wrong.append(number.map(lambda d: rule.minimum - d))
    if rule.above is not None:
        wrong.append(st.one_of(st.just(rule.above), number.map(lambda d: rule.above - d)))
    if rule.maximum is not None:
        wrong.append(number.map(lambda d: rule.maximum + d))
    if rule.kind is bool:
        wrong += [st.integers(0, 1), st.text(max_size=3)]
    if rule.kind is str:
        wrong += [st.integers(), st.floats(allow_nan=False), st.booleans()]
    return st.one_of(wrong)


FIELDS = [(cls, name, rule) for cls in CLASSES for name, rule in field_checks(cls)]


def test_the_new_options_are_declared_somewhere() -> None:
    """The property test below reaches fields with each option (else it would not test them)."""
    rules = [rule for _, _, rule in FIELDS]
    assert any(r.error is InvalidInputError for r in rules) and any(r.error is ConfigError for r in rules)
    assert {r.reader for r in rules} >= {None, finite_scalar, whole_number}
    assert any(r.label is not None for r in rules) and any(r.message is not None for r in rules)
    assert any(r.reader_message is not None for r in rules) and any(r.store for r in rules)
    assert any("{config." in (r.label or "") for r in rules) and any("{config." in (r.message or "") for r in rules)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(data=st.data())
def test_a_bad_declared_field_raises_its_declared_error_naming_it(data: st.DataObject) -> None:
    cls, name, rule = data.draw(st.sampled_from(FIELDS), label="class, field")
    value = data.draw(_bad_values(rule), label=name)
    with pytest.raises(InvalidInputError) as info:  # the one error tree
        _build(cls, **{name: value})
    good = _build(cls)  # the other fields, as a template names them ({config.name!r})
    config = types.SimpleNamespace(**{f.name: getattr(good, f.name) for f in dataclasses.fields(cls)})
    label = name if rule.label is None else rule.label.format(config=config)
    text = str(info.value)
    shown = tuple(value) if isinstance(value, list) else value  # validate_fields makes a list a tuple first
    hint = f"; {rule.hint}" if rule.hint else ""
    declared = (None if rule.message is None
                else rule.message.format(name=label, value=shown, want="", config=config) + hint)
    if rule.reader is not None:
        try:
            rule.reader(shown, label)
        except InvalidInputError as exc:  # a value that is no number: the reader's error and message, naming the field
            if rule.reader_message is None:
                assert type(info.value) is type(exc) and text == str(exc), (cls, text)
            else:  # ... re-raised as the declared error
                assert type(info.value) is rule.error, (cls, name, type(info.value))
                assert text == rule.reader_message.format(error=exc, config=config), (cls, text)
            assert label in text, (cls, text)
            return
    assert type(info.value) is rule.error, (cls, name, type(info.value))
    if declared is None:
        assert text.startswith(f"{label} must be "), (cls, text)
    elif "{want" not in rule.message:
        assert text == declared, (cls, text)


# ------------------------------------------------------------ the old pattern stays out
def _declares_checks(cls: ast.ClassDef) -> bool:
    return any(isinstance(s, ast.AnnAssign) and isinstance(s.value, ast.Call)
               and getattr(s.value.func, "id", None) == "checked" for s in cls.body)


def _post_init_calls(tree: ast.AST, names: tuple[str, ...], declaring_only: bool
                     ) -> list[tuple[str, ast.Call, set[str]]]:
    """(class, call, field names) of every call of ``names`` in a ``__post_init__`` of ``tree``."""
    out = []
    for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
        if declaring_only and not _declares_checks(cls):
            continue
        fields = {s.target.id for s in cls.body if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)}
        for fn in cls.body:
            if isinstance(fn, ast.FunctionDef) and fn.name == "__post_init__":
                for call in (c for c in ast.walk(fn) if isinstance(c, ast.Call)):
                    if getattr(call.func, "id", getattr(call.func, "attr", None)) in names:
                        out.append((cls.name, call, fields))
    return out


def _calls_in_post_init(names: tuple[str, ...] = ("config_field",), declaring_only: bool = False
                        ) -> list[tuple[str, str, ast.Call, set[str]]]:
    out = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            out += [(str(path.relative_to(ROOT)), *found) for found in _post_init_calls(tree, names, declaring_only)]
    return out


def _mentions_self(node: ast.AST) -> bool:
    return any(isinstance(n, ast.Name) and n.id == "self" for n in ast.walk(node))


def test_no_post_init_checks_a_field_by_hand_that_could_be_declared() -> None:
    """A ``config_field`` call in a ``__post_init__`` must tie fields together (a bound read from
    ``self``) or check something that is not one field (entries of a tuple, a prefixed name);
    a plain per-field check belongs in the field's ``checked(...)`` declaration."""
    calls = _calls_in_post_init()
    assert calls  # the guard reads real code (MapConfig checks its pc_shape entries this way)
    offenders = []
    for path, cls, call, fields in calls:
        name = call.args[1] if len(call.args) > 1 else None
        per_field = isinstance(name, ast.Name) or (isinstance(name, ast.Constant) and name.value in fields)
        cross_field = any(_mentions_self(k.value) for k in call.keywords) or any(_mentions_self(a) for a in call.args[2:])
        if per_field and not cross_field:
            offenders.append(f"{path}: {cls}: {ast.unparse(call)}")
    assert not offenders, "declare these with checked(...):\n" + "\n".join(offenders)


READERS = ("finite_scalar", "whole_number", "config_field")


def _reads_one_field_by_hand(call: ast.Call, fields: set[str]) -> bool:
    value = call.args[0] if call.args else None
    one_field = (  # self.field, or getattr(self, name) in a loop over field names
        isinstance(value, ast.Attribute) and isinstance(value.value, ast.Name) and value.value.id == "self"
        and value.attr in fields
    ) or (isinstance(value, ast.Call) and getattr(value.func, "id", None) == "getattr" and _mentions_self(value))
    by_name = len(call.args) > 1 and (isinstance(call.args[1], ast.Name)
                                      or (isinstance(call.args[1], ast.Constant) and call.args[1].value in fields))
    cross_field = any(_mentions_self(k.value) for k in call.keywords) or any(_mentions_self(a) for a in call.args[2:])
    return (one_field or by_name) and not cross_field


def test_a_declaring_class_reads_no_field_by_hand_with_the_shared_validators() -> None:
    """In a class that declares its checks, ``finite_scalar`` / ``whole_number`` (or
    ``config_field``) on one field in ``__post_init__`` is a check that belongs in the
    field's declaration (``reader=`` keeps the validator's messages); only a value that
    is not one field (an entry of a tuple) or that is tied to another field may be read there."""
    offenders = [f"{path}: {cls}: {ast.unparse(call)}"
                 for path, cls, call, fields in _calls_in_post_init(READERS, declaring_only=True)
                 if _reads_one_field_by_hand(call, fields)]
    assert not offenders, "declare these with checked(..., reader=...):\n" + "\n".join(offenders)


def test_the_guard_flags_a_hand_written_read_and_spares_the_rest() -> None:
    tree = ast.parse(
        "class Old:\n"
        "    rate_hz: float = checked(1.0, float)\n"
        "    gain: float = 1.0\n"
        "    span: int = 3\n"
        "    shape: tuple = (1, 2)\n"
        "    def __post_init__(self):\n"
        "        validate_fields(self)\n"
        "        if not finite_scalar(self.gain, 'gain') >= 0:\n"  # flagged: one field
        "            raise InvalidInputError('gain')\n"
        "        for name in ('gain', 'span'):\n"
        "            whole_number(getattr(self, name), name)\n"  # flagged: a loop over fields
        "        for n in self.shape:\n"
        "            config_field(n, 'shape entries', int, minimum=1)\n"  # spared: entries of a tuple
        "        config_field(self.span, 'span', int, maximum=self.rate_hz)\n"  # spared: tied to another field
        "class Untouched:\n"
        "    gain: float = 1.0\n"
        "    def __post_init__(self):\n"
        "        finite_scalar(self.gain, 'gain')\n")  # spared here: the class declares nothing (yet)
    found = _post_init_calls(tree, READERS, declaring_only=True)
    assert [c for c, _, _ in found] == ["Old"] * 4
    flagged = [ast.unparse(call) for _, call, fields in found if _reads_one_field_by_hand(call, fields)]
    assert sorted(flagged) == ["finite_scalar(self.gain, 'gain')", "whole_number(getattr(self, name), name)"]
