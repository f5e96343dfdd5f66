"""Typed errors raised by cansim.

Every error a user can provoke with bad input derives from :class:`CansimError`,
so robot code can catch one base class. Each message says what to do about it.
The model or population that raised it is left unchanged.
"""

from __future__ import annotations

__all__ = [
    "CansimError",
    "InvalidInputError",
    "ShapeError",
    "ZeroActivityError",
    "BackendUnavailableError",
    "UnknownBackendError",
    "ConfigError",
]


class CansimError(Exception):
    """Base class of every error raised on purpose by cansim."""


class InvalidInputError(CansimError, ValueError):
    """A value is out of its domain (NaN/inf velocity, negative dt, bad index...)."""


class ShapeError(InvalidInputError):
    """An array has the wrong shape or number of dimensions."""


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
    """A registered backend whose optional dependency is not installed or has no device."""


class ConfigError(InvalidInputError):
    """A parameter or configuration entry is unknown or malformed; the message names the key."""
