"""The one set of finite-value validators of the distribution.

Every public entry point that takes numbers checks them here before it touches
any state, so bad input (NaN, inf, a string, a wrong shape) raises the project's
typed error with a message naming the argument, never a NaN result later:

* :func:`finite_scalar` - one finite real number -> ``float``;
* :func:`finite_vector` - a 1-D array of finite reals, optionally of length n;
* :func:`finite_array` - an array of finite reals of a given shape;
* :func:`whole_number` - an integer count (an integral float is accepted);
* :func:`config_field` - one field of a configuration dataclass (its kind, range,
  oddness or allowed names), raising :class:`~whisker_io.errors.ConfigError`;
* :func:`plain_fields` - a configuration dataclass's numpy scalars and lists made
  plain Python numbers and tuples;
* :func:`checked` - a dataclass field whose constraint (a :class:`FieldCheck`) is
  declared with it, and :func:`validate_fields` - the one validator that reads those
  declarations (called first by each configuration's ``__post_init__``); a field may
  declare the error it raises, its name in the message and the message itself;
* :class:`ConfigDataclass` - the base of those configuration dataclasses: an argument
  that names no field (a misspelt one) or one positional argument too many is an
  :class:`~whisker_io.errors.UnknownFieldError` (a ``ConfigError`` and a ``TypeError``)
  naming the nearest field.

Non-finite values raise :class:`~whisker_io.errors.InvalidInputError`; a wrong
shape raises its subclass :class:`~whisker_io.errors.ShapeError`; a bad
configuration field raises its subclass :class:`~whisker_io.errors.ConfigError`.
Strings, bytes and booleans are not numbers here (``float("1")`` would accept a
string, ``True`` would pass as 1).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import numbers
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from whisker_io.errors import ConfigError, InvalidInputError, ShapeError, UnknownFieldError

__all__ = ["caller_stacklevel", "finite_scalar", "finite_vector", "finite_array", "whole_number", "number_tuple",
           "config_field", "plain_fields", "scale_factor", "scaled_fields", "FieldCheck", "checked", "field_checks", "validate_fields", "ConfigDataclass", "MAX_STEP_M", "MAX_TURN_RAD"]

#: The library's packages (beside this one wherever it is installed): a warning points past their frames.
_LIBRARY_DIRS = tuple(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), name) + os.sep
                      for name in ("cansim", "maps", "whisker_io"))


def caller_stacklevel() -> int:
    """The ``stacklevel`` for :func:`warnings.warn` that names the first caller outside the library.

    Call it as the argument of the ``warnings.warn`` it is for; the warning then points at the
    user's line whichever way it was reached (``RatSLAM.step``, ``run``, ``on_odo``, a study).
    """
    frame = sys._getframe(1)  # the function calling warnings.warn: stacklevel 1
    level = 1
    while frame.f_back is not None and os.path.abspath(frame.f_code.co_filename).startswith(_LIBRARY_DIRS):
        frame, level = frame.f_back, level + 1
    return level


#: Largest accepted translation of one odometry sample or between two successive poses (m);
#: a larger one is corrupt data (split real motion into steps). Used by the typed odometry
#: (:mod:`maps.odometry`), the parity engine and the simulated odometry noise.
MAX_STEP_M = 1.0e4
#: Largest accepted rotation of one odometry sample (rad).
MAX_TURN_RAD = 1.0e4


def _holds_text(value: list | tuple) -> bool:
    """True when a (nested) list or tuple holds a string, bytes or a bool anywhere."""
    return any(
        isinstance(x, (str, bytes, bool, np.bool_, np.str_)) or (isinstance(x, (list, tuple)) and _holds_text(x))
        for x in value
    )


def _as_float_array(value: object, name: str) -> NDArray[np.float64]:
    if type(value) is np.ndarray and value.dtype == np.float64:  # already real numbers: just the copy
        return value.copy()
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise InvalidInputError(f"{name} must be real numbers, got {value!r}")
    try:
        if np.iscomplexobj(value):
            raise TypeError("complex")
        if isinstance(value, (list, tuple)) and _holds_text(value):  # np.array would parse "0" as 0.0
            raise TypeError("text")
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"{name} must be real numbers, got {value!r}") from None
    if arr.dtype != np.float64:  # pragma: no cover - np.array(dtype=float) guarantees it
        raise InvalidInputError(f"{name} must be real numbers, got {value!r}")
    return arr


def _check_finite(arr: NDArray[np.float64], name: str) -> None:
    if arr.size <= 16:  # a few values (an odometry vector, a decoded pose): Python's isfinite beats a ufunc
        if all(map(math.isfinite, arr.ravel().tolist())):
            return
    elif np.isfinite(arr).all():  # fast path: the error details below only when needed
        return
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        where = tuple(int(i) for i in np.unravel_index(int(bad[0]), arr.shape)) if arr.ndim > 1 else int(bad[0])
        raise InvalidInputError(
            f"{name} holds NaN/inf at index {where} ({bad.size} non-finite values); "
            "give finite numbers (mask or drop missing samples first)"
        )


def scale_factor(value: object, name: str = "scale", hint: str = "") -> float:
    """``value`` as a finite multiplier >= 0 (dimensionless); ``hint`` is added to the error's first clause.

    Raises
    ------
    InvalidInputError
        None, a bool, a string, NaN/inf or a negative number.
    ShapeError
        An array with one or more dimensions.
    """
    if value is None:
        raise InvalidInputError(f"{name} must be a finite number >= 0{hint}, got None")
    k = finite_scalar(value, name)
    if k < 0:
        raise InvalidInputError(f"{name} must be >= 0{hint}, got {value!r}")
    return k


def scaled_fields(obj: Any, scale: object, fields: Sequence[str]) -> Any:
    """A copy of the dataclass ``obj`` with ``fields`` (standard deviations) multiplied by ``scale``.

    Parameters
    ----------
    obj : dataclass instance
    scale : float
        Factor, finite and >= 0 (dimensionless).
    fields : sequence of str
        The fields scaled; the others are kept.

    Raises
    ------
    InvalidInputError
        A scale that is not a finite number >= 0 (or a bool), or that makes a field overflow.
    """
    k = scale_factor(scale)
    values = {f: float(getattr(obj, f)) * k for f in fields}
    if not all(math.isfinite(v) for v in values.values()):
        raise InvalidInputError(f"scale {scale!r} makes the noise standard deviations overflow; use a smaller scale")
    return dataclasses.replace(obj, **values)


def finite_scalar(value: object, name: str) -> float:
    """Return ``value`` as a finite ``float``.

    Parameters
    ----------
    value : real number or 0-d array
        The value to check.
    name : str
        Argument name for the error message.

    Raises
    ------
    InvalidInputError
        Not a real number (a string, a bool, None, a complex number) or NaN/inf.
    ShapeError
        An array with one or more dimensions.
    """
    if type(value) is float:  # the common case first: no ABC or numpy machinery on the valid path
        if math.isfinite(value):
            return value
        raise InvalidInputError(f"{name} must be finite, got {value!r}")
    if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        try:
            out = float(value)
        except OverflowError:
            raise InvalidInputError(f"{name} must be finite, got an integer too large for a float") from None
    else:
        arr = _as_float_array(value, name)
        if arr.ndim != 0:
            raise ShapeError(f"{name} must be a single number, got an array of shape {arr.shape}")
        out = float(arr)
    if out != out or out in (float("inf"), float("-inf")):
        raise InvalidInputError(f"{name} must be finite, got {out!r}")
    return out


def finite_array(value: ArrayLike, shape: Sequence[int | None] | None, name: str) -> NDArray[np.float64]:
    """Return ``value`` as a new float64 array of finite values.

    Parameters
    ----------
    value : array_like
        The values to check.
    shape : sequence of int or None, optional
        Required shape; ``None`` in a position accepts any length there, a
        ``None`` shape accepts any shape.
    name : str
        Argument name for the error message.

    Returns
    -------
    ndarray of float64
        A fresh (writable) copy.

    Raises
    ------
    ShapeError
        The shape differs from ``shape``.
    InvalidInputError
        Non-numeric or NaN/inf entries (the message gives the first bad index).
    """
    arr = _as_float_array(value, name)
    if shape is not None:
        want = tuple(shape)
        if arr.ndim != len(want) or any(w is not None and w != s for w, s in zip(want, arr.shape)):
            shown = "(" + ", ".join("n" if w is None else str(w) for w in want) + ("," if len(want) == 1 else "") + ")"
            raise ShapeError(f"{name} must have shape {shown}, got {arr.shape}")
    _check_finite(arr, name)
    return arr


def finite_vector(value: ArrayLike, n: int | None, name: str) -> NDArray[np.float64]:
    """Return ``value`` as a new 1-D float64 array of finite values.

    Parameters
    ----------
    value : array_like, shape (n,)
        The vector; a plain number is accepted when ``n == 1``.
    n : int or None
        Required length; ``None`` accepts any length.
    name : str
        Argument name for the error message.

    Raises
    ------
    ShapeError
        Not 1-D, or not of length ``n``.
    InvalidInputError
        Non-numeric or NaN/inf entries.

    Examples
    --------
    >>> finite_vector([1, 2, 3], 3, "position_m").tolist()
    [1.0, 2.0, 3.0]
    """
    arr = _as_float_array(value, name)
    if arr.ndim == 0 and n == 1:
        arr = arr.reshape(1)
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n):
        raise ShapeError(f"{name} must have shape ({'n' if n is None else n},), got {arr.shape}")
    _check_finite(arr, name)  # finite_array's checks on the array made once (no second copy)
    return arr


def whole_number(value: object, name: str, minimum: int | None = None) -> int:
    """Return ``value`` as an ``int`` (a count: samples, bins, neighbours).

    Parameters
    ----------
    value : int, numpy integer, or an integral float
        The count.
    name : str
        Argument name for the error message.
    minimum : int, optional
        Smallest value allowed.

    Raises
    ------
    InvalidInputError
        Not a finite whole number (a bool, a string, 2.5, NaN), or below ``minimum``.
    """
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        out = int(value)
    else:
        x = finite_scalar(value, name)
        if not x.is_integer():
            raise InvalidInputError(f"{name} must be a whole number, got {value!r}")
        out = int(x)
    if minimum is not None and out < minimum:
        raise InvalidInputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return out


_KIND_NAMES = {int: "an integer", float: "a finite number", bool: "a boolean (True or False)", str: "a name"}


def number_tuple(value: object, name: str, *, length: int | None = None, minimum: float | None = None,
                 above: float | None = None, whole: bool = False) -> tuple[float, ...]:
    """Check a configuration's sequence of numbers (a grid, a range): finite, non-empty, in bounds.

    Parameters
    ----------
    value : sequence of numbers
        The field's value (a tuple, list or 1-D array; not text, not bools).
    name : str
        Field name for the message.
    length : int, optional
        Required length (a range: 2).
    minimum, above : float, optional
        Every entry ``>= minimum`` / ``> above``.
    whole : bool
        Every entry a whole number.

    Returns
    -------
    tuple of float
        The entries (ints when ``whole``).

    Raises
    ------
    ShapeError
        Not a flat sequence of the required length.
    InvalidInputError
        Empty, text, bools, NaN/inf, fractions where whole numbers are wanted, out of bounds.

    Examples
    --------
    >>> number_tuple([0.2, 2.5], "frequency_range_hz", length=2, above=0)
    (0.2, 2.5)
    """
    if isinstance(value, (str, bytes)) or np.ndim(value) == 0 and not isinstance(value, (list, tuple)):
        raise InvalidInputError(f"{name} must be a sequence of numbers, got {value!r}")
    arr = finite_vector(value, length, name)
    if len(arr) == 0:
        raise InvalidInputError(f"{name} must hold at least one number, got {value!r}")
    if whole and not all(float(x).is_integer() for x in arr):
        raise InvalidInputError(f"{name} must hold whole numbers, got {value!r}")
    if minimum is not None and arr.min() < minimum:
        raise InvalidInputError(f"{name} must hold numbers >= {minimum}, got {value!r}")
    if above is not None and arr.min() <= above:
        raise InvalidInputError(f"{name} must hold numbers > {above}, got {value!r}")
    return tuple(int(x) for x in arr) if whole else tuple(float(x) for x in arr)


def _is_kind(value: object, kind: type) -> bool:
    if kind is bool:
        return isinstance(value, (bool, np.bool_))
    if isinstance(value, (bool, np.bool_)):
        return False
    if kind is int:
        return isinstance(value, (int, np.integer))
    if kind is float:
        if not isinstance(value, numbers.Real):
            return False
        try:
            return math.isfinite(float(value))
        except OverflowError:  # an int too large for a float
            return False
    return isinstance(value, str)


def config_field(
    value: Any,
    name: str,
    kind: type,
    *,
    minimum: float | None = None,
    above: float | None = None,
    maximum: float | None = None,
    odd: bool = False,
    choices: Sequence[str] | None = None,
    optional: bool = False,
    hint: str = "",
    error: type[InvalidInputError] = ConfigError,
    reader: Callable[[Any, str], float | int] | None = None,
    message: str | None = None,
    reader_message: str | None = None,
) -> Any:
    """Check one field of a configuration and return it unchanged.

    The one check of a configuration field (``MapConfig``, ``RatSLAMConfig``,
    ``WhiskerRatSLAMConfig``, the front-end configs): a field declares its kind and
    range with :func:`checked` and :func:`validate_fields` applies them here, so every
    bad value is refused before any part is built, with a message naming the field,
    the allowed values and the value given. Called directly only for what is not one
    field (the entries of a tuple) or for a bound read from another field.

    Parameters
    ----------
    value : object
        The field's value.
    name : str
        The field's name (for the message).
    kind : {int, float, bool, str}
        ``int``: an integer (``numpy`` integers too; not a bool, not 2.0);
        ``float``: a finite real number (ints accepted; not a bool, NaN or inf);
        ``bool``: ``True``/``False``; ``str``: a string (one of ``choices`` if given).
    minimum, above, maximum : float, optional
        ``value >= minimum``, ``value > above``, ``value <= maximum`` (numbers only).
    odd : bool
        An odd integer (a kernel width centred on a cell).
    choices : sequence of str, optional
        The allowed names of a ``str`` field.
    optional : bool
        ``None`` is allowed too.
    hint : str
        Appended to the message: what to do.
    error : subclass of InvalidInputError
        The error raised (default :class:`~whisker_io.errors.ConfigError`); a class of
        the sensor stage raises :class:`~whisker_io.errors.InvalidInputError`.
    reader : {finite_scalar, whole_number}, optional
        Read the number with this shared validator first, so a value that is no number
        raises its error and message (``"radius_m must be finite, got nan"``, a
        :class:`~whisker_io.errors.ShapeError` for an array; :func:`whole_number` takes
        an integral float such as ``2.0``); the bounds are then checked on the number
        read. Without it the kind is checked here, with the one message of a bad value.
    message : str, optional
        The message of a bad value, a :meth:`str.format` template with ``{name}``,
        ``{value}`` (the value as given: write ``{value!r}``) and ``{want}`` (the
        allowed values in words, e.g. ``"a finite number > 0"``). Default
        ``"{name} must be {want}, got {value!r}"``.
    reader_message : str, optional
        With a ``reader``: a value the reader refuses raises ``error`` (not the reader's
        own class) with this :meth:`str.format` template of ``{error}``, the reader's
        message (e.g. ``"SafetyEnvelope: {error}"``). Default: the reader's error as it is.

    Returns
    -------
    object
        ``value``.

    Raises
    ------
    ConfigError
        The value is of another kind, out of range, even where odd is needed, or not
        one of ``choices`` (``error`` if given; with a ``reader``, a value that is no
        number raises the reader's error).

    Examples
    --------
    >>> config_field(7, "exc_width", int, minimum=1, odd=True)
    7
    >>> config_field(4, "exc_width", int, minimum=1, odd=True)
    Traceback (most recent call last):
    ...
    whisker_io.errors.ConfigError: exc_width must be an odd integer >= 1, got 4
    """
    _read_field(value, name, kind, minimum, above, maximum, odd, choices, optional, hint, error, reader, message,
                reader_message)
    return value


def _read_field(value: Any, name: str, kind: type, minimum: float | None, above: float | None,
                maximum: float | None, odd: bool, choices: Sequence[str] | None, optional: bool, hint: str,
                error: type[InvalidInputError], reader: Callable[[Any, str], float | int] | None,
                message: str | None, reader_message: str | None, config: Any = None) -> Any:
    """:func:`config_field`'s check; returns the number read (the reader's result, else ``value``)."""
    if optional and value is None:
        return value
    if reader is not None:
        if reader_message is None:
            number: Any = reader(value, name)  # a value that is no number: the reader's error and message
        else:
            try:
                number = reader(value, name)
            except InvalidInputError as exc:
                raise error(reader_message.format(error=exc, config=config)) from None
        ok = True
    else:
        number = value
        ok = _is_kind(value, kind)
    if ok and kind in (int, float):
        ok = not (
            (minimum is not None and number < minimum)
            or (above is not None and number <= above)
            or (maximum is not None and number > maximum)
            or (odd and number % 2 == 0)
        )
    if ok and choices is not None:
        ok = value in tuple(choices)
    if ok:
        return number
    if choices is not None:
        want = "one of " + ", ".join(repr(c) for c in choices)
    else:
        bounds = [f"{op} {bound:g}" for op, bound in ((">=", minimum), (">", above), ("<=", maximum)) if bound is not None]
        want = ("an odd integer" if odd else _KIND_NAMES[kind]) + (" " + " and ".join(bounds) if bounds else "")
    if optional:
        want += " or None"
    if message is None:
        text = f"{name} must be {want}, got {value!r}"
    else:
        text = message.format(name=name, value=value, want=want, config=config)
    raise error(text + (f"; {hint}" if hint else ""))


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):  # np.int64(9) -> 9, np.float32(0.1) -> 0.10000000149011612, np.bool_ -> bool
        return value.item()
    if isinstance(value, np.ndarray) and value.ndim == 1:  # a per-axis array, e.g. exc_width=np.array([7, 7, 5])
        return tuple(value.tolist())
    if isinstance(value, (list, tuple)):
        items = tuple(_plain(v) for v in value)
        return value if type(value) is tuple and all(a is b for a, b in zip(items, value)) else items
    return value


def plain_fields(config: Any) -> None:
    """Make a frozen configuration dataclass hold plain Python values, in place.

    A numpy scalar becomes the Python number of the same value (``np.int64(9)`` -> ``9``,
    ``np.float32(0.1)`` -> ``0.10000000149011612``, ``np.bool_`` -> ``bool``); a list, a
    tuple of numpy scalars or a 1-D array (a per-axis value) becomes a tuple of Python
    values. :func:`validate_fields` calls it before checking the fields (and the few
    configurations that check every field by hand call it first), so a configuration
    built from numpy values equals, hashes, computes (float64, not float32 arithmetic)
    and saves (JSON) as the one built from the same Python values:
    a saved model then loads back to a model that steps exactly as the original.
    Other values (strings, None, nested configurations, arrays of other shapes, which
    the field checks refuse) are left as they are.

    Parameters
    ----------
    config : dataclass instance
        A (frozen) configuration dataclass; changed in place.
    """
    for name in _field_names(type(config)):
        _plain_field(config, name, getattr(config, name))


def _plain_field(config: Any, name: str, value: Any) -> Any:
    """``value`` (the field ``name`` of ``config``) made plain and stored back if that changed it; returns it."""
    if type(value) in _PLAIN_TYPES:  # already plain (the common case): nothing to convert
        return value
    plain = _plain(value)
    if plain is not value:
        object.__setattr__(config, name, plain)
    return plain


#: values :func:`_plain` returns unchanged (checked by type first: a record is built per sample)
_PLAIN_TYPES = frozenset({float, int, str, bool, type(None)})


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


@functools.cache
def _init_names(cls: type) -> tuple[tuple[str, ...], float, frozenset[str]] | None:
    """What a class's ``__init__`` takes: its parameters' names in order (without ``self``), how many positional
    arguments (inf with ``*args``), and the keywords (those that may be given by name, and the old names its
    ``__renamed_keywords__`` still accepts, ``cansim._renamed.renamed_keywords``); None when it takes any keyword
    (``**kwargs``: nothing to check)."""
    params = list(inspect.signature(cls.__init__).parameters.values())[1:]  # without self
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return None
    names = tuple(p.name for p in params if p.kind is not p.VAR_POSITIONAL)
    positional = math.inf if any(p.kind is p.VAR_POSITIONAL for p in params) else \
        sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)
    keywords = frozenset(p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY))
    return names, positional, keywords | frozenset(getattr(cls, "__renamed_keywords__", ()))


class _InitSignature:
    """``cls.__signature__`` of a :class:`ConfigDataclass`: its ``__init__``'s parameters (without ``self``), so that
    ``inspect.signature`` and the API docs show the fields, not ``__new__``'s ``(*args, **kwargs)``."""

    def __get__(self, instance: Any, owner: type) -> inspect.Signature:
        if instance is not None:
            raise AttributeError("__signature__")
        sig = inspect.signature(owner.__init__)
        return sig.replace(parameters=list(sig.parameters.values())[1:], return_annotation=inspect.Signature.empty)


