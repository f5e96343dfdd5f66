"""Field checks declared next to each field (``checked``) and the one validator (``validate_fields``).

Three parts: the validator on small hand-made dataclasses (every option, with the
messages written out by hand); a property test over every configuration class of the
packages that declares its checks (found by reading the sources): the defaults build,
and a drawn wrong-kind or out-of-range value of any declared field raises
:class:`ConfigError` naming that field; and a guard that no ``__post_init__`` goes back
to checking a field by hand with ``config_field`` when the check could be declared.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from whisker_io.errors import ConfigError, InvalidInputError
from whisker_io.validation import CHECK_KEY, FieldCheck, checked, field_checks, validate_fields

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


@pytest.mark.parametrize(
    "declare",
    [
        lambda: checked(1),  # no kind
        lambda: checked(1, list),  # not int, float, bool or str
        lambda: checked("a", str, minimum=0),  # bounds on a name
        lambda: checked(1.0, float, odd=True),  # odd on a float
        lambda: checked(1, int, choices=("a",)),  # choices on a number
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
    }
    assert expected <= names, expected - names
    for cls in CLASSES:
        assert dataclasses.is_dataclass(cls) and field_checks(cls), cls


@pytest.mark.parametrize("cls", CLASSES, ids=_qualname)
def test_the_defaults_build_and_pass_their_declared_checks(cls: type) -> None:
    config = _build(cls)
    for name, rule in field_checks(cls):
        assert rule.check(getattr(config, name), name) is getattr(config, name)


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


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(data=st.data())
def test_a_bad_declared_field_raises_config_error_naming_it(data: st.DataObject) -> None:
    cls, name, rule = data.draw(st.sampled_from(FIELDS), label="class, field")
    value = data.draw(_bad_values(rule), label=name)
    with pytest.raises(ConfigError) as info:
        _build(cls, **{name: value})
    assert str(info.value).startswith(f"{name} must be "), (cls, str(info.value))


# ------------------------------------------------------------ the old pattern stays out
def _calls_in_post_init() -> list[tuple[str, str, ast.Call, set[str]]]:
    out = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
                fields = {s.target.id for s in cls.body if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)}
                for fn in cls.body:
                    if isinstance(fn, ast.FunctionDef) and fn.name == "__post_init__":
                        for call in (c for c in ast.walk(fn) if isinstance(c, ast.Call)):
                            if getattr(call.func, "id", getattr(call.func, "attr", None)) == "config_field":
                                out.append((str(path.relative_to(ROOT)), cls.name, call, fields))
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
