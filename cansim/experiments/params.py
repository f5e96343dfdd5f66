"""Parameters of the canonical experiments: defaults filled in, every value checked.

An experiment's ``DEFAULTS`` maps each parameter name (with its unit in the name) to a
default whose type is the parameter's type: ``int``, ``float``, ``bool`` or ``str``.
:func:`resolve` merges a sweep cell's parameters into those defaults and raises the
project's typed errors for anything an experiment cannot run with, so a bad sweep cell
fails with a message instead of a NaN in the results table.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from numbers import Integral, Real
from typing import Any, Optional, Sequence

from cansim.errors import ConfigError, InvalidInputError
from whisker_io.validation import finite_scalar

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
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise InvalidInputError(f"{name}: {key} must be true or false, got {value!r}")
        elif isinstance(default, int):
            if isinstance(value, bool) or not isinstance(value, Integral):
                if isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(float(value)) \
                        and float(value).is_integer():
                    value = int(value)
                else:
                    raise InvalidInputError(f"{name}: {key} must be an integer, got {value!r}")
            value = int(value)
        elif isinstance(default, float):
            if isinstance(value, bool) or not isinstance(value, Real):
                raise InvalidInputError(f"{name}: {key} must be a number, got {value!r}")
            value = finite_scalar(value, f"{name}: {key}")  # NaN, inf and ints too large for a float
        elif isinstance(default, str):
            if not isinstance(value, str):
                raise InvalidInputError(f"{name}: {key} must be a string, got {value!r}")
        out[key] = value
    for key, allowed in (choices or {}).items():
        if out[key] not in allowed:
            raise InvalidInputError(f"{name}: {key} must be one of {list(allowed)}, got {out[key]!r}")
    return out


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
    if isinstance(seed, bool) or not isinstance(seed, Integral) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)