class ConfigDataclass:
    """Base of the configuration dataclasses: a misspelt or surplus argument is a :class:`ConfigError`.

    A dataclass's generated ``__init__`` refuses a keyword that names no field with a
    plain ``TypeError`` before any field check runs. ``__new__`` receives the same
    arguments first, so this base checks their names and number there and raises
    :class:`~whisker_io.errors.UnknownFieldError` (a :class:`~whisker_io.errors.ConfigError`,
    the project's error for a bad configuration, and a ``TypeError``, as Python's own)
    naming the nearest field and listing the class's fields. The names are the
    ``__init__``'s parameters (a subclass with an ``__init__`` of its own is checked
    against that one; one that takes ``**kwargs`` is not checked). A missing required field is
    still the ``__init__``'s ``TypeError``. ``dataclasses.replace`` builds through the
    constructor and is checked alike.

    Examples
    --------
    >>> @dataclasses.dataclass(frozen=True)
    ... class WindowParams(ConfigDataclass):
    ...     start_s: float = 0.0
    ...     stop_s: float = 1.0
    >>> WindowParams(stop=2.0)
    Traceback (most recent call last):
    ...
    whisker_io.errors.UnknownFieldError: WindowParams has no field 'stop' (did you mean 'stop_s'?); its fields: start_s, stop_s
    >>> inspect.signature(WindowParams)
    <Signature (start_s: 'float' = 0.0, stop_s: 'float' = 1.0)>
    """

    __slots__ = ()
    __signature__ = _InitSignature()

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        if args or kwargs:
            init = _init_names(cls)
            if init is not None and (len(args) > init[1] or not kwargs.keys() <= init[2]):
                cls.refuse_arguments(len(args), kwargs)
        return super().__new__(cls)

    @classmethod
    def refuse_arguments(cls, n_positional: int, keywords: Any) -> None:
        """Raise :class:`UnknownFieldError` for the first keyword of ``keywords`` that names no parameter, or for
        ``n_positional`` arguments beyond the parameters (a subclass may name better advice first)."""
        import difflib

        fields = dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ()
        init = _init_names(cls)
        if init is None:  # an __init__ that takes any keyword: the dataclass's own parameters are what it names
            names = tuple(f.name for f in fields if f.init)
            positional, known = math.inf, frozenset(names)
        else:
            names, positional, known = init
        listed = ", ".join(names)
        derived = {f.name for f in fields if not f.init}
        for key in keywords:
            if key in derived and key not in known:
                raise UnknownFieldError(f"{cls.__name__}'s field {key!r} is derived from the others, not given; "
                                        f"its parameters: {listed}")
            if key not in known:
                near = difflib.get_close_matches(str(key), names, n=1)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise UnknownFieldError(f"{cls.__name__} has no field {key!r}{hint}; its fields: {listed}")
        if n_positional > positional:
            raise UnknownFieldError(f"{cls.__name__} takes at most {positional} positional arguments, got {n_positional}; "
                                    f"give them by name: {listed}")


