"""Parameters of the canonical experiments: defaults filled in, every value checked.

An experiment's ``DEFAULTS`` maps each parameter name (with its unit in the name) to a
default whose type is the parameter's type: ``int``, ``float``, ``bool`` or ``str``.
:func:`resolve` merges a sweep cell's parameters into those defaults and raises the
project's typed errors for anything an experiment cannot run with, so a bad sweep cell
fails with a message instead of a NaN in the results table.
"""

from __future__ import annotations

from collections.abc import Mapping
from numbers import Integral, Real
from typing import Any, Optional, Sequence

import numpy as np

from cansim.errors import ConfigError, InvalidInputError
from whisker_io.validation import config_field

__all__ = ["resolve", "require", "checked_seed"]


def resolve(params: Any, defaults: Mapping[str, Any], *, name: str,
            choices: Optional[Mapping[str, Sequence[Any]]] = None) -> dict:
    """``defaults`` updated with ``params``, each value of its default's type.

    Parameters
    ----------
    params : mapping or None
        The cell's parameters (a subset of ``defaults``' keys).
    defaults : mapping
        Parameter name -> default value.
    name : str
        The experiment's name, for messages.
    choices : mapping or None
        Parameter name -> allowed values (for ``str`` and ``int`` parameters).

    Returns
    -------
    dict
        Every parameter of ``defaults``; ints as ``int``, reals as finite ``float``.

    Raises
    ------
    ConfigError
        A parameter the experiment does not know (the message lists those it does).
    InvalidInputError
        A value of the wrong type, a non-finite number or a value outside ``choices``.
    """
    if params is None:
        params = {}
    if not isinstance(params, Mapping):
        raise InvalidInputError(f"{name}: params must be a mapping of parameter names to values, got {type(params).__name__}")
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ConfigError(f"{name}: unknown parameter {unknown[0]!r}; known: {', '.join(sorted(defaults))}")
    out = dict(defaults)
    for key, value in params.items():
        default = defaults[key]
        kind = next((k for k in (bool, int, float, str) if isinstance(default, k)), None)  # bool before int
        if kind is int and _integral_float(value):
            value = int(value)  # 3.0 from a TOML file or a float grid is the count 3
        if kind is not None:  # the one field check, with the message of a sweep cell's parameter
            value = config_field(value, f"{name}: {key}", kind, error=InvalidInputError, message=_MESSAGES[kind])
            value = kind(value)  # np.int64 -> int, np.bool_ -> bool (what a default of that type is)
        out[key] = value
    for key, allowed in (choices or {}).items():
        if out[key] not in allowed:
            raise InvalidInputError(f"{name}: {key} must be one of {list(allowed)}, got {out[key]!r}")
    return out


#: the message of a parameter value of the wrong kind, by the kind of its default
_MESSAGES = {bool: "{name} must be true or false, got {value!r}", int: "{name} must be an integer, got {value!r}",
             float: "{name} must be a finite number, got {value!r}", str: "{name} must be a string, got {value!r}"}


def _integral_float(value: object) -> bool:
    """A real number that is not an integer type but has an integral finite value (``3.0``)."""
    if isinstance(value, (Integral, bool, np.bool_)) or not isinstance(value, Real):
        return False
    try:
        return float(value).is_integer()  # False for NaN and inf
    except OverflowError:  # pragma: no cover - a Real too large for a float that is no int
        return False


def require(condition: bool, message: str) -> None:
    """Raise :class:`InvalidInputError` with ``message`` unless ``condition``."""
    if not condition:
        raise InvalidInputError(message)


def checked_seed(seed: object) -> int:
    """An experiment's seed as a non-negative ``int`` (numpy's generators take nothing else).

    Raises
    ------
    ConfigError
        A bool, a float, a string, a negative number (the message says what to give).
    """
    return int(config_field(seed, "seed", int, minimum=0, message="{name} must be a non-negative integer, got {value!r}"))
