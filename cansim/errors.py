"""Typed errors raised by cansim.

The tree is one for the whole distribution: :class:`CansimError` and the generic
classes (:class:`InvalidInputError`, :class:`ShapeError`, :class:`ConfigError`,
:class:`CorruptFileError`) are defined in :mod:`whisker_io.errors`, the lowest
package of the data flow, and re-exported here; this module adds the errors of the
CAN engine itself. Each message says what to do about it; the model or population
that raised it is left unchanged.
"""

from __future__ import annotations

from whisker_io.errors import (CansimError, ConfigError, CorruptFileError, InvalidInputError, MissingExtraError, ShapeError,
                               UnknownFieldError, missing_extra)  # noqa: F401 - missing_extra re-exported

__all__ = [
    "CansimError",
    "InvalidInputError",
    "ShapeError",
    "ConfigError",
    "UnknownFieldError",
    "CorruptFileError",
    "MissingExtraError",
    "ZeroActivityError",
    "BackendUnavailableError",
    "UnknownBackendError",
]


class ZeroActivityError(CansimError, ArithmeticError):
    """All cells of a population would be silent; normalisation is impossible.

    The population keeps the state it had before the failing call. Re-seed it
    with ``Population.reset_cell`` / ``reset_gaussian`` or inject energy.
    """


class UnknownBackendError(CansimError, KeyError):
    """A backend name that is not registered at all."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class BackendUnavailableError(CansimError, ImportError):
    """A registered backend that cannot run here: its optional dependency is not installed, or it has no usable
    device (the message says which extra to install, or what the device lacks)."""