# ------------------------------------------------------------ declared field checks
#: The key of a :func:`checked` field's :class:`FieldCheck` in ``dataclasses.Field.metadata``.
CHECK_KEY = "whisker_io.check"


@dataclasses.dataclass(frozen=True)
class FieldCheck:
    """The constraint of one configuration field: the options of :func:`config_field`.

    Made by :func:`checked` and stored in the field's metadata; :func:`validate_fields`
    applies it through :func:`config_field`, so the error (a
    :class:`~whisker_io.errors.ConfigError` unless ``error`` says otherwise) and its
    message are :func:`config_field`'s.

    Parameters
    ----------
    kind : {int, float, bool, str}
        The field's kind (see :func:`config_field`).
    minimum, above, maximum : float, optional
        ``value >= minimum``, ``value > above``, ``value <= maximum``.
    odd : bool
        An odd integer.
    choices : tuple of str, optional
        The allowed names of a ``str`` field.
    optional : bool
        ``None`` is allowed too.
    hint : str
        What to do, appended to the message.
    error : subclass of InvalidInputError
        The error raised (default :class:`~whisker_io.errors.ConfigError`).
    label : str, optional
        How the field is named in the message (default its name), e.g.
        ``"SignalParams.base_radius_m"``.
    reader : {finite_scalar, whole_number}, optional
        The shared validator that reads the number first (its errors and messages for a
        value that is no number); ``finite_scalar`` for kind float, ``whole_number`` for int.
    message : str, optional
        The message template of a bad value (``{name}``, ``{value!r}``, ``{want}``; see
        :func:`config_field`).
    reader_message : str, optional
        A value the reader refuses raises ``error`` with this template of ``{error}``
        (the reader's message), e.g. ``"SafetyEnvelope: {error}"`` (see :func:`config_field`).
    store : bool
        Store the number read back into the field: the reader's result (``float`` /
        ``int``), else ``float(value)`` / ``int(value)`` (a record that keeps the
        converted number, e.g. ``length_m=1`` -> ``1.0``).

    ``label``, ``message`` and ``reader_message`` may name the configuration's other
    fields as ``{config.<field>}`` (e.g. ``label="axis {config.name!r}: size"``), so a
    message can say which module or axis the bad value belongs to.

    Raises
    ------
    TypeError
        A kind other than int, float, bool or str, bounds on a non-number, choices on a
        non-string, ``odd`` on a non-integer, an error outside the project's
        :class:`~whisker_io.errors.InvalidInputError` tree, a reader other than
        :func:`finite_scalar` (float) or :func:`whole_number` (int), a template with other
        fields, a ``reader_message`` without a reader, or ``store`` on a non-number (a
        mistake in the declaration, raised when the class is defined).
    """

    kind: type
    minimum: float | None = None
    above: float | None = None
    maximum: float | None = None
    odd: bool = False
    choices: tuple[str, ...] | None = None
    optional: bool = False
    hint: str = ""
    error: type[InvalidInputError] = ConfigError
    label: str | None = None
    reader: Callable[[Any, str], float | int] | None = None
    message: str | None = None
    reader_message: str | None = None
    store: bool = False

    def __post_init__(self) -> None:
        if self.kind not in _KIND_NAMES:
            raise TypeError(f"a checked field's kind is int, float, bool or str, got {self.kind!r}")
        bounded = any(b is not None for b in (self.minimum, self.above, self.maximum))
        if bounded and self.kind not in (int, float):
            raise TypeError(f"bounds need kind int or float, got {self.kind.__name__}")
        if self.odd and self.kind is not int:
            raise TypeError("odd needs kind int")
        if self.choices is not None:
            if self.kind is not str:
                raise TypeError("choices need kind str")
            object.__setattr__(self, "choices", tuple(self.choices))
        if not (isinstance(self.error, type) and issubclass(self.error, InvalidInputError)):
            raise TypeError(f"a checked field raises a whisker_io.errors.InvalidInputError (sub)class, "
                            f"got {self.error!r}")
        if self.reader is not None and (self.reader, self.kind) not in ((finite_scalar, float), (whole_number, int)):
            raise TypeError("reader is finite_scalar (kind float) or whole_number (kind int)")
        if self.label is not None and not isinstance(self.label, str):
            raise TypeError(f"label must be a str, got {self.label!r}")
        for option, fields in (("label", {}), ("message", {"name": "", "value": 0, "want": ""}),
                               ("reader_message", {"error": ""})):
            template = getattr(self, option)
            if template is not None:
                try:
                    template.format(config=_ANY_CONFIG, **fields)
                except (AttributeError, KeyError, IndexError, ValueError, TypeError) as exc:
                    raise TypeError(f"{option} must be a str.format template of {', '.join([*fields, 'config'])}: "
                                    f"{exc!r}") from None
        if self.reader_message is not None and self.reader is None:
            raise TypeError("reader_message needs a reader")
        if self.store and self.kind not in (int, float):
            raise TypeError("store needs kind int or float")
        # validate_fields' valid path of a field read by a reader, its label fixed (no template), no choices:
        # (reader, label, lowest, above, highest, store), the bounds as numbers (a per-sample record is built per step)
        fast = None
        if self.reader is not None and not self.odd and (self.label is None or "{" not in self.label):
            fast = (self.reader, self.label, -math.inf if self.minimum is None else self.minimum,
                    -math.inf if self.above is None else self.above, math.inf if self.maximum is None else self.maximum,
                    self.store)
        object.__setattr__(self, "_fast", fast)

    def check(self, value: Any, name: str, config: Any = None) -> Any:
        """Apply the constraint to ``value`` (the field ``name``) and return it unchanged.

        Parameters
        ----------
        value : object
            The field's value.
        name : str
            The field's name.
        config : dataclass instance, optional
            The configuration the field belongs to; needed when a template names its
            fields (``{config.<field>}``).

        Raises
        ------
        ConfigError
            As :func:`config_field` (``error`` if declared; the field shown as ``label``).
        """
        self.read(value, name, config)
        return value

    def read(self, value: Any, name: str, config: Any = None) -> Any:
        """Apply the constraint and return the value to keep: the number read when ``store``, else ``value``.

        Raises
        ------
        ConfigError
            As :meth:`check`.
        """
        label = name if self.label is None else self.label if "{" not in self.label else self.label.format(config=config)
        number = _read_field(value, label, self.kind, self.minimum, self.above, self.maximum, self.odd, self.choices,
                             self.optional, self.hint, self.error, self.reader, self.message, self.reader_message,
                             config)
        if not self.store or number is None:
            return value
        if self.reader is not None:
            return number
        return float(number) if self.kind is float else int(number)


class _AnyFields:
    """Stands for a configuration when a template is checked at declaration: every field is ``""``."""

    def __getattr__(self, name: str) -> str:
        return ""


_ANY_CONFIG = _AnyFields()


def checked(
    default: Any = dataclasses.MISSING,
    kind: type | None = None,
    *,
    default_factory: Any = dataclasses.MISSING,
    minimum: float | None = None,
    above: float | None = None,
    maximum: float | None = None,
    odd: bool = False,
    choices: Sequence[str] | None = None,
    optional: bool = False,
    hint: str = "",
    error: type[InvalidInputError] = ConfigError,
    label: str | None = None,
    reader: Callable[[Any, str], float | int] | None = None,
    message: str | None = None,
    reader_message: str | None = None,
    store: bool = False,
    **field_options: Any,
) -> Any:
    """A dataclass field that declares its own constraint (read by :func:`validate_fields`).

    The constraint sits next to the field it checks, as scikit-learn declares an
    estimator's parameter constraints: the class's ``__post_init__`` is then
    ``validate_fields(self)`` followed only by the rules that tie fields together.

    Parameters
    ----------
    default : object, optional
        The field's default (leave out, with no ``default_factory``, for a required field).
    kind : {int, float, bool, str}
        The field's kind (see :func:`config_field`); required.
    default_factory : callable, optional
        Makes the default, as in :func:`dataclasses.field`.
    minimum, above, maximum, odd, choices, optional, hint
        The options of :func:`config_field`.
    error, label, reader, message
        What a bad value raises and says (see :class:`FieldCheck`): by default a
        :class:`~whisker_io.errors.ConfigError` naming the field,
        ``"{name} must be {want}, got {value!r}"``; a sensor-stage class keeps its own,
        e.g. ``checked(0.3, float, above=0, error=InvalidInputError, reader=finite_scalar,
        message="{name} must be positive, got {value!r}")``; the templates may name
        other fields as ``{config.<field>}``.
    reader_message, store
        A reader's refusal re-raised as ``error`` with this template of ``{error}``; the
        number read stored back into the field (see :class:`FieldCheck`).
    **field_options
        Passed on to :func:`dataclasses.field` (``repr``, ``compare``, ``metadata`` ...).

    Returns
    -------
    dataclasses.Field
        The field, its :class:`FieldCheck` in ``metadata[CHECK_KEY]``.

    Raises
    ------
    TypeError
        No ``kind``, or an inconsistent declaration (see :class:`FieldCheck`).

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class ProbeParams:
    ...     radius_m: float = checked(0.05, float, above=0, hint="give metres")
    ...     samples: int = checked(5, int, minimum=1, odd=True)
    ...     def __post_init__(self) -> None:
    ...         validate_fields(self)
    >>> ProbeParams(radius_m=0.1).samples
    5
    >>> ProbeParams(samples=4)
    Traceback (most recent call last):
    ...
    whisker_io.errors.ConfigError: samples must be an odd integer >= 1, got 4
    """
    if kind is None:
        raise TypeError("checked() needs the field's kind: int, float, bool or str")
    rule = FieldCheck(kind, minimum=minimum, above=above, maximum=maximum, odd=odd,
                      choices=None if choices is None else tuple(choices), optional=optional, hint=hint,
                      error=error, label=label, reader=reader, message=message, reader_message=reader_message,
                      store=store)
    metadata = {**field_options.pop("metadata", {}), CHECK_KEY: rule}
    return dataclasses.field(default=default, default_factory=default_factory, metadata=metadata, **field_options)


@functools.cache
def field_checks(cls: type) -> tuple[tuple[str, FieldCheck], ...]:
    """The declared constraints of a configuration dataclass, in field order.

    A field redeclared by a subclass only to change its default (e.g.
    ``inject_energy: float = 0.3``) keeps the constraint declared by the nearest base
    class that declares one.

    Parameters
    ----------
    cls : type
        A dataclass.

    Returns
    -------
    tuple of (str, FieldCheck)
        Each constrained field's name and its constraint.
    """
    out = []
    for f in dataclasses.fields(cls):
        rule = f.metadata.get(CHECK_KEY)
        if rule is None:
            for base in cls.__mro__[1:]:
                inherited = getattr(base, "__dataclass_fields__", {}).get(f.name)
                if inherited is not None and CHECK_KEY in inherited.metadata:
                    rule = inherited.metadata[CHECK_KEY]
                    break
        if rule is not None:
            out.append((f.name, rule))
    return tuple(out)


def validate_fields(config: Any) -> None:
    """Check every declared field of a configuration dataclass, in field order.

    The one validator of the configuration classes: first :func:`plain_fields` (numpy
    scalars -> Python numbers, lists -> tuples), then each field declared with
    :func:`checked` through :func:`config_field`. A class's ``__post_init__`` calls it
    first and then checks only what ties fields together (``a < b``, a shape that
    depends on another field), as short explicit code.

    Parameters
    ----------
    config : dataclass instance
        A (frozen) configuration; its numpy values are made plain in place.

    Raises
    ------
    ConfigError
        The first declared field (in field order) that is of the wrong kind or out of
        range; the message is :func:`config_field`'s (field name, allowed values, value
        given, hint). A field that declares ``error`` raises that class instead, and one
        that declares a ``reader`` raises the reader's error for a value that is no number
        (``error`` with ``reader_message`` if declared). A field declared with ``store``
        keeps the number read (``float`` / ``int``).

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class WindowParams:
    ...     start_s: float = checked(0.0, float, minimum=0)
    ...     stop_s: float = checked(1.0, float, minimum=0)
    ...     def __post_init__(self) -> None:
    ...         validate_fields(self)
    ...         if not self.start_s < self.stop_s:  # a rule between fields stays explicit
    ...             raise ConfigError("start_s must be < stop_s")
    >>> WindowParams(stop_s=-1.0)
    Traceback (most recent call last):
    ...
    whisker_io.errors.ConfigError: stop_s must be a finite number >= 0, got -1.0
    """
    for name, rule in _plan(type(config)):  # plain_fields and the checks in one pass over the fields
        value = _plain_field(config, name, getattr(config, name))
        if rule is None:
            continue
        fast = rule._fast
        if fast is not None and value is not None:  # the valid path of a number read by a reader, inline
            reader, label, lowest, above, highest, store = fast
            try:
                number = reader(value, name if label is None else label)
            except InvalidInputError:
                number = None  # rule.read raises the declared error and message
            if number is not None and lowest <= number <= highest and number > above:
                if store and number is not value:
                    object.__setattr__(config, name, number)
                continue
        kept = rule.read(value, name, config)  # a bad value raises here; other kinds are checked here
        if kept is not value:  # a field declared with store=True: the number read
            object.__setattr__(config, name, kept)


@functools.cache
def _plan(cls: type) -> tuple[tuple[str, FieldCheck | None], ...]:
    """Every field of ``cls`` with its declared check (None for an unchecked field), in field order."""
    rules = dict(field_checks(cls))
    return tuple((name, rules.get(name)) for name in _field_names(cls))
